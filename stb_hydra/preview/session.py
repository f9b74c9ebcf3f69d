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
"""

from __future__ import annotations

import math
import os
import threading
import time as _time
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import moderngl
import numpy as np

from .. import limits
from ..color.ocio import ColorPipeline
from ..io.debug_views import LEGEND_ROWS, legend_strip
from ..renderer.engine import Engine, RenderError
from ..renderer.frame import RenderSettings
from ..renderer.gl import GLError
from ..renderer.lighting import available, method_class
from ..renderer.lighting.options import OptionError
from ..renderer.tasks.aov_output import AOVS, DEBUG_AOVS
from ..scene.lights import influence_range
from ..scene.prims import LightPrim
from ..scene.stage_io import StageOpenError, open_stage
from ..scene.stage_scene_index import render_from_stage_matrix
from .atlas_view import AtlasView
from .camera import OrbitCamera
from .picking import Picker, instance_bounds, instance_rows

#: Temporal modes of the previewer (``auto``: accumulate while still, taa while moving).
TEMPORAL_MODES = ("auto", "accumulate", "taa", "off")
#: Views the viewport can show: the display image, then every AOV (the debug views
#: of a method only while that method is active).
VIEWS = (*(a for a in AOVS if a != "display"), "shadow_atlas")
#: Live reload: a changed layer is reloaded once its file has been quiet this long (s);
#: editors often write a file in several steps.
RELOAD_SETTLE_S = 0.2
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


class PreviewSession:
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

    # -- live reload --
    def watch(self) -> bool:
        """Watch the stage's layer files (watchdog): a change reloads that layer on the
        next frame (the camera and edits stay); a layer that no longer parses keeps
        the last good scene and says why in :attr:`message`. False if not watchable."""
        if not self.ok or self._observer is not None:
            return False
        try:
            from watchdog.events import FileSystemEvent, FileSystemEventHandler
            from watchdog.observers import Observer
        except ImportError:
            self.message = "live reload needs watchdog (the preview extra)"
            return False
        files = self._watched_files()
        session = self

        class _Handler(FileSystemEventHandler):
            def on_any_event(self, event: FileSystemEvent) -> None:
                for p in (event.src_path, getattr(event, "dest_path", "")):
                    if not p:
                        continue
                    real = os.path.realpath(os.fsdecode(p))
                    if real in session._watch_files:
                        with session._lock:
                            session._changed_files.add(real)
                            session._changed_at = _time.monotonic()

        self._watch_files = files
        self._watch_handler = _Handler()
        obs = Observer()
        for d in sorted({os.path.dirname(f) for f in files}):
            obs.schedule(self._watch_handler, d, recursive=False)
            self._watch_dirs.add(d)
        obs.daemon = True
        obs.start()
        self._observer = obs
        return True

    def _watched_files(self) -> set[str]:
        """The stage's layer files and the texture files the renderer reads."""
        files = {
            os.path.realpath(layer.realPath)
            for layer in self.stage.GetUsedLayers()
            if layer.realPath and not layer.anonymous
        }
        if self.engine is not None:
            files |= {os.path.realpath(p) for p in self.engine.delegate.texture_files()}
        return files

    def _rewatch(self) -> None:
        """Textures (and layers) that appeared since the watch began are watched too."""
        if self._observer is None:
            return
        files = self._watched_files()
        if files <= self._watch_files:
            return
        self._watch_files = self._watch_files | files
        for d in sorted({os.path.dirname(f) for f in files} - self._watch_dirs):
            self._observer.schedule(self._watch_handler, d, recursive=False)
            self._watch_dirs.add(d)

    def _reload_changed(self) -> None:
        """Reload the layers whose files changed (after RELOAD_SETTLE_S of quiet)."""
        from pxr import Tf

        from ..scene.stage_io import tf_message

        with self._lock:
            if not self._changed_files or _time.monotonic() - self._changed_at < RELOAD_SETTLE_S:
                return
            changed, self._changed_files = self._changed_files, set()
        errors = []
        layers = {
            os.path.realpath(layer.realPath): layer
            for layer in self.stage.GetUsedLayers()
            if layer.realPath
        }
        textures = changed - set(layers)
        if textures and self.engine is not None:
            self.engine.delegate.reload_textures(textures)
            self.texture_reloads += 1
        touched = [(real, layer) for real, layer in layers.items() if real in changed]
        for real, layer in touched:
            try:
                ok = layer.Reload(force=True)
            except Tf.ErrorException as exc:
                ok = False
                errors.append(f"cannot reload '{real}': {tf_message(exc, stage_file=real)}")
                continue
            if not ok:
                errors.append(f"cannot reload '{real}': unreadable or missing")
        if touched:
            self.reloads += 1
        if errors:
            self.message = "; ".join(errors) + " (showing the last good scene)"
        elif self.message and "cannot reload" in self.message:
            self.message = None
        self._scene_dirty = True

    def _camera_path_gone(self) -> None:
        """The stage camera went away: the free camera continues from the last view."""
        assert self.engine is not None and self.orbit is not None
        self.camera_path = None
        self._camera_dirty = True
        self._apply_camera()

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

    def views(self) -> list[str]:
        """The views the current method offers (colour, AOVs, its debug views)."""
        assert self.engine is not None
        offered = set(getattr(self.engine.method, "debug_aovs", ()))
        return [v for v in VIEWS if v not in DEBUG_AOVS or v == "lightcount" or v in offered]

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

    def display_texture(self) -> moderngl.Texture | None:
        """The engine's OCIO display image (rgba8, GL rows bottom-up)."""
        if not self.ok:
            return None
        assert self.engine is not None
        return self.engine.buffers.textures.get("display")

    def view_image(self) -> np.ndarray | None:
        """The current non-colour view as (h, w, 3) uint8, top row first (None for
        ``color``: the display texture is shown as it is)."""
        if self.view == "color" or not self.ok:
            return None
        assert self.engine is not None
        if self.view == "shadow_atlas":
            if self._atlas_view is None:
                self._atlas_view = AtlasView(self.engine.ctx)
            return self._atlas_view.image(self.engine, *self.size)
        a = self.engine.aovs.get(self.view)
        if a is None:
            return None
        img = view_to_rgb8(self.view, a)
        if self.view in DEBUG_AOVS and img.shape[0] >= 2 * LEGEND_ROWS:
            # the debug view's colour scale over its bottom rows
            key = (self.view, img.shape[1])
            if key not in self._legends:
                strip = legend_strip(self.view, img.shape[1])
                self._legends[key] = (np.clip(strip, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
            img[-LEGEND_ROWS:] = self._legends[key]
        return img

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

    # -- camera --
    def _pivot_distance(self, cam: Any) -> float:
        assert self.engine is not None
        lo, hi = self.engine.delegate.scene_bounds
        centre = 0.5 * (np.asarray(lo) + np.asarray(hi))
        t = np.asarray(cam.transform)
        fwd = -t[2, :3] / max(float(np.linalg.norm(t[2, :3])), 1e-30)
        d = float((centre - t[3, :3]) @ fwd)
        return d if d > 1e-3 else self._scene_radius

    def _apply_camera(self) -> None:
        e = self.engine
        assert e is not None
        if self.camera_path is not None:
            e.camera_path = self.camera_path
        else:
            assert self.orbit is not None
            e.set_free_camera(self.orbit.to_prim(self.aspect))

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

    def set_view(self, name: str) -> bool:
        """Show colour, an AOV or a debug view (read back each frame)."""
        if not self.ok:
            return False
        assert self.engine is not None
        if name not in self.views():
            self.message = (
                f"view '{name}' not offered by '{self.method}' (views: {', '.join(self.views())})"
            )
            return False
        self.engine.request_aovs(set() if name in ("color", "shadow_atlas") else {name})
        self.view = name
        self._force = True
        return True

    @property
    def exposure(self) -> float:
        assert self.engine is not None
        return self.engine.color.exposure

    def set_exposure(self, stops: float) -> bool:
        """Display exposure (stops, OCIO): the image is re-displayed, samples kept."""
        if not self.ok:
            return False
        assert self.engine is not None
        if not math.isfinite(stops):
            self.message = f"exposure must be finite, got {stops}"
            return False
        self.engine.color.exposure = float(stops)
        self._force = True
        return True

    def set_ocio_display(self, display: str) -> bool:
        """Switch the OCIO display (its default view; same config and exposure)."""
        return self.set_ocio_view(None, display)

    def set_ocio_view(self, view: str | None, display: str | None = None) -> bool:
        """Switch the OCIO view (same config; ``display``: another display too)."""
        if not self.ok:
            return False
        e = self.engine
        assert e is not None
        old = e.color
        try:
            new = ColorPipeline(old.config_source, display or old.display, view, old.exposure)
        except ValueError as exc:
            self.message = _one_line(exc)
            return False
        e.color = new
        e.set_lighting(e.settings.lighting, **e.settings.method_options)
        self._force = True
        return True

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

    # -- lights and edits (session layer) --
    def lights(self) -> list[dict[str, Any]]:
        """Every light: path, type, enabled, its authored intensity, exposure and
        colour (what the light list edits), and its light/shadow links in one line
        (``links``: "lights all, shadowed by all" without linking; ``linked``: a
        collection is authored)."""
        from pxr import UsdLux

        if not self.ok:
            return []
        assert self.engine is not None
        out = []
        for path in sorted(self.engine.delegate.lights):
            prim = self.stage.GetPrimAtPath(path)
            lp = self._light(path)
            if lp is None:
                continue
            api = UsdLux.LightAPI(prim)
            out.append(
                {
                    "path": path,
                    "type": lp.type,
                    "enabled": bool(lp.enabled),
                    "intensity": float(api.GetIntensityAttr().Get() or 0.0),
                    "exposure": float(api.GetExposureAttr().Get() or 0.0),
                    "color": [float(c) for c in (api.GetColorAttr().Get() or (1.0, 1.0, 1.0))],
                    "links": self.engine.scene_index.links.describe(path),
                    "linked": self.engine.scene_index.links.is_linked(path),
                }
            )
        return out

    def materials(self) -> list[dict[str, Any]]:
        """The Materials panel's records (``preview.materials_view``)."""
        from .materials_view import material_records

        if not self.ok:
            return []
        assert self.engine is not None
        return material_records(self.engine.delegate)

    def set_light(
        self,
        path: str,
        *,
        enabled: bool | None = None,
        intensity: float | None = None,
        exposure: float | None = None,
        color: Iterable[float] | None = None,
    ) -> bool:
        """Edit a light on the session layer (visibility for ``enabled``); the change
        reaches the engine through change tracking on the next frame."""
        from pxr import Gf, Usd, UsdGeom, UsdLux

        if not self.ok:
            return False
        prim = self.stage.GetPrimAtPath(path)
        assert self.engine is not None
        if not prim or path not in self.engine.delegate.lights:
            self.message = f"light '{path}' not found"
            return False
        api = UsdLux.LightAPI(prim)
        with Usd.EditContext(self.stage, self.stage.GetSessionLayer()):
            if enabled is not None:
                vis = UsdGeom.Tokens.inherited if enabled else UsdGeom.Tokens.invisible
                UsdGeom.Imageable(prim).CreateVisibilityAttr().Set(vis)
            if intensity is not None:
                api.CreateIntensityAttr().Set(float(intensity))
            if exposure is not None:
                api.CreateExposureAttr().Set(float(exposure))
            if color is not None:
                api.CreateColorAttr().Set(Gf.Vec3f(*[float(c) for c in color]))
        self._scene_dirty = True
        return True

    def save_edits(self, path: str | Path) -> Path | None:
        """Write the session layer (every edit made here) as a .usda layer, atomically."""
        from ..io.files import FileWriteError, write_text_atomic

        if not self.ok:
            return None
        try:
            return write_text_atomic(path, self.stage.GetSessionLayer().ExportToString())
        except (OSError, FileWriteError) as exc:
            self.message = f"cannot save edits to '{path}': {_one_line(exc)}"
            return None

    # -- prims --
    def prim_paths(self, search: str = "") -> list[str]:
        """Every prim path (instance proxies included), filtered by a case-insensitive
        substring."""
        from pxr import Usd

        if not self.ok:
            return []
        s = search.lower()
        it = self.stage.Traverse(Usd.TraverseInstanceProxies(Usd.PrimAllPrimsPredicate))
        return [str(p.GetPath()) for p in it if s in str(p.GetPath()).lower()]

    def children(self, path: str) -> list[str]:
        """Child prim paths (instance proxies included)."""
        from pxr import Usd

        if not self.ok:
            return []
        prim = self.stage.GetPrimAtPath(path)
        if not prim:
            return []
        pred = Usd.TraverseInstanceProxies(Usd.PrimAllPrimsPredicate)
        return [str(c.GetPath()) for c in prim.GetFilteredChildren(pred)]

    def select(self, path: str | None) -> bool:
        if path is not None and (not self.ok or not self.stage.GetPrimAtPath(path)):
            self.message = f"prim '{path}' not found"
            return False
        self.selected = path
        return True

    def pick(self, x: int, y: int) -> str | None:
        """Select the prim covering viewport pixel (x, y) (top-left origin; ID buffer);
        the background clears the selection. Returns the selected path."""
        from ..renderer.camera import view_setup

        if not self.ok:
            return None
        e = self.engine
        assert e is not None
        if self._picker is None:
            self._picker = Picker(e.ctx)
        self._apply_camera()
        cam, exposure = e.camera()
        w, h = self.size
        path = self._picker.pick(e.delegate, view_setup(cam, w, h, exposure), int(x), int(y))
        self.selected = path
        return path

    def properties(self, path: str) -> list[tuple[str, str]]:
        """A prim's properties as (name, value) text: type, lights in physical units
        (as ``stb inspect`` reports them), then the attributes' values at the time."""
        from pxr import Usd

        if not self.ok:
            return []
        assert self.engine is not None
        prim = self.stage.GetPrimAtPath(path)
        if not prim:
            return instance_rows(self.engine.delegate, path)  # a picked point instance
        rows: list[tuple[str, str]] = [("type", prim.GetTypeName() or "-")]
        lp = self._light(path)
        if lp is not None:
            local = lp.type in ("sphereLight", "diskLight", "rectLight", "cylinderLight")
            unit = "cd" if local else ("lx" if lp.type == "distantLight" else "nit")
            rows += [
                ("enabled", str(bool(lp.enabled))),
                (f"intensity [{unit}]", _fmt(lp.intensity)),
                ("flux [lm]", _fmt(lp.flux)),
                ("position [m]", _fmt(lp.position)),
                ("direction", _fmt(lp.direction)),
                ("shadow", f"{'on' if lp.shadow_enable else 'off'} {lp.shadow_update}"),
            ]
            if local:
                _, exposure = self.engine.camera()
                rng = (
                    lp.range if lp.range_authored else influence_range(lp.peak_intensity, exposure)
                )
                rows.append(("range [m]", _fmt(float(rng))))
            if lp.ies_asset:
                rows.append(("IES", str(lp.ies_file or lp.ies_asset)))
        rp = self.engine.delegate.meshes.get(path)
        if rp is not None and rp.mesh is not None:
            rows.append(("material", rp.mesh.material or "(display colour)"))
        t = Usd.TimeCode(self.engine.scene_index.time)
        for a in prim.GetAttributes():
            if not a.HasAuthoredValue():
                continue
            rows.append((a.GetName(), _fmt(a.Get(t))))
        return rows

    def _light(self, path: str) -> LightPrim | None:
        """The synced light at ``path`` (render frame, physical units), or None."""
        assert self.engine is not None
        sp = self.engine.delegate.lights.get(path)
        return None if sp is None else sp.light

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


def view_to_rgb8(name: str, a: np.ndarray) -> np.ndarray:
    """An AOV as an 8-bit image (top row first): depth as a grey ramp near = white,
    normals as n/2 + 1/2, albedo clipped, debug views by their own colour scale,
    colour (scene-linear) clipped."""
    from ..io.debug_views import debug_aov_image

    a = np.nan_to_num(np.asarray(a, dtype=np.float32), nan=0.0, posinf=0.0, neginf=0.0)
    if name == "depth":
        fg = a > 0
        out = np.zeros(a.shape, np.float32)
        if fg.any():
            lo, hi = float(a[fg].min()), float(a[fg].max())
            out[fg] = 1.0 - 0.8 * (a[fg] - lo) / max(hi - lo, 1e-9)
        rgb = np.repeat(out[..., None], 3, axis=-1)
    elif name == "normal":
        rgb = np.where(np.any(a != 0, axis=-1, keepdims=True), 0.5 * a + 0.5, 0.0)
    elif name in DEBUG_AOVS:
        rgb = debug_aov_image(name, a)
    else:
        rgb = a[..., :3] if a.ndim == 3 else np.repeat(a[..., None], 3, axis=-1)
    return (np.clip(rgb, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)


def _fmt(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.6g}"
    if isinstance(v, np.ndarray) or (hasattr(v, "__len__") and not isinstance(v, str)):
        try:
            vals = [float(x) for x in v]
        except (TypeError, ValueError):
            return str(v)[:200]
        return (
            "(" + ", ".join(f"{x:.4g}" for x in vals[:16]) + (", ...)" if len(vals) > 16 else ")")
        )
    return str(v)[:200]


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split()) or type(exc).__name__
