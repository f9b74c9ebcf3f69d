"""Shadow-map capture into the 16-bit atlas (GL): :class:`ShadowCapturer`.

Renders a light's depth (a perspective map for spots, a 6-face cube for omni lights)
and copies it into its atlas rect with ``shadow_copy.frag``. What is captured (the
:class:`~stb_hydra.shadows.capture.Capture` of a light), its matrices and the map
record layout are GL-free, in :mod:`stb_hydra.shadows.capture`.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, cast

import moderngl
import numpy as np

from .. import limits
from ..shadows.atlas import AtlasRect
from ..shadows.capture import (
    BIAS_TEXELS,
    Capture,
    face_rotations,
    map_record,
    spot_view_proj,
    texel_angle,
)
from .camera import perspective
from .gl import set_uniform, shader_library

if TYPE_CHECKING:
    from .gl_delegate import DrawBatch, GLRenderDelegate


class ShadowCapturer:
    """Owns the atlas texture and the temporary depth targets."""

    def __init__(self, ctx: moderngl.Context, size: int) -> None:
        self.ctx = ctx
        self.size = size
        self.atlas = ctx.texture((size, size), 1, dtype="nu2")
        self.atlas.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self.atlas.repeat_x = self.atlas.repeat_y = False
        self.atlas_fbo = ctx.framebuffer(color_attachments=[self.atlas])
        self.atlas_fbo.clear(1.0, 1.0, 1.0, 1.0)
        self._temps: dict[tuple[int, int], tuple[moderngl.Texture, moderngl.Framebuffer]] = {}
        self._faces = face_rotations().astype(np.float32)
        self.captures = 0
        self.texels = 0

    def _temp(self, w: int, h: int) -> tuple[moderngl.Texture, moderngl.Framebuffer]:
        t = self._temps.get((w, h))
        if t is None:
            tex = self.ctx.depth_texture((w, h))
            tex.compare_func = ""  # read raw depth (moderngl enables comparison by default)
            tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
            tex.repeat_x = tex.repeat_y = False
            t = (tex, self.ctx.framebuffer(depth_attachment=tex))
            self._temps[(w, h)] = t
        return t

    def capture(
        self, delegate: GLRenderDelegate, key: str, c: Capture, rect: AtlasRect, dynamic: bool
    ) -> None:
        """Render the light's depth and copy it into ``rect`` of the atlas."""
        ctx = self.ctx
        border = limits.SHADOW_MAP_BORDER_PX
        interior = rect.size - 2 * border
        if interior < 4:
            return
        prog = shader_library(ctx).program("depth_only.vert", "depth_only.frag")
        batches = _batches_in_range(delegate, c, dynamic)
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE | moderngl.BLEND)
        if c.omni:
            f = max(interior // 2, 4)
            tex, fbo = self._temp(3 * f, 2 * f)
            fbo.use()
            fbo.clear(depth=1.0)
            proj = perspective(1.0, 1.0, 0.0, 0.0, c.near, c.range)
            pos = np.array(c.position)
            for i in range(6):
                rot = np.eye(4)
                rot[:3, :3] = self._faces[i]
                trans = np.eye(4)
                trans[3, :3] = -pos
                vp = trans @ rot @ proj
                ctx.viewport = ((i % 3) * f, (i // 3) * f, f, f)
                set_uniform(prog, "u_light_view_proj", vp.astype(np.float32))
                for b in batches:
                    delegate.vertex_array(b, prog, depth_only=True).render(
                        moderngl.TRIANGLES, instances=b.count
                    )
            self.texels += 6 * f * f
        else:
            tex, fbo = self._temp(interior, interior)
            fbo.use()
            fbo.clear(depth=1.0)
            ctx.viewport = (0, 0, interior, interior)
            set_uniform(prog, "u_light_view_proj", spot_view_proj(c).astype(np.float32))
            for b in batches:
                delegate.vertex_array(b, prog, depth_only=True).render(
                    moderngl.TRIANGLES, instances=b.count
                )
            self.texels += interior * interior
        ctx.disable(moderngl.DEPTH_TEST)
        # copy into the atlas
        cp = shader_library(ctx).program("fullscreen.vert", "shadow_copy.frag")
        self.atlas_fbo.use()
        ctx.viewport = (rect.x, rect.y, rect.size, rect.size)
        tex.use(0)
        cast(moderngl.Uniform, cp["u_depth"]).value = 0
        set_uniform(cp, "u_rect", (rect.x, rect.y, rect.size, border))
        set_uniform(cp, "u_omni", 1 if c.omni else 0)
        set_uniform(cp, "u_near", float(c.near))
        set_uniform(cp, "u_far", float(c.range))
        set_uniform(cp, "u_range", float(c.range))
        set_uniform(cp, "u_tan_half", math.tan(c.spot_half_angle) if not c.omni else 1.0)
        set_uniform(cp, "u_bias_angle", BIAS_TEXELS * texel_angle(c, interior))
        if "u_face_rot" in cp:
            cast(moderngl.Uniform, cp["u_face_rot"]).write(self._faces.tobytes())
        vao = delegate_fullscreen(ctx, cp)
        vao.render(moderngl.TRIANGLES, vertices=3)
        self.captures += 1

    def record(self, c: Capture, rect: AtlasRect) -> np.ndarray:
        """The std430 ``ShadowMap`` record (28 floats) of a captured map."""
        return map_record(c, rect, self.size)

    def release(self) -> None:
        for tex, fbo in self._temps.values():
            fbo.release()
            tex.release()
        self._temps.clear()
        self.atlas_fbo.release()
        self.atlas.release()


_fs_vaos: dict[int, moderngl.VertexArray] = {}


def delegate_fullscreen(ctx: moderngl.Context, prog: moderngl.Program) -> moderngl.VertexArray:
    vao = _fs_vaos.get(prog.glo)
    if vao is None:
        vao = ctx.vertex_array(prog, [])
        _fs_vaos[prog.glo] = vao
    return vao


def _batches_in_range(delegate: GLRenderDelegate, c: Capture, dynamic: bool) -> list[DrawBatch]:
    """Draw batches whose world bounds touch the light's range sphere; static maps
    skip dynamic geometry."""
    out = []
    p = np.array(c.position)
    for b in delegate.batches:
        if b.dynamic and not dynamic:
            continue
        lo, hi = b.bounds
        d = p - np.clip(p, lo, hi)
        if float(d @ d) <= c.range * c.range:
            out.append(b)
    return out
