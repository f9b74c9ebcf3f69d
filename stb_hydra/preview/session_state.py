"""The state every part of :class:`~stb_hydra.preview.session.PreviewSession` shares
(:class:`SessionState`: the engine, the stage, the camera, the flags that say what
changed), its basic properties (``ok``, the viewport size, the lighting method),
the engine camera following the session's (:meth:`SessionState._apply_camera`), the
synced light at a path, and an error as one line for :attr:`message`.

The session's other parts are mixins on it: :mod:`.session_reload` (live reload),
:mod:`.session_navigation` (cameras, gestures, framing, time), :mod:`.session_prims`
(the prim tree, picking, properties, light edits), :mod:`.session_display` (views,
exposure, OCIO); :mod:`.session` joins them with the frame loop.
"""

from __future__ import annotations

from typing import Any

from ..renderer.engine import Engine
from ..renderer.lighting import available
from ..scene.prims import LightPrim
from .camera import OrbitCamera


class SessionState:
    """What the session's parts share (``PreviewSession.__init__`` in :mod:`.session`
    sets it all)."""

    engine: Engine | None
    stage: Any
    error: str | None
    message: str | None
    camera_path: str | None
    orbit: OrbitCamera | None
    view: str
    selected: str | None
    playing: bool
    _viewport: tuple[int, int]
    _camera_dirty: bool
    _scene_dirty: bool
    _force: bool
    _scene_radius: float
    _time: float | None
    _time_changed: bool

    # -- basic properties --
    @property
    def ok(self) -> bool:
        return self.engine is not None and self.error is None

    @property
    def size(self) -> tuple[int, int]:
        """The viewport (pixels); the engine renders at ``moving_scale`` of it while
        something moves."""
        return self._viewport

    @property
    def aspect(self) -> float:
        w, h = self.size
        return w / max(h, 1)

    @property
    def methods(self) -> list[str]:
        return available()

    @property
    def method(self) -> str:
        assert self.engine is not None
        return self.engine.settings.lighting

    @property
    def options(self) -> dict[str, Any]:
        assert self.engine is not None
        return dict(self.engine.settings.method_options)

    def _apply_camera(self) -> None:
        e = self.engine
        assert e is not None
        if self.camera_path is not None:
            e.camera_path = self.camera_path
        else:
            assert self.orbit is not None
            e.set_free_camera(self.orbit.to_prim(self.aspect))

    def _light(self, path: str) -> LightPrim | None:
        """The synced light at ``path`` (render frame, physical units), or None."""
        assert self.engine is not None
        sp = self.engine.delegate.lights.get(path)
        return None if sp is None else sp.light


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split()) or type(exc).__name__
