"""The GPU half of ``stb bake``: direct light of static lights into lightmap texels.

The bake is one engine frame with two changes to its pass graph: ``light_cull`` keeps
every enabled static local light (not only those in the view frustum), and a
side-effect pass, :class:`LightmapBakePass`, runs after the shadow atlas and the
light upload. So the lights are packed, the shadow maps captured (offline budget:
every map, sized by the resolution policy for a ``limits.BAKE_SHADOW_VIEW_HEIGHT``
frame) and bound exactly as for the reference method, and the bake shader
(``shaders/bake_light.frag``) evaluates the shared light and shadow includes.

Per mesh: (1) rasterise it in lightmap space at ``BAKE_SUPERSAMPLE`` x the lightmap
resolution into a position/normal G-buffer -- edges drawn as lines first, then the
filled triangles over them, so texels a thin triangle only touches are covered too
(conservative coverage); (2) a full-screen pass lights every covered sample; (3) the
samples are box-filtered to lightmap texels (weighted by coverage) and covered texels
are dilated ``BAKE_DILATE_TEXELS`` times into the padding (seams stay lit under
bilinear lookups).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import cast

import moderngl
import numpy as np

from .. import limits
from ..renderer.engine import Engine
from ..renderer.frame import FrameContext
from ..renderer.fullscreen import draw_fullscreen
from ..renderer.gl import park, set_uniform, shader_library
from ..renderer.graph import Imported
from ..renderer.lighting.base import GBUFFER_INPUTS, READS
from ..renderer.lighting.reference import ReferenceLighting
from ..renderer.records import InViewLights, LightBuffer
from ..renderer.shader_constants import SSBO_BAKE_LIGHTS
from ..renderer.tasks.base import Pass
from ..renderer.tasks.light_cull import LightCullTask
from ..scene.prims import CONE_CUTOFF_TEST_RAD
from .unwrap import MeshLayout


@dataclass
class BakedMap:
    """One mesh's lightmap planes, (h, w, 3) float32 each, row 0 = v = 0 (GL order):
    ``diffuse`` irradiance (lux, diffuse multipliers applied); ``spec_top`` the
    strongest light's irradiance (lux, specular multipliers) and ``dir_top`` its unit
    direction (world); ``spec_2nd`` / ``dir_2nd`` the second strongest's;
    ``spec_rest`` / ``dir_rest`` the same for the other lights
    together (their mean direction, weighted by irradiance; length <= 1: shorter =
    spread). ``coverage`` (h, w) in [0, 1]."""

    diffuse: np.ndarray
    spec_top: np.ndarray
    dir_top: np.ndarray
    spec_2nd: np.ndarray
    dir_2nd: np.ndarray
    spec_rest: np.ndarray
    dir_rest: np.ndarray
    coverage: np.ndarray

    def planes(self) -> list[np.ndarray]:
        return [
            self.diffuse,
            self.spec_top,
            self.dir_top,
            self.spec_2nd,
            self.dir_2nd,
            self.spec_rest,
            self.dir_rest,
        ]


class StaticLightCull(LightCullTask):
    """``light_cull`` for the bake: every enabled static local light, in row order."""

    def prepare(self, frame: FrameContext) -> None:
        t = self.delegate.light_table
        rows = np.nonzero(t.local_mask() & t.static)[0]
        frame.put(
            InViewLights(
                rows=rows,
                has_cones=bool(np.any(t.cone_cutoff[rows] < np.float32(CONE_CUTOFF_TEST_RAD))),
                has_ies=bool(np.any(t.ies_layer[rows] >= 0)),
                has_focus=bool(np.any(t.focus[rows] > 0)),
            )
        )
        frame.stats["fov_lights"] = len(rows)


class LightmapBakePass(Pass):
    """Bakes every layout in ``layouts`` (results in ``self.maps`` by prim path)."""

    name = "lightmap_bake"
    # The lighting inputs less the G-buffer: nothing of the view is drawn for a bake.
    reads = (*(r for r in READS if r not in GBUFFER_INPUTS), Imported("meshes"))
    writes = ()
    side_effect = True

    def __init__(
        self,
        delegate: object,
        layouts: list[MeshLayout],
        progress: Callable[[MeshLayout], None] | None = None,
    ) -> None:
        super().__init__(delegate)  # type: ignore[arg-type]
        self.layouts = layouts
        self.progress = progress
        self.maps: dict[str, BakedMap] = {}
        self.light_count = 0
        #: Sum over meshes of lightmap texels x the lights whose range reaches it.
        self.texel_lights = 0

    def execute(self, frame: FrameContext) -> None:
        if self.maps:
            return  # baked on the first frame
        ctx = frame.ctx
        method = ReferenceLighting(self.delegate)
        defines = method.scene_defines(frame)
        self.light_count = frame.get(LightBuffer).count
        rows = frame.get(InViewLights).rows
        t = self.delegate.light_table
        pos = np.asarray(t.position[rows], dtype=np.float64).reshape(-1, 3)
        rng = np.asarray(t.range[rows], dtype=np.float64)
        lib = shader_library(ctx)
        raster = lib.program("bake_raster.vert", "bake_raster.frag")
        light = lib.program("fullscreen.vert", "bake_light.frag", defines)
        for lay in self.layouts:
            idx = mesh_lights(pos, rng, lay.P)
            self.texel_lights += lay.size[0] * lay.size[1] * len(idx)
            self.maps[lay.path] = self._bake_one(ctx, frame, method, raster, light, lay, idx)
            if self.progress is not None:
                self.progress(lay)

    def _bake_one(
        self,
        ctx: moderngl.Context,
        frame: FrameContext,
        method: ReferenceLighting,
        raster: moderngl.Program,
        light: moderngl.Program,
        lay: MeshLayout,
        light_idx: np.ndarray,
    ) -> BakedMap:
        ss = limits.BAKE_SUPERSAMPLE
        w, h = lay.size
        size = (w * ss, h * ss)
        pos = ctx.texture(size, 4, dtype="f4")
        nrm = ctx.texture(size, 4, dtype="f4")
        outs = [ctx.texture(size, 4, dtype="f4") for _ in range(7)]
        for t in (pos, nrm, *outs):
            t.filter = (moderngl.NEAREST, moderngl.NEAREST)
        fbo_g = ctx.framebuffer([pos, nrm])
        fbo_l = ctx.framebuffer(outs)
        verts = np.concatenate(
            [
                lay.tri_uv.reshape(-1, 2).astype(np.float32),
                lay.P.reshape(-1, 3).astype(np.float32),
                lay.N.reshape(-1, 3).astype(np.float32),
            ],
            axis=1,
        )
        m = len(lay.corners)
        edges = np.stack(
            [np.arange(3 * m), (np.arange(3 * m) // 3) * 3 + (np.arange(3 * m) + 1) % 3]
        )
        vbo = ctx.buffer(np.ascontiguousarray(verts).tobytes())
        # One element at least: a zero-size SSBO is not bindable (u_bake_count says 0).
        lbuf = ctx.buffer(np.r_[light_idx, 0].astype(np.uint32).tobytes())
        ibo = ctx.buffer(np.ascontiguousarray(edges.T.reshape(-1), dtype=np.uint32).tobytes())
        vao_t = ctx.vertex_array(raster, [(vbo, "2f 3f 3f", "in_uv", "in_pos", "in_normal")])
        vao_e = ctx.vertex_array(
            raster, [(vbo, "2f 3f 3f", "in_uv", "in_pos", "in_normal")], index_buffer=ibo
        )
        try:
            fbo_g.use()
            ctx.viewport = (0, 0, *size)
            fbo_g.clear(0.0, 0.0, 0.0, 0.0)
            ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE | moderngl.BLEND)
            vao_e.render(moderngl.LINES)  # conservative fringe first ...
            vao_t.render(moderngl.TRIANGLES)  # ... exact interior samples over it
            method.bind_common(frame, light)
            rp = self.delegate.meshes.get(lay.path)
            group = rp.mesh.link_group if rp is not None and rp.mesh is not None else 0
            set_uniform(light, "u_link_group", int(group))  # light linking (bake_light.frag)
            lbuf.bind_to_storage_buffer(SSBO_BAKE_LIGHTS)
            set_uniform(light, "u_bake_count", len(light_idx))
            unit = 8
            for name, tex in (("u_pos", pos), ("u_normal", nrm)):
                tex.use(unit)
                cast(moderngl.Uniform, light[name]).value = unit
                unit += 1
            draw_fullscreen(ctx, light, fbo_l, size)
            arrs = [_read(t, size) for t in outs]
            cov = _read(pos, size)[..., 3]
        finally:
            park(ctx)  # never leave a framebuffer bound that is about to be deleted
            for o in (vao_t, vao_e, vbo, ibo, lbuf, fbo_g, fbo_l, pos, nrm, *outs):
                o.release()
        return _resolve(arrs, cov, ss)


def mesh_lights(pos: np.ndarray, rng: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Light-buffer indices (uint32, increasing) of the lights whose range sphere --
    centre ``pos`` (n, 3) and radius ``rng`` (n,), metres, render frame -- meets the
    axis-aligned bounding box of the mesh's triangle corners ``P`` (m, 3, 3). Past its
    range a light adds exactly 0 (the range window of common/lights.glsl), so the bake
    loops over these only: its time follows texels x lights in range, not all lights."""
    if len(pos) == 0:
        return np.zeros(0, dtype=np.uint32)
    pts = np.asarray(P, dtype=np.float64).reshape(-1, 3)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    d = np.maximum(lo - pos, 0.0) + np.maximum(pos - hi, 0.0)  # per axis, 0 inside
    reach = rng * (1.0 + 1e-5) + 1e-6  # float32 ranges: never cull on rounding
    return np.nonzero(np.sum(d * d, axis=1) <= reach * reach)[0].astype(np.uint32)


def _read(tex: moderngl.Texture, size: tuple[int, int]) -> np.ndarray:
    a = np.frombuffer(tex.read(), dtype=np.float32)
    return a.reshape(size[1], size[0], 4).copy()


def _box(a: np.ndarray, ss: int) -> np.ndarray:
    h, w = a.shape[0] // ss, a.shape[1] // ss
    return a.reshape(h, ss, w, ss, *a.shape[2:]).sum(axis=(1, 3))


def _resolve(arrs: list[np.ndarray], cov: np.ndarray, ss: int) -> BakedMap:
    """Supersamples -> texels (coverage-weighted mean; directions weighted by their
    irradiance), then dilation into empty texels (seams)."""
    c = (cov > 0).astype(np.float32)
    n = _box(c, ss)
    safe = np.maximum(n, 1.0)[..., None]
    planes = []
    for k in range(7):
        if k in (2, 4, 6):  # directions: irradiance-weighted means
            w = _box(arrs[k][..., 3] * c, ss)[..., None]
            v = _box(arrs[k][..., :3] * c[..., None], ss) / np.maximum(w, 1e-30)
            planes.append(np.where(w > 0, v, 0.0))
        else:
            planes.append(_box(arrs[k][..., :3] * c[..., None], ss) / safe)
    covered = n > 0
    for _ in range(limits.BAKE_DILATE_TEXELS):
        planes, covered = _dilate(planes, covered)
    for k in (2, 4, 6):
        ln = np.linalg.norm(planes[k], axis=-1, keepdims=True)
        # one light: unit; the rest: a mean direction, length <= 1
        big = ln > 0 if k != 6 else ln > 1.0
        planes[k] = np.where(big, planes[k] / np.maximum(ln, 1e-30), planes[k])
    f32 = np.float32
    return BakedMap(*(p.astype(f32) for p in planes), (n / float(ss * ss)).astype(f32))


def _dilate(planes: list[np.ndarray], covered: np.ndarray) -> tuple[list[np.ndarray], np.ndarray]:
    """Empty texels next to covered ones get the mean of their covered 8-neighbours."""
    h, w = covered.shape
    pad = np.pad(covered, 1).astype(np.float32)
    acc = [np.zeros_like(p) for p in planes]
    padded = [np.pad(src, ((1, 1), (1, 1), (0, 0))) for src in planes]  # once, not per shift
    cnt = np.zeros((h, w), np.float32)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            if dx == 0 and dy == 0:
                continue
            m = pad[1 + dy : 1 + dy + h, 1 + dx : 1 + dx + w]
            cnt += m
            for a, src in zip(acc, padded):
                a += src[1 + dy : 1 + dy + h, 1 + dx : 1 + dx + w] * m[..., None]
    grow = (~covered) & (cnt > 0)
    k = np.maximum(cnt, 1.0)[..., None]
    out = [np.where(grow[..., None], a / k, src) for a, src in zip(acc, planes)]
    return out, covered | grow


def run_bake_frame(
    engine: Engine,
    layouts: list[MeshLayout],
    progress: Callable[[MeshLayout], None] | None = None,
) -> LightmapBakePass:
    """One frame of ``engine`` with the bake's light cull and bake pass in its graph.

    The view's side-effect passes (colour correction, AOV output) leave the graph, so
    the graph culls the G-buffer, lighting and accumulation too: only the light cull,
    shadow atlas, light upload and frame uniforms run before the bake. (Kept, the
    view's 1080p reference frame of every static light cost as much as the bake
    itself: 153 s of the 228 s of issue 35's scene.)"""
    ps = engine._set  # the engine's pass list; the bake swaps one pass and adds one
    bake = LightmapBakePass(engine.delegate, layouts, progress)
    ps.passes = [
        StaticLightCull(engine.delegate) if p.name == "light_cull" else p
        for p in ps.passes
        if not p.side_effect
    ]
    ps.passes.append(bake)
    engine._graph = None
    engine.render_frame()
    return bake


__all__ = ["BakedMap", "LightmapBakePass", "StaticLightCull", "mesh_lights", "run_bake_frame"]
