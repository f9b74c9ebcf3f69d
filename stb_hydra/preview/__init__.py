"""``stb preview``: an interactive, usdview-like previewer on the same :class:`Engine`.

* :mod:`.camera` -- the free camera (orbit about a pivot: usdview's tumble, track,
  dolly, frame; WASD fly), pure maths.
* :mod:`.script` -- ``--script EVENTS.json``: the event list, parsed and checked.
* :mod:`.session` -- everything the window drives, without a window: the engine,
  progressive rendering (accumulate while still, ``taa`` while moving, a reduced
  render size while moving), method and option switches, light edits on the session
  layer, time, views, live reload, the HUD figures.
* :mod:`.picking` -- the ID buffer rendered on a click; :mod:`.atlas_view` -- the
  shadow-atlas view.
* :mod:`.window` -- the GLFW window (its own OpenGL 4.3 context, shared with the
  engine), input bindings, snapshots; :mod:`.panels` -- the Dear ImGui panels
  (imgui-bundle); :mod:`.bench` -- frame rate and panel overhead.

GLFW, imgui-bundle and watchdog are the ``preview`` extra; only :mod:`.window`,
:mod:`.panels` and :mod:`.bench` import the first two, and watchdog is imported lazily.
"""
