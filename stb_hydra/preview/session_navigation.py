"""Where and when a :class:`~stb_hydra.preview.session.PreviewSession` looks
(:class:`Navigation`): the stage cameras and the free (orbit) camera that takes over
from them, the gestures (tumble, track, dolly, fly), framing everything or the
selected prim (:meth:`Navigation.prim_bounds`), and the stage time (scrub, playback).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..scene.stage_scene_index import render_from_stage_matrix
from .camera import OrbitCamera
from .picking import instance_bounds
from .session_state import SessionState


class Navigation(SessionState):
    """The camera and time part of the session."""

    # -- camera --
    def _pivot_distance(self, cam: Any) -> float:
        assert self.engine is not None
        lo, hi = self.engine.delegate.scene_bounds
        centre = 0.5 * (np.asarray(lo) + np.asarray(hi))
        t = np.asarray(cam.transform)
        fwd = -t[2, :3] / max(float(np.linalg.norm(t[2, :3])), 1e-30)
        d = float((centre - t[3, :3]) @ fwd)
        return d if d > 1e-3 else self._scene_radius

    def _camera_path_gone(self) -> None:
        """The stage camera went away: the free camera continues from the last view."""
        assert self.engine is not None and self.orbit is not None
        self.camera_path = None
        self._camera_dirty = True
        self._apply_camera()

    def cameras(self) -> list[str]:
        """The stage's cameras."""
        assert self.engine is not None
        return list(self.engine.scene_index.cameras())

    def set_camera(self, path: str | None) -> bool:
        """Look through a stage camera (``None``: the free camera, taking over the
        current view)."""
        if not self.ok:
            return False
        if path is not None and path not in self.cameras():
            self.message = (
                f"camera '{path}' not found (cameras: {', '.join(self.cameras()) or 'none'})"
            )
            return False
        if path is None and self.camera_path is not None:
            self._take_over_camera()
        self.camera_path = path
        self._camera_dirty = True
        return True

    def _take_over_camera(self) -> None:
        """Leave the stage camera: the free camera starts from its view."""
        assert self.engine is not None
        if self.camera_path is None:
            return
        cam, exposure = self.engine.camera()
        self.orbit = OrbitCamera.from_prim(cam, self._pivot_distance(cam), self._scene_radius)
        self.engine.free_camera_exposure = exposure  # same brightness (and light ranges)
        self.camera_path = None

    def _gesture(self) -> OrbitCamera:
        self._take_over_camera()
        self._camera_dirty = True
        assert self.orbit is not None
        return self.orbit

    def tumble(self, dx: float, dy: float) -> None:
        if self.ok:
            self._gesture().tumble(dx, dy)

    def track(self, dx: float, dy: float) -> None:
        if self.ok:
            self._gesture().track(dx, dy, self.size[1], self.aspect)

    def dolly(self, px: float = 0.0, wheel: float = 0.0) -> None:
        if self.ok:
            self._gesture().dolly(px, wheel)

    def fly(self, forward: float, right: float, up: float = 0.0) -> None:
        """WASD: metres per call scale with the pivot distance."""
        if self.ok:
            o = self._gesture()
            k = 0.05 * o.distance
            o.fly(forward * k, right * k, up * k)

    def frame_all(self) -> None:
        if self.ok:
            assert self.engine is not None
            lo, hi = self.engine.delegate.scene_bounds
            self._gesture().frame(lo, hi, self.aspect)

    def frame_selection(self) -> None:
        """Frame the selected prim (everything when nothing is selected)."""
        if not self.ok:
            return
        b = self.prim_bounds(self.selected) if self.selected else None
        if b is None:
            self.frame_all()
            return
        self._gesture().frame(b[0], b[1], self.aspect)

    def prim_bounds(self, path: str) -> tuple[np.ndarray, np.ndarray] | None:
        """World bounds of a prim in the render frame (Y up, metres); lights: a box of
        their radius (at least 0.25 m) about their position."""
        from pxr import Usd, UsdGeom

        assert self.engine is not None
        light = self._light(path)
        if light is not None:
            r = max(float(light.radius or 0.0), float(light.length or 0.0), 0.25)
            p = np.asarray(light.position, dtype=np.float64)
            return p - r, p + r
        prim = self.stage.GetPrimAtPath(path)
        if not prim or not prim.IsValid():
            return instance_bounds(self.engine.delegate, path)  # a picked point instance
        cache = UsdGeom.BBoxCache(
            Usd.TimeCode(self.engine.scene_index.time),
            [UsdGeom.Tokens.default_, UsdGeom.Tokens.render, UsdGeom.Tokens.proxy],
            useExtentsHint=True,
        )
        box = cache.ComputeWorldBound(prim).ComputeAlignedRange()
        if box.IsEmpty():
            return None
        lo, hi = np.array(box.GetMin()), np.array(box.GetMax())
        corners = np.array(
            [
                [(lo, hi)[i][0], (lo, hi)[j][1], (lo, hi)[k][2], 1.0]
                for i in (0, 1)
                for j in (0, 1)
                for k in (0, 1)
            ]
        )
        w = corners @ render_from_stage_matrix(self.stage)
        return w[:, :3].min(0), w[:, :3].max(0)

    # -- time --
    def time_range(self) -> tuple[float, float] | None:
        """The stage's authored time range (None: no animation range)."""
        if not self.ok or not self.stage.HasAuthoredTimeCodeRange():
            return None
        return float(self.stage.GetStartTimeCode()), float(self.stage.GetEndTimeCode())

    @property
    def time(self) -> float | None:
        """The time code the stage is read at; None for ``Usd.TimeCode.Default()`` and
        the earliest time (a stage without an authored range), and when nothing loaded."""
        if not self.ok:
            return None
        assert self.engine is not None
        t = self.engine.scene_index.time
        return None if t.IsDefault() or t.IsEarliestTime() else float(t.GetValue())

    @property
    def time_text(self) -> str:
        """The time for people (HUD, time tab): ``"default"`` for the default and the
        earliest time code, never the raw double; otherwise the value (``%g``)."""
        if not self.ok:
            return "default"
        assert self.engine is not None
        from ..scene.stage_io import time_label

        lab = time_label(self.engine.scene_index.time)
        return lab if isinstance(lab, str) else f"{lab:g}"

    def set_time(self, t: float) -> None:
        """Scrub: the scene index moves to time code ``t`` (no reload)."""
        self._time = float(t)
        self._time_changed = True

    def set_playing(self, on: bool) -> None:
        self.playing = bool(on)

    def _advance_time(self) -> None:
        rng = self.time_range()
        if rng is None:
            self.playing = False
            return
        cur = self._time if self._time is not None else (self.time or rng[0])
        nxt = cur + 1.0
        self._time = rng[0] if nxt > rng[1] else nxt
        self._time_changed = True
