"""The previewer's state and actions, without a window (headless-testable on EGL).

A :class:`PreviewSession` owns one :class:`~stb_hydra.renderer.engine.Engine` and
decides, frame by frame, what to render:

* **progressive** (``temporal="auto"``, the default): while nothing moves the engine
  runs ``temporal="accumulate"`` (a running average, one new sample per window
  frame) up to ``max_samples``, then stops rendering; while the camera or the scene
  moves (a gesture, an edit, playback, a reload) it runs ``temporal="taa"``
  (reprojected history). A change of either kind restarts the count. Fixed modes
  (``accumulate``, ``taa``, ``off``) are honoured as given, also up to
  ``max_samples`` still frames.
* **edits** (light enable, intensity, exposure, colour) are authored on the stage's
  session layer, so they reach the engine through the scene index's change
  tracking like any other USD edit; :meth:`save_edits` writes that layer.
* **errors** (a missing or broken stage, an unknown camera, a bad option) never
  raise: they land in :attr:`error` (fatal: nothing to show) or :attr:`message`
  (the last action failed), one line each, for the window to show.

This module holds the session's construction, its frame loop (:meth:`PreviewSession.step`)
and the rendering controls (method, options, temporal mode); its other parts are mixins
on :class:`~.session_state.SessionState`: :mod:`.session_reload` (live reload),
:mod:`.session_navigation` (cameras, gestures, framing, time), :mod:`.session_prims`
(prim tree, picking, properties, light edits), :mod:`.session_display` (views,
exposure, OCIO).
"""

from __future__ import annotations

import threading
import time as _time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import moderngl
import numpy as np

from .. import limits
from ..color.ocio import ColorPipeline
from ..renderer.engine import Engine, RenderError
from ..renderer.frame import RenderSettings
from ..renderer.gl import GLError
from ..renderer.lighting import method_class
from ..renderer.lighting.options import OptionError
from ..renderer.tasks.aov_output import DEBUG_AOVS
from ..scene.stage_io import StageOpenError, open_stage
from .atlas_view import AtlasView
from .camera import OrbitCamera
from .picking import Picker
from .session_display import DisplayControls
from .session_navigation import Navigation
from .session_prims import StageContents
from .session_reload import LiveReload
from .session_state import _one_line

#: Temporal modes of the previewer (``auto``: accumulate while still, taa while moving).
TEMPORAL_MODES = ("auto", "accumulate", "taa", "off")
#: Default still-frame sample budget (``--max-samples``).
DEFAULT_MAX_SAMPLES = 64


@dataclass
class HudStats:
    """The figures the HUD shows, from the last rendered frame."""

    frame_ms: float = 0.0
    fps: float = 0.0
    passes_ms: dict[str, float] = field(default_factory=dict)
    lights_in_view: int = 0
    shadow_pending: int = 0
    atlas_occupancy: float = 0.0
    samples: int = 0
    temporal: str = "accumulate"


class PreviewSession(LiveReload, Navigation, StageContents, DisplayControls):
    """Engine + camera + progressive rendering + edits. ``ctx``: the window's context
    (or any context; tests use the EGL one)."""

    def __init__(
        self,
        scene: str | Path,
        settings: RenderSettings,
        *,
        ctx: moderngl.Context | None = None,
        color: ColorPipeline | None = None,
        max_samples: int = DEFAULT_MAX_SAMPLES,
        temporal: str = "auto",
        time: float | None = None,
        moving_temporal: str = "taa",
        moving_scale: float = 1.0,
    ) -> None:
        if not 0.1 <= moving_scale <= 1.0:
            raise ValueError(f"moving_scale must be in [0.1, 1]; got {moving_scale}")
        if moving_temporal not in ("taa", "off"):
            raise ValueError(f"moving_temporal must be taa or off; got {moving_temporal!r}")
        if temporal not in TEMPORAL_MODES:
            raise ValueError(
                f"temporal must be one of {', '.join(TEMPORAL_MODES)}; got {temporal!r}"
            )
        if max_samples < 1:
            raise ValueError(f"max_samples must be >= 1; got {max_samples}")
        self.scene = str(scene)
        self.max_samples = int(max_samples)
        self.temporal = temporal
        #: What ``auto`` runs while something moves: "taa" (default) or "off" (raw
        #: frames: noisier, cheaper where the temporal pass is slow, e.g. llvmpipe).
        self.moving_temporal = moving_temporal
        #: Render scale while something moves (1: full resolution; 0.5: a quarter of
        #: the pixels, upscaled by the window) -- frame rate while navigating.
        self.moving_scale = float(moving_scale)
        self._viewport = (int(settings.width), int(settings.height or 1))
        self.error: str | None = None
        self.message: str | None = None
        self.engine: Engine | None = None
        self.stage: Any = None
        self.camera_path: str | None = None
        self.orbit: OrbitCamera | None = None
        self.view = "color"
        self.selected: str | None = None
        self.playing = False
        self.hud = HudStats()
        self.frames_rendered = 0
        self._camera_dirty = False
        self._scene_dirty = False
        self._force = True  # the first frame
        self._last_frame: Any = None
        self._picker: Picker | None = None
        self._atlas_view: AtlasView | None = None
        self._legends: dict[tuple[str, int], np.ndarray] = {}
        self._observer: Any = None
        self._lock = threading.Lock()
        self._changed_files: set[str] = set()
        self._changed_at = 0.0
        #: Layer reloads done (live reload).
        self.reloads = 0
        #: Texture-file reloads done (live reload of changed images).
        self.texture_reloads = 0
        self._watch_files: set[str] = set()
        self._watch_dirs: set[str] = set()
        self._watch_handler: Any = None
        self._watch_loads: float = -1
        self._time: float | None = time
        self._time_changed = False
        settings.temporal = "accumulate" if temporal == "auto" else temporal
        if settings.shadow_budget is None:  # interactive: shadow maps refresh over frames
            settings.shadow_budget = limits.SHADOW_UPDATE_BUDGET_TEXELS_DEFAULT
        try:
            self.stage = open_stage(scene)
            self.engine = Engine(self.stage, settings, color=color, ctx=ctx, time=time)
        except (StageOpenError, RenderError, GLError, OptionError, ValueError) as exc:
            self.error = _one_line(exc)
            return
        e = self.engine
        if e.scene_index.skipped_lights:
            # The light list shows every light, also under a method that draws none of
            # the local ones (``--lighting sun`` builds its engine without them).
            e.include_all_lights()
        self._viewport = (int(e.settings.width), int(e.settings.height or 1))
        # The window renders one frame per tick as one long sequence: the engine's
        # accumulation is reset here, on every change, not after each frame.
        e.continuous(True)
        self.camera_path = e.camera_path
        lo, hi = e.delegate.scene_bounds
        self._scene_radius = max(0.5 * float(np.linalg.norm(np.asarray(hi) - lo)), 1.0)
        if self.camera_path is not None:
            cam, _ = e.camera()
            self.orbit = OrbitCamera.from_prim(cam, self._pivot_distance(cam), self._scene_radius)
        else:
            self.orbit = OrbitCamera.framing(lo, hi, self.aspect)
            self.orbit.scene_radius = self._scene_radius
            self._apply_camera()

    # -- progress --
    @property
    def samples(self) -> int:
        return self.hud.samples

    @property
    def converged(self) -> bool:
        """Nothing left to render until something changes."""
        still = "accumulate" if self.temporal == "auto" else self.temporal
        return self.ok and not self._pending_change() and self._done(still)

    def _done(self, want: str) -> bool:
        """The still image is finished: the wanted mode ran ``max_samples`` frames."""
        assert self.engine is not None
        return self.engine.settings.temporal == want and self.hud.samples >= self.max_samples

    # -- the frame loop --
    def _pending_change(self) -> bool:
        e = self.engine
        return bool(
            self._camera_dirty
            or self._scene_dirty
            or self._force
            or self.playing
            or self._time_changed
            or bool(self._changed_files)
            or (e is not None and e.scene_index.has_pending_updates)
        )

    def step(self) -> bool:
        """Render the next frame if there is anything to do; True when one was rendered
        (the display texture changed)."""
        if not self.ok:
            return False
        e = self.engine
        assert e is not None
        if self._observer is not None:
            self._reload_changed()
            loads = e.delegate.textures.stats["loads"]
            if loads != self._watch_loads:  # new textures: watch their files too
                self._watch_loads = loads
                self._rewatch()
        moving = bool(
            self._camera_dirty
            or self._scene_dirty
            or self._time_changed
            or self.playing
            or e.scene_index.has_pending_updates
        )
        want = (
            (self.moving_temporal if moving else "accumulate")
            if self.temporal == "auto"
            else self.temporal
        )
        if not moving and not self._force and self._done(want):
            return False
        if want != e.settings.temporal:
            self._set_engine_temporal(want)
            self.hud.samples = 0
        self._set_render_size(self.moving_scale if moving else 1.0)
        if moving or want == "off":
            e.reset_accumulation()
        if moving:
            self.hud.samples = 0
        if self.playing:
            self._advance_time()
        time = self._time if self._time_changed or self.playing else None
        self._apply_camera()
        t0 = _time.perf_counter()
        try:
            frame = e.render_frame(time=time, final=True)
        except RenderError as exc:
            if self.camera_path is None or self.camera_path in self.cameras():
                self.error = _one_line(exc)
                return False
            # the stage camera went away (a reload, an edit): the free camera takes over
            self.message = f"camera '{self.camera_path}' is gone; free camera"
            self._camera_path_gone()
            return self.step()
        except (GLError, ValueError) as exc:
            self.error = _one_line(exc)
            return False
        dt = (_time.perf_counter() - t0) * 1e3
        self._camera_dirty = self._scene_dirty = self._force = self._time_changed = False
        self._last_frame = frame
        self.frames_rendered += 1
        st = frame.stats
        pending = int(st.get("shadow_statics_pending", 0) or 0)
        if pending and e.settings.temporal == "accumulate":
            # Static shadow maps still arriving (the real-time budget): samples
            # without them would stay in the average, so the count restarts.
            e.reset_accumulation()
            self.hud.samples = 0
        else:
            self.hud.samples += 1
        self.hud.frame_ms = dt
        self.hud.passes_ms = dict(e.timings.frames[-1]) if e.timings.frames else {}
        self.hud.lights_in_view = int(frame.light_count)
        self.hud.shadow_pending = int(st.get("shadow_statics_pending", 0) or 0)
        self.hud.atlas_occupancy = float(st.get("shadow_atlas_occupancy", 0.0) or 0.0)
        self.hud.temporal = e.settings.temporal
        return True

    def _set_engine_temporal(self, mode: str) -> None:
        e = self.engine
        assert e is not None
        e.settings.temporal = mode
        e.set_lighting(e.settings.lighting, **e.settings.method_options)

    def resize(self, width: int, height: int) -> None:
        """The viewport's new size (pixels); render buffers follow on the next frame."""
        if not self.ok or width < 1 or height < 1:
            return
        assert self.engine is not None
        self._viewport = (int(width), int(height))
        self._set_render_size(1.0)
        self._camera_dirty = True

    def _set_render_size(self, scale: float) -> None:
        """The engine's image size: the viewport times ``scale`` (16 px at least)."""
        assert self.engine is not None
        w, h = self._viewport
        st = self.engine.settings
        st.width = max(16, round(w * scale)) if scale != 1.0 else w
        st.height = max(16, round(h * scale)) if scale != 1.0 else h

    # -- rendering controls --
    def set_method(self, name: str, options: dict[str, Any] | None = None) -> bool:
        """Switch the lighting method live (options validated first; on a bad name or
        option the current method stays and :attr:`message` says why)."""
        if not self.ok:
            return False
        e = self.engine
        assert e is not None
        try:
            cls = method_class(name)
        except (KeyError, ValueError, OptionError) as exc:
            self.message = _one_line(exc)
            return False
        if (
            self.view in DEBUG_AOVS
            and self.view != "lightcount"
            and self.view not in getattr(cls, "debug_aovs", ())
        ):
            self.set_view("color")
        try:
            e.set_lighting(name, **(options or {}))
        except (OptionError, ValueError, KeyError) as exc:
            self.message = _one_line(exc)
            return False
        if self.view in DEBUG_AOVS and self.view not in (*e.method.debug_aovs, "lightcount"):
            self.set_view("color")  # e.g. a reuse view after -o reuse=off
        self.message = None
        self._scene_dirty = True
        return True

    def set_options(self, **options: Any) -> bool:
        """Change options of the current method (merged with the current ones)."""
        return self.set_method(self.method, {**self.options, **options})

    def set_temporal(self, mode: str) -> bool:
        if mode not in TEMPORAL_MODES:
            self.message = f"temporal must be one of {', '.join(TEMPORAL_MODES)}; got {mode!r}"
            return False
        self.temporal = mode
        self._scene_dirty = True
        return True

    def release(self) -> None:
        if self._observer is not None:
            self._observer.stop()
            self._observer.join(5.0)
            self._observer = None
        if self._picker is not None:
            self._picker.release()
            self._picker = None
        if self._atlas_view is not None:
            self._atlas_view.release()
            self._atlas_view = None
        if self.engine is not None:
            self.engine.release()
            self.engine = None
