"""The engine: Hydra's four phases (sync, prepare, commit, execute) over tasks.

    engine = Engine(stage, RenderSettings(width=256, height=144, lighting="reference"))
    frame = engine.render(time=1.0)            # one frame (accumulated if settings.accumulate > 1)
    frame.aovs["color"]                        # (h, w, 4) float32 scene-linear, top row first

Per frame: (1) sync: queued USD edits and the time change reach the render
index, which syncs dirty prims; (2) prepare: camera, sun, light culling, shadow
scheduling; (3) commit: the delegate uploads what changed; (4) execute: shadow
maps -> G-buffer -> min/max depth -> lighting method -> accumulation ->
colour correction -> AOV readback. Every phase/task is timed.
"""

from __future__ import annotations

import math
from pathlib import Path

import moderngl
import numpy as np
from pxr import Usd

from ..color.ocio import ColorPipeline
from ..scene import prims
from ..scene.stage_scene_index import StageSceneIndex
from .camera import ViewSetup, framing_camera, view_setup
from .frame import FrameContext, RenderBuffers, RenderSettings, Timings, timed
from .frame_data import FrameUniforms, SunSetup, pack_frame_block
from .gl import get_context, park, shader_library
from .gl_delegate import GLRenderDelegate
from .light_table import TYPE_CODES
from .lighting import method_class
from .render_index import RenderIndex
from .tasks.aov_output import AovOutputTask
from .tasks.color_correction import ColorCorrectionTask
from .tasks.gbuffer import GBufferTask
from .tasks.hiz import HiZTask
from .tasks.light_cull import LightCullTask
from .tasks.lighting import LightingTask
from .tasks.shadow import SunShadowTask
from .tasks.shadow_atlas import ShadowAtlasTask
from .tasks.taa import AccumulateTask

LUMA = np.array([0.2126, 0.7152, 0.0722])


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
            from ..apps.common import CliError, open_stage

            try:
                stage = open_stage(stage)
            except CliError as exc:
                raise RenderError(str(exc)) from None
        self.stage = stage
        self.ctx = ctx or get_context()
        self.scene_index = StageSceneIndex(stage, time)
        self.delegate = GLRenderDelegate(self.ctx)
        self.render_index = RenderIndex(self.scene_index, self.delegate)
        self.color = color or ColorPipeline()
        self.buffers = RenderBuffers(self.ctx)
        self.uniforms = FrameUniforms(self.ctx)
        self.timings = Timings()
        self._fs_vaos: dict[int, moderngl.VertexArray] = {}
        self._prev_view_proj: np.ndarray | None = None
        self.frame_index = 0
        method = method_class(self.settings.lighting)(self, **self.settings.method_options)
        self.method = method
        self.accumulate = AccumulateTask(self)
        self.aov_output = AovOutputTask(self)
        self.tasks = [
            LightCullTask(self),
            SunShadowTask(self),
            ShadowAtlasTask(self, self.settings.shadow_atlas_size, self.settings.shadow_budget),
            GBufferTask(self),
            HiZTask(self),
            LightingTask(self, method),
            self.accumulate,
            ColorCorrectionTask(self, self.color),
            self.aov_output,
        ]
        self._task_by_name = {t.name: t for t in self.tasks}
        self.camera_path: str | None = None
        self._free_camera: prims.CameraPrim | None = None
        self.warnings: list[str] = []
        self._seen_warnings: set[str] = set()
        self._in_sequence = False
        self._sync(None)  # first sync so bounds/cameras are known
        self._choose_camera()
        if not self.settings.height:
            cam, _ = self.camera()
            self.settings.height = max(1, round(self.settings.width / max(cam.aspect, 1e-6)))

    # -- helpers --
    def task(self, name: str):
        return self._task_by_name.get(name)

    def fullscreen(self, prog: moderngl.Program) -> moderngl.VertexArray:
        vao = self._fs_vaos.get(prog.glo)
        if vao is None:
            vao = self.ctx.vertex_array(prog, [])
            self._fs_vaos[prog.glo] = vao
        return vao

    @property
    def renderer_info(self) -> str:
        from .gl import renderer_info

        return renderer_info(self.ctx)

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

    def camera(self) -> tuple[prims.CameraPrim, float]:
        if self.camera_path is not None:
            sp = self.delegate.cameras.get(self.camera_path)
            if sp is None or sp.camera is None:
                raise RenderError(f"camera '{self.camera_path}' disappeared from the stage")
            return sp.camera, sp.exposure_scale
        return self._free_camera, 1.0

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
        for w in si.warnings + self.delegate.warnings:
            if w not in self._seen_warnings:
                self._seen_warnings.add(w)
                self.warnings.append(w)

    def _sun_and_ambient(self, frame: FrameContext) -> None:
        t = self.delegate.light_table
        rows = t.rows_of_type(prims.DISTANT_LIGHT)
        rows = rows[t.enabled[rows]]
        if len(rows):
            lum = t.intensity[rows] @ LUMA
            order = rows[np.argsort(-lum, kind="stable")]
            r = int(order[0])
            sun = SunSetup()
            sun.direction_to_sun = -t.direction[r].astype(np.float64)
            sun.illuminance = t.intensity[r].astype(np.float64)
            sun.enabled = True
            sun.shadow = bool(t.shadow_enable[r])
            sun.diffuse, sun.specular = float(t.diffuse[r]), float(t.specular[r])
            sun.shadow_color = t.shadow_color[r].astype(np.float64)
            frame.sun = sun
            extra = []
            for r2 in order[1:4]:
                extra.append(
                    (
                        -t.direction[r2].astype(np.float64),
                        t.intensity[r2].astype(np.float64),
                        float(t.diffuse[r2]),
                        float(t.specular[r2]),
                    )
                )
            frame.extra_distant = extra
            if len(order) > 4:
                self._warn_once(f"{len(order)} distant lights: only the 4 brightest are used")
        domes = t.rows_of_type(prims.DOME_LIGHT)
        domes = domes[t.enabled[domes]]
        amb = t.intensity[domes].sum(axis=0).astype(np.float64) if len(domes) else np.zeros(3)
        frame.ambient = amb + self.settings.ambient

    def _warn_once(self, msg: str) -> None:
        if msg not in self._seen_warnings:
            self._seen_warnings.add(msg)
            self.warnings.append(msg)

    def render_frame(
        self, time: float | None = None, seed: int | None = None, final: bool = True
    ) -> FrameContext:
        """One frame through all four phases. ``seed`` selects the frame's random
        sequence (stochastic methods); default: the frame counter."""
        s = self.settings
        if not self._in_sequence:
            self.accumulate.reset()  # a lone frame: no running average with older frames
        self.timings.start_frame()
        self._sync(time)
        if self.is_empty():
            raise RenderError("the stage has nothing to render (no geometry and no lights)")
        cam, exposure = self.camera()
        view: ViewSetup = view_setup(cam, s.width, s.height, exposure)
        self.buffers.resize(s.width, s.height)
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
        )
        with timed(self.timings, "prepare", None, False):
            self._sun_and_ambient(frame)
            for t in self.tasks:
                t.sync(frame)
            for t in self.tasks:
                with timed(self.timings, "prepare." + t.name, None, False):
                    t.prepare(frame)
        with timed(self.timings, "commit.lights", None, False):
            frame.stats["light_upload"] = self.delegate.upload_fov_lights()
        prev = self._prev_view_proj if self._prev_view_proj is not None else view.view_proj
        big = (math.ceil(s.width / 128), math.ceil(s.height / 128))
        self.uniforms.update(
            pack_frame_block(
                view,
                prev,
                frame.sun,
                frame.ambient,
                frame.light_count,
                fidx,
                frame.seed,
                big,
                frame.extra_distant,
            )
        )
        for t in self.tasks:
            if t.only_final and not final:
                continue
            with timed(self.timings, t.name, self.ctx, s.profile):
                t.execute(frame)
        self._prev_view_proj = view.view_proj
        park(self.ctx)
        self.frame_index += 1
        self.timings.end_frame()
        frame.stats["programs_compiled"] = shader_library(self.ctx).compiled
        return frame

    def render(self, time: float | None = None, accumulate: int | None = None) -> FrameContext:
        """Render ``accumulate`` frames (distinct seeds, same time) and average them."""
        n = max(1, int(accumulate or self.settings.accumulate))
        self.accumulate.reset()
        frame = None
        self._in_sequence = True
        try:
            for i in range(n):
                frame = self.render_frame(time, final=i == n - 1)
        finally:
            self._in_sequence = False
        return frame

    @property
    def aovs(self) -> dict[str, np.ndarray]:
        return self.aov_output.results

    def request_aovs(self, names) -> None:
        self.aov_output.requested = set(names) | {"color"}

    def release(self) -> None:
        park(self.ctx)
        for t in self.tasks:
            t.release()
        for vao in self._fs_vaos.values():
            vao.release()
        self._fs_vaos.clear()
        self.buffers.release()
        self.uniforms.release()
        self.delegate.release()
        self.scene_index.close()


_ = TYPE_CODES
