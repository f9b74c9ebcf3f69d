"""The shadow-atlas view: the atlas texture (depth as grey) with every map's outline,
static maps green, dynamic maps cyan, maps waiting for an update (dirty) red. Only
the used corner of the atlas is shown (maps are packed from the origin), so small
maps stay visible.

The atlas (``ShadowCapturer.atlas``, a 16-bit depth texture) is drawn into a square
the viewport's height on the GPU and read back at that size (never the full atlas);
the outlines come from the scheduler's rects (texels, border included)."""

from __future__ import annotations

from typing import TYPE_CHECKING, cast

import moderngl
import numpy as np

if TYPE_CHECKING:
    from ..renderer.engine import Engine

STATIC = (60, 220, 60)
DYNAMIC = (60, 200, 230)
PENDING = (240, 50, 40)

_VS = """
#version 430 core
out vec2 uv;
void main() {
    vec2 p = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));
    uv = p;
    gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}
"""
_FS = """
#version 430 core
uniform sampler2D atlas;
uniform float u_scale;
in vec2 uv;
out vec4 color;
void main() { color = vec4(texture(atlas, uv * u_scale).r, 0.0, 0.0, 1.0); }
"""


class AtlasView:
    """Draws the atlas of an engine's shadow pass into an (h, w, 3) uint8 image."""

    def __init__(self, ctx: moderngl.Context) -> None:
        self.ctx = ctx
        self.prog = ctx.program(vertex_shader=_VS, fragment_shader=_FS)
        self.vao = ctx.vertex_array(self.prog, [])
        self.sampler = ctx.sampler(filter=(moderngl.NEAREST, moderngl.NEAREST))
        self._fbo: moderngl.Framebuffer | None = None

    def image(self, engine: Engine, width: int, height: int) -> np.ndarray | None:
        """The view (top row first), or None when the stage has no shadowed lights yet."""
        task = engine.task("shadow_atlas")
        capturer = getattr(task, "capturer", None)
        if task is None or capturer is None:
            return None
        sched = task.scheduler  # type: ignore[attr-defined]
        rects = sched.atlas.rects()
        # the used corner of the atlas (maps are packed from the origin), a power of two
        used = max((max(r.x, r.y) + r.size for r in rects.values()), default=capturer.size)
        region = min(capturer.size, 1 << max(int(used - 1).bit_length(), 5))
        side = max(8, min(width, height))
        if self._fbo is None or self._fbo.size != (side, side):
            if self._fbo is not None:
                for a in self._fbo.color_attachments:
                    a.release()
                self._fbo.release()
            self._fbo = self.ctx.framebuffer([self.ctx.texture((side, side), 4, dtype="f4")])
        with self.ctx.scope(framebuffer=self._fbo, enable_only=moderngl.NOTHING):
            self.ctx.viewport = (0, 0, side, side)
            capturer.atlas.use(0)
            self.sampler.use(0)
            cast(moderngl.Uniform, self.prog["atlas"]).value = 0
            cast(moderngl.Uniform, self.prog["u_scale"]).value = region / capturer.size
            self.vao.render(moderngl.TRIANGLES, vertices=3)
            self.sampler.clear(0)
            raw = self._fbo.read(components=1, dtype="f4")
        d = np.frombuffer(raw, np.float32).reshape(side, side)[::-1]
        near = d < 1.0
        g = np.zeros_like(d)
        if near.any():  # contrast from the depths present (cleared texels stay black)
            lo, hi = float(d[near].min()), float(d[near].max())
            g[near] = 1.0 - 0.85 * (d[near] - lo) / max(hi - lo, 1e-6)
        sq = np.repeat((g * 200.0).astype(np.uint8)[..., None], 3, axis=-1)
        scale = side / float(region)
        lights = engine.delegate.lights
        for key, rect in rects.items():
            sp = lights.get(key)
            dyn = sp is not None and sp.light is not None and sp.light.shadow_update == "dynamic"
            col = PENDING if sched.is_dirty(key) else (DYNAMIC if dyn else STATIC)
            # atlas texel rows are GL bottom-up; the image is top row first
            x0 = int(rect.x * scale)
            x1 = max(x0 + 1, int((rect.x + rect.size) * scale) - 1)
            y1 = side - 1 - int(rect.y * scale)
            y0 = max(0, min(y1 - 1, side - int((rect.y + rect.size) * scale)))
            x1, y1 = min(x1, side - 1), min(y1, side - 1)
            sq[y0, x0 : x1 + 1] = col
            sq[y1, x0 : x1 + 1] = col
            sq[y0 : y1 + 1, x0] = col
            sq[y0 : y1 + 1, x1] = col
        out = np.full((height, width, 3), 24, np.uint8)
        ox, oy = (width - side) // 2, (height - side) // 2
        out[oy : oy + side, ox : ox + side] = sq[: min(side, height), : min(side, width)]
        return out

    def release(self) -> None:
        if self._fbo is not None:
            for a in self._fbo.color_attachments:
                a.release()
            self._fbo.release()
        self.prog.release()
