"""The engine: Hydra's four phases (sync, prepare, commit, execute) over a pass graph.

    engine = Engine(stage, RenderSettings(width=256, height=144, lighting="reference"))
    frame = engine.render(time=1.0)            # one frame (accumulated if settings.accumulate > 1)
    engine.aovs["color"]                       # (h, w, 4) float32 scene-linear, top row first
    engine.set_lighting("stb", N=4)            # switch methods on a live engine
    print(engine.describe())                   # the frame's pass graph

Per frame: (1) sync: queued USD edits and the time change reach the render index,
which syncs dirty prims, and the delegate commits what changed; (2) prepare: each
pass in graph order (distant lights, culling, shadow scheduling, light upload,
frame uniforms, method set-up); (3) execute: each pass in graph order (shadow
maps -> G-buffer -> min/max depth -> lighting method -> accumulation -> colour
correction -> AOV readback). The graph (``passes.py`` + ``graph.py``) is built
from the passes' declarations and rebuilt only when the method, its options or
the requested AOVs change. Every phase and pass is timed.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

import moderngl
import numpy as np
from pxr import Usd

from ..color.ocio import ColorPipeline
from ..scene import prims
from ..scene.stage_io import StageOpenError, open_stage
from ..scene.stage_scene_index import StageSceneIndex
from .camera import ViewSetup, framing_camera, view_setup
from .delegate import rect_texture_of
from .frame import (
    TEMPORAL_MODES,
    FrameContext,
    RenderBuffers,
    RenderSettings,
    ScopedBuffers,
    Timings,
    timed,
)
from .fullscreen import release_fullscreen
from .gl import get_context, park, shader_library
from .gl_delegate import GLRenderDelegate
from .graph import FORMATS, CompiledGraph, Rec, Tex, compile_graph
from .lighting import debug_aov_names, method_class
from .lighting.base import LightingMethod, light_filter
from .passes import IMPORTS, PassSet, build_passes
from .render_index import RenderIndex
from .tasks.aov_output import AovOutputTask
from .tasks.base import Pass
from .tasks.gbuffer import LINK_TARGET
from .tasks.shadow_atlas import ShadowAtlasTask
from .tasks.taa import AccumulateTask
from .tasks.temporal import TemporalTask, halton_jitter


class RenderError(RuntimeError):
    """A user-facing render problem (unknown camera, empty stage...)."""


class Engine:
    def __init__(
        self,
        stage: Usd.Stage | str | Path,
        settings: RenderSettings | None = None,
        *,
        color: ColorPipeline | None = None,
        ctx: moderngl.Context | None = None,
        time: float | None = None,
    ) -> None:
        self.settings = settings or RenderSettings()
        if not isinstance(stage, Usd.Stage):
            try:
                stage = open_stage(stage)
            except StageOpenError as exc:
                raise RenderError(str(exc)) from None
        self.stage = stage
        self.ctx = ctx or get_context()
        # Lights the method cannot show are not populated (set_lighting adds them).
        self.scene_index = StageSceneIndex(
            stage, time, light_filter=light_filter(method_class(self.settings.lighting))
        )
        self.delegate = GLRenderDelegate(self.ctx)
        if self.settings.texture_budget_mib is not None:
            mib = self.settings.texture_budget_mib
            self.delegate.textures.budget_bytes = int(mib * 2**20)
        self.render_index = RenderIndex(self.scene_index, self.delegate)
        self.color = color or ColorPipeline()
        self.buffers = RenderBuffers(self.ctx)
        self.timings = Timings()
        self.frame_index = 0
        self.camera_path: str | None = None
        self._free_camera: prims.CameraPrim | None = None
        #: Linear exposure of the free camera (a previewer keeps a stage camera's).
        self.free_camera_exposure = 1.0
        self.warnings: list[str] = []
        self._seen_warnings: set[str] = set()
        self._in_sequence = False
        #: The offline shadow-footprint probe ran (``_probe_footprint``).
        self._footprint_probed = False
        self._requested_aovs: set[str] = {"color"}
        self._graph: CompiledGraph[Pass] | None = None
        #: Light linking when the graph was compiled (it adds the G-buffer's g_link).
        self._graph_features: tuple[bool, bool] = (False, False)
        self._scopes: dict[int, _PassScope] = {}
        self._allocated: tuple[int, int, int] | None = None
        self.method: LightingMethod = self._make_method(
            self.settings.lighting, self.settings.method_options
        )
        self._set: PassSet = self._build_passes()
        self._sync(None)  # first sync so bounds/cameras are known
        if self.scene_index.skipped_lights and not self.delegate.batches:
            # No geometry: the local lights frame the camera and make the stage non-empty.
            self.include_all_lights()
        self._choose_camera()
        if not self.settings.height:
            cam, _ = self.camera()
            self.settings.height = max(1, round(self.settings.width / max(cam.aspect, 1e-6)))

    # -- the pass graph --
    def _make_method(self, name: str, options: dict[str, Any]) -> LightingMethod:
        return method_class(name)(self.delegate, self._warn_once, **options)

    def _build_passes(self, keep: PassSet | None = None) -> PassSet:
        ps = build_passes(
            self.ctx, self.delegate, self.settings, self.method, self.color, keep=keep
        )
        ps.aov_output.requested = self._requested_aovs
        ps.aov_output.on_change = self._invalidate_graph
        if ps.lightmap is not None:
            ps.lightmap.attach(self.stage)  # baked static light (tasks/lightmap.py)
        self._graph = None
        return ps

    def _invalidate_graph(self) -> None:
        self._graph = None

    def _features(self) -> tuple[bool, bool]:
        """What decides the G-buffer's optional targets: (light links, clearcoat)."""
        d = self.delegate
        return (d.light_table.has_light_links(), d.has_clearcoat)

    @property
    def graph(self) -> CompiledGraph[Pass]:
        """The compiled pass graph (built on first use after a change)."""
        if self._graph is None:
            self._graph_features = self._features()
            self._graph = compile_graph(self._set.passes, IMPORTS)
            self._allocated = None
            # Each pass's declared access, resolved once per graph, not per frame.
            self._scopes = {id(p): _PassScope(self.buffers, p) for p in self._graph.passes}
        return self._graph

    def describe(self) -> str:
        """The frame's pass graph as text (``stb render --print-graph``)."""
        w, h = self.settings.width, self.settings.height or 0
        return f"lighting method: {self.method.name}\n" + self.graph.describe((w, h))

    def set_lighting(self, name: str, **options: Any) -> None:
        """Switch the lighting method (and its options) on a live engine; the scene,
        the shadow atlas and the render buffers are kept."""
        method = self._make_method(name, options)  # validates before anything changes
        if method.uses_local_lights and self.scene_index.skipped_lights:
            self.include_all_lights()
        # Debug views the new method does not draw are no longer asked for.
        methods_views = set(debug_aov_names())
        self._requested_aovs = {
            a for a in self._requested_aovs if a not in methods_views or a in method.debug_aovs
        }
        old = self._set
        for p in old.passes:
            if p not in (old.shadow_atlas, old.frame_uniforms, old.lightmap):
                p.release()
        self.method = method
        self.settings.lighting = name
        self.settings.method_options = dict(options)
        # Captured shadow maps and the previous view stay (build_passes(keep=...)).
        self._set = self._build_passes(keep=old)

    def set_temporal(self, mode: str) -> None:
        """Switch the temporal mode (``accumulate``, ``taa``, ``off``) on a live engine:
        the pass set is rebuilt like :meth:`set_lighting` does (scene, shadow atlas and
        render buffers kept); the new mode starts with an empty history."""
        if mode not in TEMPORAL_MODES:
            raise ValueError(f"temporal must be one of {', '.join(TEMPORAL_MODES)}; got {mode!r}")
        if mode == self.settings.temporal:
            return
        self.settings.temporal = mode
        self.set_lighting(self.settings.lighting, **self.settings.method_options)

    def _allocate(self) -> None:
        """Allocate the graph's render buffers at the viewport size (once per size
        and graph)."""
        graph = self.graph
        key = (*self.buffers.size, id(graph))
        if self._allocated == key:
            return
        w, h = self.buffers.size
        if LINK_TARGET.name not in graph.resources:
            self.buffers.release_texture(LINK_TARGET.name)  # light linking went away
        for t in graph.textures():
            size = t.size.resolve(w, h)
            if size is None or t.fmt is None:
                continue
            comps, dtype = FORMATS[t.fmt]
            if dtype == "depth":
                cur = self.buffers.textures.get(t.name)
                if cur is None or cur.size != size:
                    self.buffers.set_texture(t.name, self.ctx.depth_texture(size))
            else:
                self.buffers.texture(t.name, comps, dtype, size=size)
        self._allocated = key

    @property
    def tasks(self) -> list[Pass]:
        """The scheduled passes in execution order."""
        return self.graph.passes

    @property
    def accumulate(self) -> AccumulateTask:
        return self._set.accumulate

    @property
    def temporal(self) -> TemporalTask | None:
        """The taa pass (None unless ``settings.temporal == "taa"``); its history
        is kept across frames and ``render`` calls."""
        return self._set.temporal

    @property
    def aov_output(self) -> AovOutputTask:
        return self._set.aov_output

    # -- helpers --
    def task(self, name: str) -> Pass | None:
        """The registered pass called ``name`` (scheduled or not), or None."""
        return next((p for p in self._set.passes if p.name == name), None)

    @property
    def renderer_info(self) -> str:
        from .gl import renderer_info

        return renderer_info(self.ctx)

    def include_all_lights(self) -> None:
        """Populate and sync the lights the scene index left out (see ``light_filter``):
        a method switch, the ``lightcount`` AOV, or a client that lists the stage's
        lights (``stb preview``) needs them all."""
        self.scene_index.set_light_filter(None)
        self._sync(None)

    # -- camera --
    def _choose_camera(self) -> None:
        cams = self.scene_index.cameras()
        want = self.settings.camera
        if want:
            if want not in cams:
                raise RenderError(
                    f"camera '{want}' not found (cameras in the stage: {', '.join(cams) or 'none'})"
                )
            self.camera_path = want
        elif cams:
            self.camera_path = cams[0]
        else:
            self.camera_path = None
            lo, hi = self.delegate.scene_bounds
            if not np.all(hi > lo):
                lights = self.delegate.light_table
                m = lights.local_mask()
                if m.any():
                    p = lights.position[m]
                    lo, hi = p.min(0) - 1.0, p.max(0) + 1.0
            aspect = self.settings.width / self.settings.height if self.settings.height else 16 / 9
            self._free_camera = framing_camera(lo, hi, aspect)

    def set_free_camera(self, camera: prims.CameraPrim, exposure: float | None = None) -> None:
        """View through ``camera`` (not a stage prim: a previewer's free camera) from the
        next frame on; ``exposure`` (linear) keeps a stage camera's brightness."""
        self.camera_path = None
        self._free_camera = camera
        if exposure is not None:
            self.free_camera_exposure = float(exposure)

    def continuous(self, on: bool = True) -> None:
        """Frames rendered with :meth:`render_frame` form one open-ended sequence (a
        previewer's frames): the still-camera running average is then reset only by
        :meth:`reset_accumulation`, not after each frame."""
        self._in_sequence = bool(on)

    def reset_accumulation(self) -> None:
        """Start the still-camera running average again (the view or scene changed)."""
        self.accumulate.reset()

    def camera(self) -> tuple[prims.CameraPrim, float]:
        if self.camera_path is not None:
            sp = self.delegate.cameras.get(self.camera_path)
            if sp is None or sp.camera is None:
                raise RenderError(f"camera '{self.camera_path}' disappeared from the stage")
            return sp.camera, sp.exposure_scale
        assert self._free_camera is not None  # _choose_camera made one (no camera_path)
        return self._free_camera, self.free_camera_exposure

    def is_empty(self) -> bool:
        return not self.delegate.batches and not self.delegate.lights

    # -- phases --
    def _sync(self, time: float | None) -> None:
        si = self.scene_index
        with timed(self.timings, "sync", None, False):
            si.apply_pending_updates()
            if time is not None:
                si.set_time(time)
            self.render_index.sync_all()
        with timed(self.timings, "commit", None, False):
            self.delegate.commit_resources()
        if self._graph is not None and self._features() != self._graph_features:
            self._graph = None  # linking / a clearcoat came or went: G-buffer targets change
        for w in si.warnings + self.delegate.warnings:
            self._warn_once(w)

    def _warn_once(self, msg: str) -> None:
        msg = " ".join(msg.split())  # every warning is one line, whatever a value printed
        if msg not in self._seen_warnings:
            self._seen_warnings.add(msg)
            self.warnings.append(msg)

    def skip_frames(self, n: int) -> None:
        """Advance the frame counter as if ``n`` frames had been rendered (their seeds
        and jitter phases are used up), so a resumed sequence (``stb render
        --skip-existing``) renders the frames after the skipped ones as a full run
        does. History-free modes only: a taa history needs the frames themselves."""
        self.frame_index += max(0, int(n))

    def render_frame(
        self, time: float | None = None, seed: int | None = None, final: bool = True
    ) -> FrameContext:
        """One frame through all four phases. ``seed`` selects the frame's random
        sequence (stochastic methods); default: the frame counter."""
        return self._frame(time, seed, final)

    def _frame(
        self,
        time: float | None = None,
        seed: int | None = None,
        final: bool = True,
        probe: bool = False,
    ) -> FrameContext:
        """``render_frame``; ``probe``: the shadow-footprint probe (``_probe_footprint``):
        the shadow atlas frozen (lights registered, no map captured), the passes
        executed up to the footprint pass only, the frame counter not advanced."""
        s = self.settings
        if not self._in_sequence or s.temporal == "off":
            self.accumulate.reset()  # a lone frame: no running average with older frames
        self.timings.start_frame()
        self._sync(time)
        if self.is_empty():
            raise RenderError("the stage has nothing to render (no geometry and no lights)")
        cam, exposure = self.camera()
        assert s.height is not None  # resolved from the camera's aspect in __init__
        # taa: subpixel jitter (Halton 2, 3); motion vectors stay unjittered.
        jitter = halton_jitter(self.frame_index) if s.temporal == "taa" else (0.0, 0.0)
        view: ViewSetup = view_setup(cam, s.width, s.height, exposure, jitter)
        # Influence ranges follow the exposure: the display image does not depend on
        # the unit scale of the lights (every method culls and fades with them).
        self.delegate.light_table.set_exposure(exposure)
        self.buffers.resize(s.width, s.height)
        self._allocate()
        fidx = self.frame_index
        frame = FrameContext(
            self.ctx,
            s,
            view,
            self.buffers,
            self.timings,
            frame_index=fidx,
            seed=(s.seed * 7919 + (fidx if seed is None else seed)) & 0xFFFFFFFF,
            final=final,
            sample_index=fidx if s.temporal == "taa" else self.accumulate.count,
        )
        passes = self.graph.passes
        with timed(self.timings, "prepare", None, False):
            for p in passes:
                with self._scope(frame, p):
                    p.sync(frame)
            for p in passes:
                with timed(self.timings, "prepare." + p.name, None, False), self._scope(frame, p):
                    p.prepare(frame)
        for p in passes:
            if p.only_final and not final:
                continue
            with timed(self.timings, p.name, self.ctx, s.profile), self._scope(frame, p):
                p.execute(frame)
            if probe and p.name == "shadow_footprint":
                break
        frame.buffers = self.buffers
        for w in frame.warnings:
            self._warn_once(w)
        park(self.ctx)
        if probe:  # not a frame: its cost shows in the next frame's timings as "probe"
            self.timings.carry_frame("probe")
        else:
            self.frame_index += 1
            self.timings.end_frame()
        frame.stats["programs_compiled"] = shader_library(self.ctx).compiled
        return frame

    def _scope(self, frame: FrameContext, p: Pass) -> _PassScope:
        return self._scopes[id(p)].bind(frame)

    def render(self, time: float | None = None, accumulate: int | None = None) -> FrameContext:
        """Render ``accumulate`` frames (distinct seeds, same time) and average them
        (``temporal="accumulate"``). With ``temporal="taa"`` the frames feed the
        reprojected history, which carries over to the next call (a sequence);
        with ``"off"`` only the last frame is shown."""
        n = max(1, int(accumulate or self.settings.accumulate))
        ((_, frame),) = self.render_progressive((n,), time)
        return frame

    def render_progressive(
        self, counts: Iterable[int], time: float | None = None
    ) -> Iterator[tuple[int, FrameContext]]:
        """Accumulate ``max(counts)`` frames as ``render(time, accumulate=max(counts))``
        does, reading the AOVs back after each of ``counts`` frames: yields ``(count,
        frame)`` with :attr:`aovs` then the mean of the first ``count`` frames -- the
        image a ``render`` of ``count`` frames gives (the same seeds), without rendering
        those frames again (convergence checks: 32 and 256 frames cost 256)."""
        marks = {int(c) for c in counts}
        if not marks or min(marks) < 1:
            raise ValueError(f"frame counts must be >= 1, got {sorted(marks)}")
        self._probe_footprint(time)
        self.accumulate.reset()
        self._in_sequence = True
        try:
            for i in range(1, max(marks) + 1):
                frame = self.render_frame(time, final=i in marks)
                if i in marks:
                    yield i, frame
        finally:
            self._in_sequence = False

    def _probe_footprint(self, time: float | None) -> None:
        """Offline renders (``render``, ``render_progressive``) under a footprint-based
        ``shadow_resolution``: before the first frame's maps are captured, measure the
        shadow footprint on one G-buffer (``_frame(probe=True)``: the atlas registers
        the lights and places them at the flux rule's sides but captures nothing), so
        the policy sizes every map of the first frame from it. Once per engine (later
        calls find a measurement; the pass re-measures every policy interval; one probe
        an engine when nothing was measured, e.g. no shadowed light in view)."""
        if self._footprint_probed:
            return
        atlas = self.task("shadow_atlas")
        fp = self.task("shadow_footprint")
        if atlas is None or fp is None or fp not in self.graph.passes:
            return
        if not isinstance(atlas, ShadowAtlasTask) or atlas.footprint_measured:
            return
        if not atlas.enabled:
            return
        self._footprint_probed = True
        frozen = atlas.frozen
        atlas.frozen = True
        try:
            self._frame(time, final=False, probe=True)
        finally:
            atlas.frozen = frozen

    @property
    def aovs(self) -> dict[str, np.ndarray]:
        return self.aov_output.results

    def reload_files(self, paths: Iterable[str]) -> int:
        """Image files changed on disk (the previewer's file watcher): material textures
        that read them reload on the next commit, and lights whose texture (a dome's, a
        rect's) is one of them are read again on the next sync. Returns how many
        textures and lights will reload."""
        paths = set(paths)
        n = self.delegate.reload_textures(paths)
        real = {os.path.realpath(p) for p in paths}
        for light, file in self.delegate.light_texture_files().items():
            if os.path.realpath(file) in real and self.render_index.mark_dirty(light):
                n += 1
        rects = self.delegate.rect_textures  # a RectLight's layer of the texture array
        for key in list(rects.layers):
            if os.path.realpath(rect_texture_of(key)[0]) in real:
                rects.touch(key)
        return n

    def request_aovs(self, names: Iterable[str]) -> None:
        """AOVs read back on the last frame of each render (``color`` always)."""
        names = set(names)
        if "lightcount" in names and self.scene_index.skipped_lights:
            self.include_all_lights()  # it counts the local lights in reach of a pixel
        self._requested_aovs = names | {"color"}
        self.aov_output.requested = self._requested_aovs

    def release(self) -> None:
        park(self.ctx)
        for p in self._set.passes:
            p.release()
        release_fullscreen(self.ctx)
        self.buffers.release()
        self.delegate.release()
        self.scene_index.close()


class _PassScope:
    """While a pass runs: the frame's records and buffers restricted to what it
    declared (undeclared access raises ``PassScopeError`` naming pass and resource)."""

    def __init__(self, buffers: RenderBuffers, p: Pass) -> None:
        reads, writes = p.io()
        self.frame: FrameContext | None = None
        self.name = p.name
        self.rec_reads = frozenset(r.cls for r in reads if isinstance(r, Rec))
        self.rec_writes = frozenset(w.cls for w in writes if isinstance(w, Rec))
        self.view = ScopedBuffers(
            buffers,
            p.name,
            {r.name for r in reads if isinstance(r, Tex)},
            {w.name for w in writes if isinstance(w, Tex)},
        )

    def bind(self, frame: FrameContext) -> _PassScope:
        """This scope for ``frame`` (the declarations are the graph's, the frame new)."""
        self.frame = frame
        return self

    def __enter__(self) -> _PassScope:
        assert self.frame is not None
        self.frame.enter(self.name, self.rec_reads, self.rec_writes)
        self.frame.buffers = self.view
        return self

    def __exit__(self, *exc: object) -> None:
        assert self.frame is not None
        self.frame.leave()
