"""Baked static light (``stb bake``, docs/BAKE.md): lightmaps added to ``g_emission``.

Meshes that carry ``primvars:stb:lightmap:uv`` (faceVarying) and
``stb:lightmap:file`` (an EXR written by ``stb bake``) are drawn again after the
G-buffer with their lightmap UVs; where a fragment is the visible front-facing
surface of its pixel (its linear view depth matches ``g_depth``), the baked
radiance is added to the pixel's emission:

    diffuse / PI * E_baked  +  sum over (the 2 strongest lights, the others' mean direction)
                               of the specular BRDF towards it * its baked irradiance

(``shaders/bake_apply.frag``). Every lighting method adds ``g_emission`` to its
result, so all of them see the baked lights; the lights themselves (``stb:baked``)
leave the light set (``light_cull``) and hence the shadow atlas. The pass joins the
graph only when the stage has lightmaps (``io()`` is empty otherwise, so it is culled).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, cast

import moderngl
import numpy as np
from pxr import Usd, UsdGeom

from ...scene.geometry import (
    IMPLICIT_TYPES,
    _read_topology,
    _Topology,
    implicit_lightmap_triangles,
    tessellate_implicit,
)
from ...scene.prims import CONE_CUTOFF_TEST_RAD
from ..frame import FrameContext
from ..fullscreen import fullscreen_vao
from ..gl import shader_library
from ..graph import Imported, Rec, Resource, Tex
from ..light_buffer import cull_lights, pack_lights
from ..link_masks import LinkBufferUploader, pack_link_buffer
from ..records import FrameBlock
from ..shader_constants import SSBO_LIGHT_LINKS, SSBO_LIGHTS
from .base import Pass

if TYPE_CHECKING:
    from ..gl_delegate import GLRenderDelegate

#: The attributes ``stb bake`` writes on a baked mesh (stb_hydra/bake/baker.py).
UV_PRIMVAR = "stb:lightmap:uv"
FILE_ATTR = "stb:lightmap:file"
#: EXR channel groups of a lightmap, in texture order.
LIGHTMAP_CHANNELS = (
    ("R", "G", "B"),
    ("specTop.R", "specTop.G", "specTop.B"),
    ("dirTop.X", "dirTop.Y", "dirTop.Z"),
    ("spec2nd.R", "spec2nd.G", "spec2nd.B"),
    ("dir2nd.X", "dir2nd.Y", "dir2nd.Z"),
    ("specRest.R", "specRest.G", "specRest.B"),
    ("dirRest.X", "dirRest.Y", "dirRest.Z"),
)
#: Relative view-depth difference under which a lightmapped fragment is the surface
#: the G-buffer kept (same triangles, same transform: float rounding is ~1e-6).
DEPTH_MATCH_REL = 1e-3
#: Smallest |cos| between a lightmapped fragment's facet and the G-buffer normal: where
#: two surfaces meet both match the depth; only the one the pixel shows agrees (0.5 =
#: 60 degrees, wider than the facet/shading-normal gap of a coarse cylinder).
FACET_MATCH_COS = 0.5


@dataclass
class _Lightmapped:
    path: str
    vbo: moderngl.Buffer
    vao: moderngl.VertexArray | None
    textures: list[moderngl.Texture]
    vertices: int


def stage_has_lightmaps(stage: Usd.Stage) -> bool:
    """Whether any prim of ``stage`` has ``stb:lightmap:file`` authored."""
    for prim in stage.Traverse():
        a = prim.GetAttribute(FILE_ATTR)
        if a and a.HasAuthoredValue():
            return True
    return False


def read_lightmap(path: str) -> list[np.ndarray]:
    """The seven (h, w, 3) float32 planes of a lightmap EXR, row 0 = v 0 (GL order).
    Raises OSError naming the problem."""
    import OpenImageIO as oiio

    inp = oiio.ImageInput.open(path)
    if inp is None:
        raise OSError(oiio.geterror() or "cannot open")
    try:
        names = list(inp.spec().channelnames)
        px = inp.read_image(format="float")
    finally:
        inp.close()
    if px is None:
        raise OSError("cannot read pixels")
    a = np.asarray(px, dtype=np.float32)
    if a.ndim == 2:
        a = a[..., None]
    out = []
    for group in LIGHTMAP_CHANNELS:
        if not all(c in names for c in group):
            raise OSError(f"missing channels {', '.join(group)}")
        plane = np.stack([a[..., names.index(c)] for c in group], axis=-1)[::-1]
        out.append(np.ascontiguousarray(np.nan_to_num(plane, nan=0.0, posinf=0.0)))
    return out


#: Texels between two meshes' lightmaps in the runtime atlas (edge-replicated).
ATLAS_GAP_TEXELS = 4


def shelf_pack(
    sizes: list[tuple[int, int]], gap: int
) -> tuple[list[tuple[int, int]], tuple[int, int]]:
    """Shelf packing of (w, h) rects, tallest first: (x, y) offsets (texels, ``gap``
    apart and from the border) and the atlas (width, height)."""
    area = sum((w + gap) * (h + gap) for w, h in sizes)
    width = max(max(w for w, _ in sizes) + 2 * gap, math.ceil(math.sqrt(area * 1.1)))
    order = sorted(range(len(sizes)), key=lambda i: -sizes[i][1])
    offsets = [(0, 0)] * len(sizes)
    x, y, shelf = gap, gap, 0
    for i in order:
        w, h = sizes[i]
        if x + w + gap > width:
            x, y, shelf = gap, y + shelf + gap, 0
        offsets[i] = (x, y)
        x += w + gap
        shelf = max(shelf, h)
    return offsets, (width, y + shelf + gap)


class LightmapTask(Pass):
    name = "lightmap"
    reads = (
        Imported("meshes"),
        Rec(FrameBlock),
        Tex("g_depth", "r32f"),
        Tex("g_normal", "rg16f"),
        Tex("g_base_rough", "rgba16f"),
        Tex("g_f0_metal", "rgba16f"),
        Tex("g_emission", "rgba16f"),
        Tex("g_zbuffer", "depth24"),
    )
    #: g_zbuffer is only the depth test's attachment (early-z culls hidden fragments of
    #: the re-drawn meshes; nothing is written to it), declared as modified in place.
    writes = (
        Tex("g_emission", "rgba16f"),
        Tex("lightmap_mask", "r8"),
        Tex("g_zbuffer", "depth24"),
    )

    def __init__(self, delegate: GLRenderDelegate) -> None:
        super().__init__(delegate)
        self.stage: Usd.Stage | None = None
        self._has: bool | None = None
        self._items: list[_Lightmapped] | None = None
        #: Lightmap texels resident on the GPU and their bytes (7 x RGB16F per texel).
        self.texels = 0
        self.gpu_bytes = 0
        self._baked_ssbo: moderngl.Buffer | None = None
        self._baked_key: tuple[int, bytes] | None = None
        self._links = LinkBufferUploader()
        #: Baked lights evaluated per frame on pixels without a lightmap.
        self.baked_in_view = 0

    def attach(self, stage: Usd.Stage) -> None:
        """The stage whose baked meshes this pass draws (set by the engine)."""
        self.stage = stage
        self._has = None

    def io(self) -> tuple[tuple[Resource, ...], tuple[Resource, ...]]:
        if self._has is None:
            self._has = bool(self.delegate.light_table.baked.any()) or (
                self.stage is not None and stage_has_lightmaps(self.stage)
            )
        if not self._has:
            return (), ()
        if self.delegate.light_table.has_light_links():
            return (*self.reads, Tex("g_link", "r8ui")), self.writes
        return self.reads, self.writes

    def _load(self, frame: FrameContext) -> list[_Lightmapped]:
        """Every baked mesh's triangles and lightmap, packed into one vertex buffer and
        one atlas per plane (one draw per frame: per-draw cost dominates on software
        GL). Meshes whose lightmap cannot be used are warned about and skipped."""
        assert self.stage is not None
        parts: list[tuple[str, np.ndarray, list[np.ndarray]]] = []
        for prim in self.stage.Traverse():
            fa = prim.GetAttribute(FILE_ATTR)
            if not fa or not fa.HasAuthoredValue():
                continue
            if not (prim.IsA(UsdGeom.Mesh) or prim.GetTypeName() in IMPLICIT_TYPES):
                continue
            path = str(prim.GetPath())
            try:
                parts.append((path, *self._read_one(prim, fa)))
            except (OSError, ValueError) as exc:
                frame.warnings.append(
                    f"mesh <{path}>: lightmap not used ({exc}); its baked lights are missing"
                )
        if not parts:
            return []
        sizes = [(pl[0].shape[1], pl[0].shape[0]) for _, _, pl in parts]
        offsets, (aw, ah) = shelf_pack(sizes, ATLAS_GAP_TEXELS)
        n_planes = len(parts[0][2])
        # RGBA16F: 3-channel half textures take a slow path in software GL.
        atlas = [np.zeros((ah, aw, 4), dtype=np.float16) for _ in range(n_planes)]
        verts = []
        g = ATLAS_GAP_TEXELS // 2
        for (_path, v, planes), (ox, oy), (w, h) in zip(parts, offsets, sizes):
            for k, plane in enumerate(planes):
                # Edge-replicated border: bilinear lookups at a rect's edge stay inside it.
                padded = np.pad(plane, ((g, g), (g, g), (0, 0)), mode="edge")
                atlas[k][oy - g : oy + h + g, ox - g : ox + w + g, :3] = padded
            v = v.copy()
            v[:, 3] = (ox + v[:, 3] * w) / aw
            v[:, 4] = (oy + v[:, 4] * h) / ah
            verts.append(v)
        ctx = frame.ctx
        prog = shader_library(ctx).program("bake_apply.vert", "bake_apply.frag")
        allv = np.ascontiguousarray(np.concatenate(verts), dtype=np.float32)
        vbo = ctx.buffer(allv.tobytes())
        texs = []
        for plane in atlas:
            t = ctx.texture((aw, ah), 4, np.ascontiguousarray(plane).tobytes(), dtype="f2")
            t.filter = (moderngl.LINEAR, moderngl.LINEAR)
            t.repeat_x = t.repeat_y = False
            texs.append(t)
        self.texels = aw * ah
        self.gpu_bytes = aw * ah * 8 * n_planes
        vao = ctx.vertex_array(prog, [(vbo, "3f 2f", "in_pos", "in_uv")])
        return [_Lightmapped("atlas", vbo, vao, texs, len(allv))]

    def _read_one(self, prim: Usd.Prim, fa: Usd.Attribute) -> tuple[np.ndarray, list[np.ndarray]]:
        """(vertices (3 m, 5): world position, lightmap UV; lightmap planes) of one mesh.

        An implicit shape (``Cube``, ``Sphere``, ...) is tessellated as the renderer
        draws it; its faceVarying UVs are per corner of its non-degenerate triangles
        (``implicit_lightmap_triangles``, 3 per triangle), as ``stb bake`` writes them."""
        path = str(prim.GetPath())
        rp = self.delegate.meshes.get(path)
        mesh = rp.mesh if rp is not None else None
        if mesh is None or not mesh.visible or mesh.dynamic:
            raise ValueError("the mesh is not drawn as static geometry")
        tc = Usd.TimeCode.Default()
        if prim.GetTypeName() in IMPLICIT_TYPES:
            g = tessellate_implicit(prim, tc)
            if g is None:
                raise ValueError(f"implicit {prim.GetTypeName()} does not tessellate")
            points = np.asarray(g.points, dtype=np.float64)
            fvi = implicit_lightmap_triangles(g).reshape(-1)
            corners = np.arange(len(fvi), dtype=np.int64)
        else:
            topo = _read_topology(prim, UsdGeom.Mesh(prim), tc)
            if not isinstance(topo, _Topology):
                raise ValueError("no usable topology")
            points = topo.points.astype(np.float64)
            fvi = topo.fvi
            corners = topo.corners.reshape(-1)
        pv = UsdGeom.PrimvarsAPI(prim).GetPrimvar(UV_PRIMVAR)
        uv = pv.Get() if pv else None
        if uv is None or pv.GetInterpolation() != UsdGeom.Tokens.faceVarying:
            raise ValueError(f"primvars:{UV_PRIMVAR} is not authored faceVarying")
        uv_fv = np.asarray(uv, dtype=np.float32).reshape(-1, 2)
        if len(uv_fv) != len(fvi):
            raise ValueError(f"{len(uv_fv)} lightmap UVs for {len(fvi)} face-vertices")
        asset = fa.Get()
        file = getattr(asset, "resolvedPath", "") or ""
        if not file or not Path(file).is_file():
            raise OSError(f"file '{getattr(asset, 'path', asset)}' not found")
        planes = read_lightmap(file)
        xf = np.asarray(mesh.transform, dtype=np.float64)
        pts = np.c_[points, np.ones(len(points))] @ xf
        verts = np.concatenate([pts[fvi[corners], :3].astype(np.float32), uv_fv[corners]], axis=1)
        if not np.all(np.isfinite(verts)) or uv_fv.min() < 0.0 or uv_fv.max() > 1.0:
            raise ValueError("non-finite positions or lightmap UVs outside [0, 1]")
        return verts, planes

    def execute(self, frame: FrameContext) -> None:
        if self._items is None:
            self._items = self._load(frame)
        ctx = frame.ctx
        bufs = frame.buffers
        bufs.framebuffer("fb_lightmap_mask", ["lightmap_mask"]).clear(0.0, 0.0, 0.0, 0.0)
        ctx.viewport = (0, 0, *bufs.size)
        ctx.disable(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
        ctx.enable(moderngl.BLEND)
        ctx.blend_func = (moderngl.ONE, moderngl.ONE)
        try:
            if self._items:
                self._draw_lightmaps(frame)
            self._draw_dynamic(frame)
        finally:
            ctx.disable(moderngl.BLEND)
            ctx.blend_func = (moderngl.SRC_ALPHA, moderngl.ONE_MINUS_SRC_ALPHA)  # the default

    def _bind_gbuffer(self, frame: FrameContext, prog: moderngl.Program) -> int:
        unit = 0
        for name in (
            "g_depth",
            "g_normal",
            "g_base_rough",
            "g_f0_metal",
            "g_link",
            "lightmap_mask",
        ):
            if name == "lightmap_mask" and "u_mask" not in prog:
                continue
            if name != "lightmap_mask" and name not in prog:
                continue
            frame.buffers.textures[name].use(unit)
            key = "u_mask" if name == "lightmap_mask" else name
            cast(moderngl.Uniform, prog[key]).value = unit
            unit += 1
        return unit

    def _draw_lightmaps(self, frame: FrameContext) -> None:
        assert self._items is not None
        prog = shader_library(frame.ctx).program("bake_apply.vert", "bake_apply.frag")
        cast(moderngl.Uniform, prog["u_depth_match"]).value = DEPTH_MATCH_REL
        cast(moderngl.Uniform, prog["u_facet_match"]).value = FACET_MATCH_COS
        ctx = frame.ctx
        fbo = frame.buffers.framebuffer("fb_lightmap", ["g_emission", "lightmap_mask"], "g_zbuffer")
        fbo.use()
        fbo.depth_mask = False
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.depth_func = "<="
        # The G-buffer drew these triangles from GPU-transformed vertices, this pass from
        # CPU-transformed ones: pull them a little towards the eye so equal surfaces pass
        # (the shader's own depth and facet checks then decide).
        ctx.polygon_offset = (-1.0, -4.0)
        unit = 0
        for name in ("g_depth", "g_normal", "g_base_rough", "g_f0_metal"):
            frame.buffers.textures[name].use(unit)
            cast(moderngl.Uniform, prog[name]).value = unit
            unit += 1
        for it in self._items:
            for k, t in enumerate(it.textures):
                if f"u_lightmap{k}" in prog:  # a plane the shader does not read is optimised out
                    t.use(unit + k)
                    cast(moderngl.Uniform, prog[f"u_lightmap{k}"]).value = unit + k
            assert it.vao is not None
            it.vao.render(moderngl.TRIANGLES, vertices=it.vertices)
        # Shared context: leave the depth state as every other pass expects it.
        ctx.polygon_offset = (0.0, 0.0)
        ctx.depth_func = "<"
        ctx.disable(moderngl.DEPTH_TEST)
        fbo.depth_mask = True

    def _draw_dynamic(self, frame: FrameContext) -> None:
        """Baked in-view lights on the pixels no lightmap covered (reference, unshadowed)."""
        t = self.delegate.light_table
        rows = cull_lights(t, frame.view.frustum_planes())
        rows = rows[t.baked[rows]]
        self.baked_in_view = len(rows)
        if not len(rows):
            return
        ctx = frame.ctx
        packed = pack_lights(t, rows)
        key = (t.version, rows.tobytes())
        if self._baked_key != key:
            data = np.ascontiguousarray(packed, dtype=np.float32).tobytes()
            if self._baked_ssbo is None or self._baked_ssbo.size < len(data):
                if self._baked_ssbo is not None:
                    self._baked_ssbo.release()
                self._baked_ssbo = ctx.buffer(reserve=max(len(data), 4096))
            self._baked_ssbo.write(data)
            self._baked_key = key
        assert self._baked_ssbo is not None
        defines: dict[str, object] = {}
        d = self.delegate
        if d.has_ies and bool(np.any(t.ies_layer[rows] >= 0)):
            defines["HAS_IES"] = True
        if bool(np.any(t.cone_cutoff[rows] < np.float32(CONE_CUTOFF_TEST_RAD))):
            defines["HAS_CONES"] = True
        if t.has_light_links():  # the baked lights' masks, in their buffer's order
            defines["HAS_LINKS"] = True
            self._links.upload(ctx, pack_link_buffer(t, rows)).bind_to_storage_buffer(
                SSBO_LIGHT_LINKS
            )
        prog = shader_library(ctx).program("fullscreen.vert", "bake_dynamic.frag", defines)
        unit = self._bind_gbuffer(frame, prog)
        if "u_ies" in prog and d.ies_texture is not None:
            d.ies_texture.use(unit)
            cast(moderngl.Uniform, prog["u_ies"]).value = unit
        cast(moderngl.Uniform, prog["u_baked_count"]).value = len(rows)
        self._baked_ssbo.bind_to_storage_buffer(SSBO_LIGHTS)
        fbo = frame.buffers.framebuffer("fb_lightmap_dyn", ["g_emission"])
        fbo.use()
        fullscreen_vao(ctx, prog).render(moderngl.TRIANGLES, vertices=3)
        if d.light_ssbo is not None:  # the frame's own light buffer back in place
            d.light_ssbo.bind_to_storage_buffer(SSBO_LIGHTS)

    def release(self) -> None:
        self._links.release()
        if self._baked_ssbo is not None:
            self._baked_ssbo.release()
            self._baked_ssbo = None
        for it in self._items or []:
            if it.vao is not None:
                it.vao.release()
            it.vbo.release()
            for t in it.textures:
                t.release()
        self._items = None
