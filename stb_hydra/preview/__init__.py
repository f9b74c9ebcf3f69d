"""``stb preview``: an interactive, usdview-like previewer on the same :class:`Engine`.

* :mod:`.camera` -- the free camera (orbit about a pivot: usdview's tumble, track,
  dolly, frame; WASD fly), pure maths.
* :mod:`.script` -- ``--script EVENTS.json``: the event list, parsed and checked.
* :mod:`.session` -- everything the window drives, without a window: the engine,
  progressive rendering (accumulate while still, ``taa`` while moving), method and
  option switches, light edits on the session layer, time, views, the HUD figures.
* :mod:`.window` -- the GLFW window (its own OpenGL 4.3 context, shared with the
  engine), the Dear ImGui panels (``imgui-bundle``), input bindings and snapshots.

GLFW and imgui-bundle are the ``preview`` extra; only :mod:`.window` imports them.
"""
