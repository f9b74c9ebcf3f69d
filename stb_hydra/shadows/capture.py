"""Shadow-map capture into the 16-bit atlas (GL).

* Spot lights (cone <= ``SPOT_MAX_HALF_ANGLE_DEG``): a perspective depth map
  rendered from the light into a temporary depth target of the map's interior size.
* Omni lights (no cone or a wide one; disk/rect hemispheres too): a cube of 6
  faces rendered into a temporary 3F x 2F depth grid, F = interior / 2.
* Copy (``shadow_copy.frag``) into the atlas rect: linearise, distance along
  the texel's ray, bias, normalise by the range, 3 px border (clamp for spot,
  octahedral mirroring for omni).

Every capture records a :class:`Capture` (the light transform it used); lookups
use that, not the light's current transform.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import moderngl
import numpy as np

from .. import limits
from ..renderer.camera import look_at, perspective
from ..renderer.gl import set_uniform, shader_library
from .atlas import AtlasRect

#: Widest cone captured with one perspective map; wider cones use an octahedral map.
SPOT_MAX_HALF_ANGLE_DEG = 75.0
#: Bias as a multiple of the texel's angular size (x distance), applied at copy.
BIAS_TEXELS = 1.0
#: Floats per std430 ``ShadowMap`` record (``common/shadow.glsl``): mat4 + 3 vec4.
RECORD_FLOATS = 28
#: Receiver normal offset, in texels at the receiver's distance (lookup side).
NORMAL_BIAS_TEXELS = 0.6

_FACES = (  # forward, up
    ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0)),
    ((-1.0, 0.0, 0.0), (0.0, 1.0, 0.0)),
    ((0.0, 1.0, 0.0), (0.0, 0.0, 1.0)),
    ((0.0, -1.0, 0.0), (0.0, 0.0, 1.0)),
    ((0.0, 0.0, 1.0), (0.0, 1.0, 0.0)),
    ((0.0, 0.0, -1.0), (0.0, 1.0, 0.0)),
)


@dataclass(frozen=True)
class Capture:
    """The light transform a map is captured with (exact-compare 'moved' key)."""

    position: tuple[float, float, float]
    direction: tuple[float, float, float]
    range: float
    near: float
    spot_half_angle: float  # radians; <= 0: omni

    @property
    def omni(self) -> bool:
        return self.spot_half_angle <= 0.0


def capture_for(position, direction, range_m, radius, cone_cutoff_rad, emission) -> Capture:
    """Capture parameters of a light (positions in metres, cone cut-off in radians)."""
    half = float(cone_cutoff_rad)
    spot = half < math.radians(SPOT_MAX_HALF_ANGLE_DEG) and emission != 2
    near = max(float(radius) * 1.05, 0.01)
    rng = max(float(range_m), near * 4.0)
    return Capture(
        tuple(float(x) for x in position),
        tuple(float(x) for x in direction),
        rng,
        near,
        min(half * 1.02 + math.radians(1.0), math.radians(85.0)) if spot else 0.0,
    )


def spot_view_proj(c: Capture) -> np.ndarray:
    pos = np.array(c.position)
    d = np.array(c.direction)
    to_world = look_at(pos, pos + d, up=_up_for(d))
    t = math.tan(c.spot_half_angle)
    return np.linalg.inv(to_world) @ perspective(t, t, 0.0, 0.0, c.near, c.range)


def _up_for(d: np.ndarray):
    return (0.0, 0.0, 1.0) if abs(float(d[1])) > 0.9 else (0.0, 1.0, 0.0)


def face_rotations() -> np.ndarray:
    """(6, 3, 3) world -> face-view rotations (row-vector), face order +X -X +Y -Y +Z -Z."""
    out = np.zeros((6, 3, 3))
    for i, (f, up) in enumerate(_FACES):
        m = look_at(np.zeros(3), np.array(f), up=up)
        out[i] = np.linalg.inv(m)[:3, :3]
    return out


def texel_angle(c: Capture, interior: int) -> float:
    """Angular size of one map texel (radians), for biases."""
    if c.omni:
        return math.sqrt(4.0 * math.pi) / max(interior, 1)
    return 2.0 * math.tan(c.spot_half_angle) / max(interior, 1)


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

    def _temp(self, w: int, h: int):
        t = self._temps.get((w, h))
        if t is None:
            tex = self.ctx.depth_texture((w, h))
            tex.compare_func = ""  # read raw depth (moderngl enables comparison by default)
            tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
            tex.repeat_x = tex.repeat_y = False
            t = (tex, self.ctx.framebuffer(depth_attachment=tex))
            self._temps[(w, h)] = t
        return t

    def capture(self, delegate, key: str, c: Capture, rect: AtlasRect, dynamic: bool) -> None:
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
        cp["u_depth"].value = 0
        set_uniform(cp, "u_rect", (rect.x, rect.y, rect.size, border))
        set_uniform(cp, "u_omni", 1 if c.omni else 0)
        set_uniform(cp, "u_near", float(c.near))
        set_uniform(cp, "u_far", float(c.range))
        set_uniform(cp, "u_range", float(c.range))
        set_uniform(cp, "u_tan_half", math.tan(c.spot_half_angle) if not c.omni else 1.0)
        set_uniform(cp, "u_bias_angle", BIAS_TEXELS * texel_angle(c, interior))
        if "u_face_rot" in cp:
            cp["u_face_rot"].write(self._faces.tobytes())
        vao = delegate_fullscreen(ctx, cp)
        vao.render(moderngl.TRIANGLES, vertices=3)
        self.captures += 1

    def record(self, c: Capture, rect: AtlasRect) -> np.ndarray:
        """The std430 ``ShadowMap`` record (28 floats) of a captured map."""
        border = limits.SHADOW_MAP_BORDER_PX
        interior = rect.size - 2 * border
        rec = np.zeros(RECORD_FLOATS, dtype=np.float32)
        if not c.omni:
            rec[0:16] = spot_view_proj(c).astype(np.float32).reshape(16)
        rec[16:19] = c.position
        rec[19] = c.range
        rec[20:24] = (rect.x + border, rect.y + border, interior, 1.0 if c.omni else 0.0)
        rec[24:28] = (c.near, texel_angle(c, interior), 1.0 / self.size, NORMAL_BIAS_TEXELS)
        return rec

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


def _batches_in_range(delegate, c: Capture, dynamic: bool):
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
