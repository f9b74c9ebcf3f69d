"""The sun's shadow map: one depth map fitted to the part of the view frustum
that intersects the scene bounds, in the sun's orthographic space."""

from __future__ import annotations

from typing import TYPE_CHECKING

import moderngl
import numpy as np

from ...scene.links import ALL_GROUPS
from ..camera import ViewSetup, look_at, orthographic
from ..depth_draw import DepthDraw
from ..frame import FrameContext
from ..graph import Imported, Rec
from ..link_masks import shadow_batches
from ..records import DistantLights, SunShadowMap
from .base import Pass

if TYPE_CHECKING:
    from ..gl_delegate import GLRenderDelegate


def _frustum_corners(view: ViewSetup, max_dist: float) -> np.ndarray:
    tx, ty = view.tan_half
    ox, oy = view.offset
    pts = []
    for d in (view.near, min(view.far, max_dist)):
        for sx in (-1, 1):
            for sy in (-1, 1):
                if view.orthographic:
                    p = np.array([sx * tx + ox, sy * ty + oy, -d, 1.0])
                else:
                    p = np.array([(sx * tx + ox) * d, (sy * ty + oy) * d, -d, 1.0])
                pts.append(p @ view.inv_view)
    return np.array(pts)[:, :3]


class SunShadowTask(Pass):
    """Fits the sun's shadow frustum (prepare: sets the sun's matrix and biases on
    ``DistantLights``) and renders its depth map (``SunShadowMap``)."""

    name = "shadow"
    reads = (Imported("meshes"), Imported("light_table"), Rec(DistantLights))
    writes = (Rec(DistantLights), Rec(SunShadowMap))

    def __init__(self, delegate: GLRenderDelegate) -> None:
        super().__init__(delegate)
        self.texture: moderngl.Texture | None = None
        self.fbo: moderngl.Framebuffer | None = None
        self._light_vp: np.ndarray | None = None
        self._shadow_mask = ALL_GROUPS

    def prepare(self, frame: FrameContext) -> None:
        dist = frame.get(DistantLights)
        sun = dist.sun
        t = self.delegate.light_table
        self._shadow_mask = int(t.shadow_link_mask[dist.rows[0]]) if dist.rows else ALL_GROUPS
        rec = SunShadowMap()
        frame.put(rec)
        if not (sun.enabled and sun.shadow):
            return
        lo, hi = self.delegate.scene_bounds
        if not np.all(hi > lo):
            sun.shadow = False
            return
        d = sun.direction_to_sun / np.linalg.norm(sun.direction_to_sun)
        center = 0.5 * (lo + hi)
        radius = 0.5 * float(np.linalg.norm(hi - lo))
        light_to_world = look_at(center + d * radius * 2.0, center)
        to_light = np.linalg.inv(light_to_world)
        box = np.array(
            [[x, y, z, 1.0] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
        )
        scene_ls = (box @ to_light)[:, :3]
        fr = np.c_[_frustum_corners(frame.view, 4.0 * radius + frame.view.near), np.ones(8)]
        fr_ls = (fr @ to_light)[:, :3]
        xy_lo = np.maximum(scene_ls[:, :2].min(0), fr_ls[:, :2].min(0))
        xy_hi = np.minimum(scene_ls[:, :2].max(0), fr_ls[:, :2].max(0))
        if np.any(xy_hi <= xy_lo):
            xy_lo, xy_hi = scene_ls[:, :2].min(0), scene_ls[:, :2].max(0)
        half = 0.5 * (xy_hi - xy_lo) * 1.02 + 1e-4
        half = np.full(2, max(half))  # square texels
        off = 0.5 * (xy_hi + xy_lo)
        near = max(-scene_ls[:, 2].max() - 1e-3, 1e-4)
        far = -scene_ls[:, 2].min() + 1e-3
        proj = orthographic(half[0], half[1], off[0], off[1], near, far)
        sun.view_proj = to_light @ proj
        size = frame.settings.sun_shadow_size
        texel_world = 2.0 * half[0] / size
        sun.texel = 1.0 / size
        sun.normal_bias = 1.5 * texel_world
        sun.depth_bias = 1.0 * texel_world / max(far - near, 1e-6)
        self._light_vp = sun.view_proj
        frame.stats["sun_shadow_texel_m"] = texel_world
        self._allocate(frame.ctx, size)
        rec.texture = self.texture

    def _allocate(self, ctx: moderngl.Context, size: int) -> None:
        if self.texture is None or self.texture.size != (size, size):
            self.release()
            self.texture = ctx.depth_texture((size, size))
            self.texture.compare_func = "<="
            self.texture.filter = (moderngl.LINEAR, moderngl.LINEAR)
            self.texture.repeat_x = self.texture.repeat_y = False
            self.fbo = ctx.framebuffer(depth_attachment=self.texture)

    def execute(self, frame: FrameContext) -> None:
        sun = frame.sun
        if not (sun.enabled and sun.shadow) or self.fbo is None:
            return
        ctx = frame.ctx
        size = frame.settings.sun_shadow_size
        self.fbo.use()
        ctx.viewport = (0, 0, size, size)
        self.fbo.clear(depth=1.0)
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE)
        draw = DepthDraw(ctx, "depth_only.vert", "depth_only.frag")
        draw.set("u_light_view_proj", np.asarray(self._light_vp, dtype=np.float32))
        delegate = self.delegate
        for b in shadow_batches(delegate.batches, self._shadow_mask):
            draw.draw(delegate, b)
        ctx.disable(moderngl.DEPTH_TEST)

    def release(self) -> None:
        if self.fbo is not None:
            self.fbo.release()
        if self.texture is not None:
            self.texture.release()
        self.fbo = self.texture = None
