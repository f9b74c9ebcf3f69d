"""Per-frame state shared by tasks, and the named render buffers they exchange."""

from __future__ import annotations

import time
from collections import defaultdict
from dataclasses import dataclass, field

import moderngl
import numpy as np

from .camera import ViewSetup
from .frame_data import SunSetup


@dataclass
class RenderSettings:
    width: int = 256
    #: None or 0: from the camera's aspect ratio.
    height: int | None = 144
    camera: str | None = None
    lighting: str = "reference"
    seed: int = 0
    accumulate: int = 1
    sun_shadow_size: int = 2048
    #: Local-light shadows from the atlas (False: every local light unshadowed).
    shadows: bool = True
    #: Shadow atlas side (texels) and per-frame capture budget (texels rendered);
    #: None = limits.SHADOW_ATLAS_SIZE_DEFAULT / SHADOW_UPDATE_BUDGET_TEXELS_DEFAULT.
    shadow_atlas_size: int | None = None
    shadow_budget: int | None = None
    #: Local shadow filter: "pcf" (4-tap gather) or "stochastic" (gather + a random
    #: sub-texel offset per pixel and frame; converges softer under accumulation).
    shadow_filter: str = "pcf"
    #: Extra uniform ambient radiance (nits) added to the dome, e.g. for thumbnails.
    ambient: float = 0.0
    #: ``ctx.finish()`` after every task so per-task wall times are real (benchmarks).
    profile: bool = False
    #: Lighting-method specific options (``render.lighting.<method>``).
    method_options: dict = field(default_factory=dict)


class Timings:
    """Wall-clock per task (ms), per frame."""

    def __init__(self) -> None:
        self.frames: list[dict[str, float]] = []
        self.current: dict[str, float] = defaultdict(float)

    def start_frame(self) -> None:
        self.current = defaultdict(float)

    def end_frame(self) -> None:
        self.frames.append(dict(self.current))

    def add(self, name: str, ms: float) -> None:
        self.current[name] += ms

    def medians(self, skip: int = 0) -> dict[str, float]:
        frames = self.frames[skip:] or self.frames
        keys = sorted({k for f in frames for k in f})
        return {k: float(np.median([f.get(k, 0.0) for f in frames])) for k in keys}


class timed:
    """Context manager adding a task's wall time (optionally after ctx.finish())."""

    def __init__(self, timings: Timings, name: str, ctx: moderngl.Context | None, finish: bool):
        self.t, self.name, self.ctx, self.finish = timings, name, ctx, finish

    def __enter__(self):
        self.t0 = time.perf_counter()
        return self

    def __exit__(self, *exc):
        if self.finish and self.ctx is not None:
            self.ctx.finish()
        self.t.add(self.name, (time.perf_counter() - self.t0) * 1e3)
        return False


class RenderBuffers:
    """Named textures/framebuffers sized to the viewport (Hydra's render buffers)."""

    def __init__(self, ctx: moderngl.Context) -> None:
        self.ctx = ctx
        self.size = (0, 0)
        self.textures: dict[str, moderngl.Texture] = {}
        self.fbos: dict[str, moderngl.Framebuffer] = {}
        self._fbo_deps: dict[str, tuple[str, ...]] = {}

    def resize(self, width: int, height: int) -> None:
        if (width, height) == self.size:
            return
        self.release()
        self.size = (width, height)

    def texture(self, name: str, components: int, dtype: str, size=None, nearest=True):
        size = size or self.size
        t = self.textures.get(name)
        if t is None or t.size != tuple(size) or t.components != components or t.dtype != dtype:
            if t is not None:
                t.release()
                self._drop_fbos_using(name)
            t = self.ctx.texture(size, components, dtype=dtype)
            if nearest:
                t.filter = (moderngl.NEAREST, moderngl.NEAREST)
            t.repeat_x = t.repeat_y = False
            self.textures[name] = t
        return t

    def _drop_fbos_using(self, tex_name: str) -> None:
        for fb_name, deps in list(self._fbo_deps.items()):
            if tex_name in deps:
                self.fbos.pop(fb_name).release()
                del self._fbo_deps[fb_name]

    def set_texture(self, name: str, tex: moderngl.Texture) -> None:
        old = self.textures.get(name)
        if old is not None and old is not tex:
            old.release()
            self._drop_fbos_using(name)
        self.textures[name] = tex

    def framebuffer(self, name: str, colors: list[str], depth: str | None = None):
        fb = self.fbos.get(name)
        if fb is None:
            fb = self.ctx.framebuffer(
                color_attachments=[self.textures[c] for c in colors],
                depth_attachment=self.textures[depth] if depth else None,
            )
            self.fbos[name] = fb
            self._fbo_deps[name] = (*colors, *([depth] if depth else []))
        return fb

    def release(self) -> None:
        for fb in self.fbos.values():
            fb.release()
        for t in self.textures.values():
            t.release()
        self.fbos.clear()
        self.textures.clear()
        self._fbo_deps.clear()


@dataclass
class FrameContext:
    ctx: moderngl.Context
    settings: RenderSettings
    view: ViewSetup
    buffers: RenderBuffers
    timings: Timings
    frame_index: int = 0
    seed: int = 0
    sun: SunSetup = field(default_factory=SunSetup)
    ambient: np.ndarray = field(default_factory=lambda: np.zeros(3))
    #: Extra distant lights (direction to light, illuminance lux RGB, diffuse, specular).
    extra_distant: list = field(default_factory=list)
    light_count: int = 0
    stats: dict = field(default_factory=dict)
    #: Name of the buffer holding this frame's scene-linear lighting result.
    color_buffer: str = "lighting"
    #: Last frame of an accumulation sequence (display + readback run only then).
    final: bool = True

    def timings_scope(self, name: str) -> timed:
        """Time a sub-pass as ``lighting.<name>`` (ctx.finish() when profiling)."""
        return timed(self.timings, "lighting." + name, self.ctx, self.settings.profile)
