"""Directional shadow maps of a textured dome (issue 37).

The reference method lights a textured dome by importance sampling it
(``scene.dome.DomeSampler``): each frame draws ``limits.DOME_REFERENCE_SAMPLES``
directions and gives each an orthographic depth map fitted to the scene bounds, tiled
into one depth atlas (``shaders/common/dome_sampled.glsl`` reads it). The frames of an
accumulation draw fresh directions, so ``--accumulate`` converges to the dome's
shadowed light.

The real-time methods' sky occlusion (:class:`SkyOcclusion`) uses the same maps for
``limits.DOME_OCCLUSION_SAMPLES`` fixed directions (the dome without its split-off sun),
drawn again only when the scene's draw batches or the dome change; the shader
(``shaders/common/dome_occlusion.glsl``) turns them into the share of the prefiltered
sky light that reaches a point. Render frame, metres.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import moderngl
import numpy as np

from .. import limits
from ..scene.dome import DomeSampler
from ..scene.prims import LightPrim
from .camera import look_at, orthographic
from .depth_draw import DepthDraw
from .gl import set_uniform
from .gl_delegate import GLRenderDelegate
from .link_masks import shadow_batches

#: The golden ratio's fractional part (the Fibonacci lattice's second axis step).
_GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0


@dataclass
class DomeSamples:
    """One frame's dome samples: directions to the light (n, 3), the illuminance each
    stands for (n, 3) lux (radiance / (n pdf)), world -> map clip (n, 4, 4), and the
    biases (n, 2): normal offset (m) and depth bias (clip depth units)."""

    directions: np.ndarray
    illuminance: np.ndarray
    view_proj: np.ndarray
    bias: np.ndarray


class DomeShadowMaps:
    """Owns the depth atlas and the sampling table of the current dome map."""

    def __init__(self, ctx: moderngl.Context, count: int = limits.DOME_REFERENCE_SAMPLES) -> None:
        self.ctx = ctx
        self.atlas: moderngl.Texture | None = None
        self.fbo: moderngl.Framebuffer | None = None
        self._sampler: DomeSampler | None = None
        self._image: np.ndarray | None = None
        self.count = count
        self.cols = math.ceil(math.sqrt(count))
        self.rows = math.ceil(count / self.cols)

    def draw_samples(
        self, lp: LightPrim, seed: int, sample_index: int, without_sun: bool = False
    ) -> DomeSamples | None:
        """Directions for dome ``lp`` (None without a map): a fresh stratified set per
        (seed, sample_index). ``without_sun``: drawn from the map without its split-off
        sun (``DomeMap.rest``; the whole map when it has none)."""
        dm = lp.dome_map
        if dm is None:
            return None
        img = dm.rest if without_sun and dm.rest is not None else dm.latlong
        if img is not self._image:
            self._sampler = DomeSampler(img)
            self._image = img
        assert self._sampler is not None
        n = self.count
        rng = np.random.default_rng([seed & 0xFFFFFFFF, sample_index])
        # A Fibonacci lattice over (row, column) with a random toroidal shift: n points
        # stratified in both CDF dimensions; fresh shift and texel offsets per frame.
        u = rng.random((n, 4))
        k = np.arange(n)
        u[:, 0] = (k + 0.5) / n
        u[:, 1] = k * _GOLDEN
        u[:, :2] = (u[:, :2] + rng.random(2)) % 1.0
        d, rad, pdf = self._sampler.sample(u)
        e = rad * np.asarray(lp.dome_scale, dtype=np.float64)[None, :]
        e = e / (n * np.maximum(pdf, 1e-30))[:, None]
        return DomeSamples(d, e, np.zeros((n, 4, 4)), np.zeros((n, 2)))

    def render(self, delegate: GLRenderDelegate, samples: DomeSamples, mask: int) -> None:
        """Fit each sample's orthographic map to the scene bounds and draw the
        batches casting ``mask``'s shadows into its atlas tile."""
        lo, hi = delegate.scene_bounds
        size = limits.DOME_SHADOW_MAP_PX
        self._allocate(size)
        assert self.fbo is not None
        ctx = self.ctx
        self.fbo.use()
        ctx.viewport = (0, 0, size * self.cols, size * self.rows)
        self.fbo.clear(depth=1.0)
        if not np.all(hi > lo):
            samples.view_proj[:] = np.eye(4)
            return
        center = 0.5 * (lo + hi)
        radius = 0.5 * float(np.linalg.norm(hi - lo)) * 1.01 + 1e-4
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE)
        draw = DepthDraw(ctx, "depth_only.vert", "depth_only.frag")
        batches = list(shadow_batches(delegate.batches, mask))
        texel = 2.0 * radius / size
        for k, d in enumerate(samples.directions):
            to_light = np.linalg.inv(look_at(center + d * radius * 2.0, center))
            proj = orthographic(radius, radius, 0.0, 0.0, radius, 3.0 * radius)
            vp = to_light @ proj
            samples.view_proj[k] = vp
            samples.bias[k] = (1.5 * texel, 1.0 * texel / (2.0 * radius))
            col, row = k % self.cols, k // self.cols
            ctx.viewport = (col * size, row * size, size, size)
            draw.set("u_light_view_proj", np.asarray(vp, dtype=np.float32))
            for b in batches:
                draw.draw(delegate, b)
        ctx.disable(moderngl.DEPTH_TEST)

    def bind(self, prog: moderngl.Program, samples: DomeSamples, unit: int) -> int:
        """Bind the atlas and the samples' uniforms; returns the next texture unit."""
        if self.atlas is None or "u_dome_shadow" not in prog:
            return unit
        self.atlas.use(unit)
        set_uniform(prog, "u_dome_shadow", unit)
        n = len(samples.directions)
        pad = limits.DOME_REFERENCE_SAMPLES - n  # the uniform arrays' size (LIM_DOME_SAMPLES)
        vp = np.concatenate([samples.view_proj, np.zeros((pad, 4, 4))])
        dirs = np.c_[samples.directions, samples.bias[:, 0]]
        illum = np.c_[samples.illuminance, samples.bias[:, 1]]
        set_uniform(prog, "u_dome_vp", vp.astype(np.float32))
        set_uniform(
            prog, "u_dome_dir", np.concatenate([dirs, np.zeros((pad, 4))]).astype(np.float32)
        )
        set_uniform(
            prog, "u_dome_illum", np.concatenate([illum, np.zeros((pad, 4))]).astype(np.float32)
        )
        set_uniform(prog, "u_dome_tiles", (float(self.cols), float(self.rows), float(n), 0.0))
        return unit + 1

    def _allocate(self, size: int) -> None:
        shape = (size * self.cols, size * self.rows)
        if self.atlas is None or self.atlas.size != shape:
            self.release()
            self.atlas = self.ctx.depth_texture(shape)
            self.atlas.compare_func = "<="
            self.atlas.filter = (moderngl.LINEAR, moderngl.LINEAR)
            self.atlas.repeat_x = self.atlas.repeat_y = False
            self.fbo = self.ctx.framebuffer(depth_attachment=self.atlas)

    def release(self) -> None:
        if self.fbo is not None:
            self.fbo.release()
        if self.atlas is not None:
            self.atlas.release()
        self.fbo = None
        self.atlas = None


class SkyOcclusion:
    """The real-time methods' sky occlusion: :data:`limits.DOME_OCCLUSION_SAMPLES` dome
    directions with their shadow maps, re-drawn when the draw batches (rebuilt on any
    geometry or transform change), the dome's map, its shadow mask, the sun split or
    the frame's sample index change. The directions are a fixed set per sample index
    (``FrameContext.sample_index``: 0 for a lone frame, so a still view draws them once
    and does not flicker), a fresh stratified set for each frame an accumulation or taa
    integrates, so those converge to the dome's shadowed light instead of keeping the
    few directions' shadow wedges."""

    #: Seed of the directions (with the sample index).
    SEED = 0x5C1

    def __init__(self, ctx: moderngl.Context) -> None:
        self.maps = DomeShadowMaps(ctx, limits.DOME_OCCLUSION_SAMPLES)
        self.samples: DomeSamples | None = None
        self._key: tuple = ()
        self._batches: object = None
        self.draws = 0  # times the maps were drawn (tests, stats)

    def prepare(
        self,
        delegate: GLRenderDelegate,
        lp: LightPrim,
        mask: int,
        without_sun: bool,
        sample_index: int = 0,
    ) -> DomeSamples | None:
        """This frame's samples, their maps drawn if anything they depend on changed."""
        key = (id(lp.dome_map), mask, without_sun, sample_index)
        if self.samples is not None and key == self._key and self._batches is delegate.batches:
            return self.samples
        samples = self.maps.draw_samples(lp, self.SEED, sample_index, without_sun)
        if samples is None:
            return None
        self.maps.render(delegate, samples, mask)
        self.samples, self._key, self._batches = samples, key, delegate.batches
        self.draws += 1
        return samples

    def bind(self, prog: moderngl.Program, unit: int) -> int:
        """Bind the atlas and the samples' uniforms; returns the next texture unit."""
        if self.samples is None:
            return unit
        return self.maps.bind(prog, self.samples, unit)

    def release(self) -> None:
        self.maps.release()
        self.samples = None
        self._batches = None
