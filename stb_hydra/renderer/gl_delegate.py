"""GL render delegate: GPU resources built from render prims.

* Geometry: one vertex/index buffer pair per ``geometry_key`` (instance
  prototypes share it).
* Draw batches: meshes grouped by (geometry, resolved material, dynamic, light/shadow
  link groups) into
  instanced draws with per-instance model matrices for this and the previous
  frame (motion vectors).
* Lights: the FoV-culled std430 buffer (``light_buffer``), uploaded only when
  the culled set or a culled light changed; IES tables in a 2D texture array.

``commit_resources()`` uploads only what changed since the last commit.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import moderngl
import numpy as np

from .. import limits
from ..scene import prims
from ..scene.locators import DirtyBits as D
from . import shader_constants as sc
from .delegate import RenderDelegate
from .dome_env import DomeEnvironment
from .light_buffer import LIGHT_SHADOW_SLOT_COLUMN, LIGHT_STRIDE_BYTES, pack_lights
from .material_binding import MaterialParams, alpha_floor, material_params
from .receiver_bounds import box_corners, leaf_boxes, world_boxes
from .textures import TextureCache, TextureKey

__all__ = ["BatchArrays", "DrawBatch", "GLRenderDelegate", "GeometryBuffers", "MaterialParams"]

_GEOM_BITS = D.DirtyPoints | D.DirtyTopology | D.DirtyNormals | D.DirtyPrimvar
_BATCH_BITS = (
    _GEOM_BITS
    | D.DirtyTransform
    | D.DirtyInstancer
    | D.DirtyVisibility
    | D.DirtyMaterialId
    | D.DirtyStbFlags
    | D.DirtyCategories
)


@dataclass
class GeometryBuffers:
    vbo: moderngl.Buffer  # position, normal, colour (9 floats per vertex)
    ibo: moderngl.Buffer
    index_count: int
    bounds: tuple[np.ndarray, np.ndarray]  # object-space AABB
    users: set[str] = field(default_factory=set)
    #: Object-space leaf boxes of its triangles ((G, 3) lo, hi: receiver_bounds.leaf_boxes).
    leaves: tuple[np.ndarray, np.ndarray] = (np.zeros((0, 3)), np.zeros((0, 3)))
    #: Texture coordinates, tangent frame, material primvars (10 floats per vertex):
    #: only for meshes that have texture coordinates or material primvars.
    vbo_material: moderngl.Buffer | None = None
    #: ``receiver_bounds.box_corners(*leaves)``, made on first use (None: not yet).
    leaf_corners: np.ndarray | None = None
    #: (8, 4) the corners of ``bounds`` (homogeneous), made on first use (None: not yet).
    bound_corners: np.ndarray | None = None


@dataclass
class DrawBatch:
    geometry_key: str
    material: MaterialParams
    dynamic: bool
    models: np.ndarray  # (k, 4, 4) float32 this frame
    prev_models: np.ndarray  # (k, 4, 4) float32 previous frame
    #: World AABB (render frame, metres) of every instance.
    bounds: tuple[np.ndarray, np.ndarray] = (np.zeros(3), np.zeros(3))
    #: (light-link group, shadow-link group) of its meshes (``scene/links.py``).
    links: tuple[int, int] = (0, 0)
    instance_buffer: moderngl.Buffer | None = None
    vaos: dict[int, moderngl.VertexArray] = field(default_factory=dict)

    @property
    def count(self) -> int:
        return len(self.models)


_NO_BOXES = (np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0))


def _receiver_mode(n_recv: int, instances: int, leaves: int) -> int:
    """Which receiver boxes a mesh gets after ``n_recv`` boxes of the meshes before it
    (within ``limits.RECEIVER_BOXES_MAX``): 0 its leaf boxes per instance, 1 one box per
    instance, 2 one box (the mesh's world AABB)."""
    if n_recv + instances * leaves <= limits.RECEIVER_BOXES_MAX:
        return 0
    if n_recv + instances <= limits.RECEIVER_BOXES_MAX:
        return 1
    return 2


@dataclass(slots=True)
class _MeshEntry:
    """One visible mesh's part of the draw batches (``GLRenderDelegate._mesh_entry``):
    its batch key, geometry key, material parameters and dynamic flag, what they were
    made from (material sprim and record, geometry buffers with their object-space
    bounds and leaf boxes: identity-checked), its world matrices ((k, 4, 4), row
    vectors, render frame), its world AABB (metres; None: no finite corner) and its
    receiver boxes (branch of ``_receiver_mode``; lo, hi (n, 3) m, alpha floor (n,))."""

    key: tuple
    key_g: str
    mp: MaterialParams
    dynamic: bool
    mat_sprim: Any
    mat: Any
    geom: GeometryBuffers
    bounds: tuple[np.ndarray, np.ndarray]
    leaves: tuple[np.ndarray, np.ndarray]
    xf: np.ndarray
    box: tuple[np.ndarray, np.ndarray] | None
    recv_mode: int
    recv: tuple[np.ndarray, np.ndarray, np.ndarray]
    #: Kept by the rebuild under way (not made anew).
    reused: bool = False


@dataclass(frozen=True)
class BatchArrays:
    """``GLRenderDelegate.batch_arrays``: numpy views of the draw batches (world AABBs
    in metres, triangles per draw with every instance, dynamic flags)."""

    batches: list[DrawBatch]
    lo: np.ndarray  # (B, 3)
    hi: np.ndarray  # (B, 3)
    triangles: np.ndarray  # (B,)
    dynamic: np.ndarray  # (B,) bool


class GLRenderDelegate(RenderDelegate):
    def __init__(self, ctx: moderngl.Context) -> None:
        super().__init__()
        self.ctx = ctx
        self.geometry: dict[str, GeometryBuffers] = {}
        self.batches: list[DrawBatch] = []
        self._batch_arrays: BatchArrays | None = None
        self._batch_prev: dict[tuple, np.ndarray] = {}
        self._batches_dirty = True
        self._static_changed: set[str] = set()
        #: Per visible mesh, its part of the batches as of the last rebuild (kept while
        #: the mesh syncs nothing: ``_mesh_entry``), and the meshes synced since.
        self._mesh_entries: dict[str, _MeshEntry] = {}
        self._meshes_changed: set[str] = set()
        #: Per batch key as of the last rebuild: the batch, its meshes in order, and the
        #: geometry buffers its VAOs read.
        self._batch_of: dict[tuple, DrawBatch] = {}
        self._batch_members: dict[tuple, list[str]] = {}
        self._batch_geom: dict[tuple, GeometryBuffers] = {}
        self.light_ssbo: moderngl.Buffer | None = None
        self._fov_version = -1
        self._fov_uploaded_rows: np.ndarray | None = None
        self._fov_uploaded_maps: np.ndarray | None = None
        #: The packed records last uploaded (partial updates patch it in place).
        self._fov_packed: np.ndarray | None = None
        #: Records written by the last upload (0: none; len(rows): full).
        self.last_upload_records = 0
        #: Material textures (OIIO -> OCIO -> GL), shared by every batch.
        self.textures = TextureCache(ctx)
        #: Some batch's material has a clearcoat lobe (the G-buffer's g_coat exists).
        self.has_clearcoat = False
        self.ies_texture: moderngl.TextureArray | None = None
        #: Per IES layer, the table's maximum over phi against cos off the axis
        #: (``ies_cos_rowmax``): the per-pixel IES of ``-o reuse_target=tile``.
        self.ies_cos_texture: moderngl.TextureArray | None = None
        #: The textured dome's map and uniforms (issue 37).
        self.dome_env = DomeEnvironment(ctx)
        self._ies_version = -1
        self.ies_layer_count = 0
        #: RectLight textures (issue 37 item 3): one mipmapped RGB16F layer each
        #: (``scene/rect_texture.py``), bound as u_rect_tex.
        self.rect_texture_array: moderngl.TextureArray | None = None
        self._rect_version = -1
        self._seen_rects: tuple[tuple[int, int, bool], np.ndarray] | None = None
        self.scene_bounds = (np.zeros(3), np.zeros(3))
        self.stats = {
            "geometry_uploads": 0,
            "light_uploads": 0,
            "light_partial_uploads": 0,
            "instance_uploads": 0,
        }
        #: World bounds per mesh prim, and the bounds static geometry changed in
        #: since the shadow task last looked (old and new): static shadow maps in
        #: range of these must be re-captured.
        self.mesh_bounds: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        #: World AABBs ((B, 3) lo, hi, render frame, m) that together hold every drawn
        #: triangle, finer than ``mesh_bounds`` (each mesh's leaf boxes per instance:
        #: ``receiver_bounds``), and (B,) the smallest GGX alpha of each box's material
        #: (``material_binding.alpha_floor``): the narrow-sphere bound's receivers (issue 34).
        self.receiver_boxes: tuple[np.ndarray, np.ndarray, np.ndarray] = (
            np.zeros((0, 3)),
            np.zeros((0, 3)),
            np.zeros(0),
        )
        self.changed_static_bounds: list[tuple[np.ndarray, np.ndarray]] = []

    # -- render prim hooks --
    def release_mesh(self, path: str) -> None:
        b = self.mesh_bounds.pop(path, None)
        if b is not None:
            self.changed_static_bounds.append(b)
        self._meshes_changed.add(path)
        for key, g in list(self.geometry.items()):
            if path in g.users:
                g.users.discard(path)
                if not g.users:
                    self._release_geometry(g)
                    del self.geometry[key]
        self._batches_dirty = True

    @staticmethod
    def _release_geometry(g: GeometryBuffers) -> None:
        g.vbo.release()
        g.ibo.release()
        if g.vbo_material is not None:
            g.vbo_material.release()

    # -- commit --
    def commit_resources(self) -> None:
        """Upload changed geometry, rebuild draw batches when meshes changed."""
        done: set[str] = set()
        for path, rp in self.meshes.items():
            bits = rp.pending_bits
            if not bits:
                continue
            self._meshes_changed.add(path)
            if bits & _GEOM_BITS and rp.mesh is not None:
                self._upload_geometry(path, rp.mesh, done)
            if bits & _BATCH_BITS:
                self._batches_dirty = True
                if rp.mesh is not None and not rp.mesh.dynamic and path in self.mesh_bounds:
                    self.changed_static_bounds.append(self.mesh_bounds[path])
                self._static_changed.add(path)
        if any(m.pending_bits for m in self.materials.values()):
            self._batches_dirty = True
        if self._batches_dirty:
            self._rebuild_batches()
        else:
            self._age_batches()
        if self.ies.version != self._ies_version:
            self._upload_ies()
        if self.rect_textures.version != self._rect_version:
            self._upload_rect_textures()
        super().commit_resources()

    def _upload_geometry(
        self, path: str, mesh: prims.MeshPrim, done: set[str] | None = None
    ) -> None:
        key = mesh.geometry_key or path
        g = self.geometry.get(key)
        if g is not None and done is not None and key in done:
            g.users.add(path)  # shared prototype already uploaded by a sibling this commit
            return
        if done is not None:
            done.add(key)
        n = len(mesh.points)
        cols = mesh.vertex_colors if mesh.vertex_colors is not None else np.zeros((n, 3))
        data = np.empty((n, 9), dtype=np.float32)
        data[:, 0:3] = mesh.points
        data[:, 3:6] = mesh.normals
        data[:, 6:9] = cols[:n]
        idx = np.ascontiguousarray(mesh.indices, dtype=np.uint32)
        bounds = (
            (mesh.points.min(axis=0), mesh.points.max(axis=0))
            if n
            else (np.zeros(3, np.float32), np.zeros(3, np.float32))
        )
        extra = _material_vertices(mesh)
        leaves = leaf_boxes(mesh.points, idx)
        if g is None:
            g = GeometryBuffers(
                self.ctx.buffer(data.tobytes() if n else b"\0" * 36),
                self.ctx.buffer(idx.tobytes() if idx.size else b"\0" * 12),
                int(idx.size),
                bounds,
            )
            if extra is not None:
                g.vbo_material = self.ctx.buffer(extra.tobytes())
            g.leaves = leaves
            g.leaf_corners = g.bound_corners = None
            self.geometry[key] = g
        else:
            if extra is not None:
                if g.vbo_material is None:
                    g.vbo_material = self.ctx.buffer(extra.tobytes())
                else:
                    g.vbo_material.orphan(extra.nbytes)
                    g.vbo_material.write(extra.tobytes())
            elif g.vbo_material is not None:
                g.vbo_material.release()
                g.vbo_material = None
            g.vbo.orphan(max(data.nbytes, 36))
            if n:
                g.vbo.write(data.tobytes())
            g.ibo.orphan(max(idx.nbytes, 12))
            if idx.size:
                g.ibo.write(idx.tobytes())
            g.index_count = int(idx.size)
            g.bounds = bounds
            g.leaves = leaves
            g.leaf_corners = g.bound_corners = None
            self._batch_arrays = None
            for b in self.batches:
                if b.geometry_key == key:
                    for vao in b.vaos.values():
                        vao.release()
                    b.vaos.clear()
        g.users.add(path)
        self.stats["geometry_uploads"] += 1

    def resolve_material(self, mesh: prims.MeshPrim) -> MaterialParams:
        sp = self.materials.get(mesh.material) if mesh.material else None
        return material_params(sp.material if sp is not None else None, mesh)

    def batch_key(self, path: str, mesh: prims.MeshPrim) -> tuple:
        """What groups meshes into one instanced draw batch: geometry, material,
        dynamic, (light-link group, shadow-link group) -- ``DrawBatch.links`` is k[3]."""
        return self._batch_key(mesh.geometry_key or path, self.resolve_material(mesh), mesh)

    @staticmethod
    def _batch_key(key_g: str, mp: MaterialParams, m: prims.MeshPrim) -> tuple:
        return (key_g, mp.key(), m.dynamic, (m.link_group, m.shadow_group))

    def texture_files(self) -> set[str]:
        """Files of the textures in use (every tile of a UDIM set, and the lights'
        textures: domes, rects), resolved paths."""
        out: set[str] = set()
        for key in self.textures.textures:
            info = self.textures.info(key.file)
            out.update(p for p, _t in info.layers) if info is not None else out.add(key.file)
        out.update(self.light_texture_files().values())
        return out

    def light_texture_files(self) -> dict[str, str]:
        """Light path -> the texture file it reads (``LightPrim.texture_file``)."""
        return {
            path: sp.light.texture_file
            for path, sp in self.lights.items()
            if sp.light is not None and sp.light.texture_file
        }

    def reload_textures(self, paths: set[str]) -> int:
        """Files changed on disk: reload the textures that read them on the next commit
        (the others stay on the GPU). Returns how many textures will reload."""
        hit = 0
        for key in list(self.textures.textures):
            info = self.textures.info(key.file)
            files = {p for p, _t in info.layers} if info is not None else {key.file}
            if files & paths:
                self.textures.forget_file(key.file)
                hit += 1
        for p in paths:
            self.textures.forget_file(p)  # also a texture that failed to load before
        if hit or paths:
            self._batches_dirty = True
        return hit

    def _commit_textures(self) -> None:
        """Plan (budget) and load the textures the batches read; free the rest."""
        need: dict[TextureKey, str] = {}
        users: dict[TextureKey, set[str]] = {}
        for b in self.batches:
            for ref in b.material.textures:
                if ref is not None:
                    k = TextureKey(ref.file, ref.source_color_space)
                    need.setdefault(k, b.material.path)
                    users.setdefault(k, set()).add(b.material.path)
        cache = self.textures
        for k in [k for k in cache.textures if k not in need]:
            cache._drop(k)
        cache.plan(need)
        for b in self.batches:
            for ref in b.material.textures:
                if ref is not None:
                    cache.acquire(ref, b.material.path)
        for k, t in cache.textures.items():
            t.users = set(users.get(k, ()))
        for w in cache.warnings:
            self.warn_once("texture:" + w, w)
        cache.warnings.clear()

    def _mesh_entry(self, path: str, m: prims.MeshPrim, n_recv: int) -> _MeshEntry:
        """``path``'s part of the draw batches: the entry kept from the last rebuild when
        it still holds (the mesh synced nothing since, its geometry and material are the
        objects it was made from, its receiver boxes took the same branch of the
        ``limits.RECEIVER_BOXES_MAX`` budget), else made anew."""
        key_g = m.geometry_key or path
        sp = self.materials.get(m.material) if m.material else None
        mat = sp.material if sp is not None else None
        e = self._mesh_entries.get(path)
        g = self.geometry.get(key_g)
        if (
            e is not None
            and path not in self._meshes_changed
            and e.geom is g
            and g is not None
            and e.bounds is g.bounds
            and e.leaves is g.leaves
            and e.mat_sprim is sp
            and e.mat is mat
            and e.recv_mode == _receiver_mode(n_recv, len(e.xf), len(g.leaves[0]))
        ):
            e.reused = True
            return e
        if g is None:
            self._upload_geometry(path, m)
            g = self.geometry[key_g]
        mp = material_params(mat, m)  # == self.resolve_material(m)
        k = self._batch_key(key_g, mp, m)  # == self.batch_key(path, m)
        xf = m.world_transforms()
        blo, bhi = g.bounds
        corners = g.bound_corners
        if corners is None:
            corners = np.array(np.meshgrid(*zip(blo, bhi), indexing="ij")).reshape(3, -1).T
            corners = g.bound_corners = np.c_[corners, np.ones(8)]
        wc = np.einsum("ci,kij->kcj", corners, xf)[..., :3].reshape(-1, 3)
        wc = wc[np.all(np.isfinite(wc), axis=1)]
        box = None
        mode = -1
        recv = _NO_BOXES
        if len(wc):
            mlo, mhi = wc.min(axis=0), wc.max(axis=0)
            box = (mlo, mhi)
            # receiver boxes: the leaves of every instance, else one box per
            # instance, else the mesh's (within limits.RECEIVER_BOXES_MAX in all)
            glo, ghi = g.leaves
            mode = _receiver_mode(n_recv, len(xf), len(glo))
            if mode == 0:
                if g.leaf_corners is None:
                    g.leaf_corners = box_corners(glo, ghi)
                rlo, rhi = world_boxes(glo, ghi, xf, g.leaf_corners)
            elif mode == 1:
                rlo, rhi = world_boxes(np.array([blo]), np.array([bhi]), xf)
            else:
                rlo, rhi = mlo[None], mhi[None]
            if len(rlo) == 0:
                rlo, rhi = mlo[None], mhi[None]
            recv = (rlo, rhi, np.full(len(rlo), alpha_floor(mp)))
        e = _MeshEntry(k, key_g, mp, m.dynamic, sp, mat, g, g.bounds, g.leaves, xf, box, mode, recv)
        self._mesh_entries[path] = e
        return e

    def _rebuild_batches(self) -> None:
        """Group the visible meshes into draw batches (instanced draws), with the world
        bounds per mesh, per batch and of the scene and the receiver boxes. Incremental
        (Hydra's dirty bits): a mesh that synced nothing since the last rebuild keeps its
        entry (material, transforms, bounds, receiver boxes), and a batch whose meshes
        all kept theirs is kept whole (its instance buffer and VAOs); a changed batch
        keeps its GPU objects and re-uploads its instances. The result is the one a
        rebuild from scratch gives (same batches in the same order, same matrices)."""
        groups: dict[tuple, list[_MeshEntry]] = {}
        members: dict[tuple, list[str]] = {}
        lo = np.full(3, np.inf)
        hi = np.full(3, -np.inf)
        new_bounds: dict[str, tuple[np.ndarray, np.ndarray]] = {}
        recv_lo: list[np.ndarray] = []
        recv_hi: list[np.ndarray] = []
        recv_alpha: list[np.ndarray] = []
        n_recv = 0
        for e in self._mesh_entries.values():
            e.reused = False
        live: set[str] = set()
        for path, rp in self.meshes.items():
            m = rp.mesh
            if m is None or not m.visible or len(m.indices) == 0:
                continue
            e = self._mesh_entry(path, m, n_recv)
            live.add(path)
            groups.setdefault(e.key, []).append(e)
            members.setdefault(e.key, []).append(path)
            if e.box is not None:
                mlo, mhi = e.box
                new_bounds[path] = e.box
                rlo, rhi, ralpha = e.recv
                recv_lo.append(rlo)
                recv_hi.append(rhi)
                recv_alpha.append(ralpha)
                n_recv += len(rlo)
                lo = np.minimum(lo, mlo)
                hi = np.maximum(hi, mhi)
        for path in [p for p in self._mesh_entries if p not in live]:
            del self._mesh_entries[path]
        self._meshes_changed.clear()
        for path in self._static_changed:
            nb = new_bounds.get(path)
            sp = self.meshes.get(path)
            if nb is not None and sp is not None and sp.mesh is not None and not sp.mesh.dynamic:
                self.changed_static_bounds.append(nb)
        self._static_changed.clear()
        self.mesh_bounds = new_bounds
        self.receiver_boxes = (
            (np.concatenate(recv_lo), np.concatenate(recv_hi), np.concatenate(recv_alpha))
            if recv_lo
            else (np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0))
        )
        old_of = self._batch_of
        kept: set[int] = set()
        new: list[DrawBatch] = []
        prev_map: dict[tuple, np.ndarray] = {}
        for k, entries in groups.items():
            gk, mp, dyn = entries[-1].key_g, entries[-1].mp, entries[-1].dynamic
            geom = entries[-1].geom
            old = old_of.get(k)
            if old is not None and self._batch_geom.get(k) is not geom:
                old = None  # its VAOs read released buffers
            if (
                old is not None
                and all(e.reused for e in entries)
                and self._batch_members.get(k) == members[k]
                and self._batch_prev.get(k) is old.models
            ):
                # nothing in it changed: made anew, its previous matrices would be these
                # (the upload is skipped when the buffer already holds them)
                if old.prev_models is not old.models:
                    same = np.array_equal(old.prev_models, old.models)
                    old.prev_models = old.models
                    if not same:
                        self._upload_instances(old)
                kept.add(id(old))
                new.append(old)
                prev_map[k] = old.models
                continue
            models = np.concatenate([e.xf for e in entries]).astype(np.float32)
            prev = self._batch_prev.get(k)
            if prev is None or prev.shape != models.shape:
                prev = models
            bounds = (np.zeros(3), np.zeros(3))
            g0 = None
            for e in entries:
                if e.box is not None:
                    mlo, mhi = e.box
                    g0 = (
                        (mlo, mhi)
                        if g0 is None
                        else (np.minimum(g0[0], mlo), np.maximum(g0[1], mhi))
                    )
            if g0 is not None:
                bounds = g0
            b = DrawBatch(gk, mp, dyn, models, prev, bounds)
            b.links = k[3]
            if old is not None:  # the same GPU objects, new contents
                kept.add(id(old))
                b.instance_buffer, b.vaos = old.instance_buffer, old.vaos
            self._upload_instances(b)
            new.append(b)
            prev_map[k] = models
        for old in self.batches:
            if id(old) in kept:
                continue
            if old.instance_buffer is not None:
                old.instance_buffer.release()
            for vao in old.vaos.values():
                vao.release()
        self._batch_prev = prev_map
        self._batch_of = dict(zip(groups, new, strict=True))
        self._batch_members = members
        self._batch_geom = {k: entries[-1].geom for k, entries in groups.items()}
        self.batches = new
        self.has_clearcoat = any(b.material.coated for b in new)
        self._commit_textures()
        self.scene_bounds = (lo, hi) if np.all(np.isfinite(lo)) else (np.zeros(3), np.zeros(3))
        self._batches_dirty = False

    def batch_arrays(self) -> BatchArrays:
        """Per-batch world bounds, triangle counts (instances included) and dynamic
        flags as arrays aligned with ``batches`` (rebuilt when the batches are)."""
        cached = self._batch_arrays
        if cached is not None and cached.batches is self.batches:
            return cached
        bs = self.batches
        lo = np.array([b.bounds[0] for b in bs], dtype=np.float64).reshape(-1, 3)
        hi = np.array([b.bounds[1] for b in bs], dtype=np.float64).reshape(-1, 3)
        tris = np.array(
            [self.geometry[b.geometry_key].index_count // 3 * b.count for b in bs],
            dtype=np.float64,
        )
        dyn = np.array([b.dynamic for b in bs], dtype=bool)
        self._batch_arrays = BatchArrays(bs, lo, hi, tris, dyn)
        return self._batch_arrays

    def _age_batches(self) -> None:
        """No transform changed: the previous-frame matrices catch up once."""
        for b in self.batches:
            if b.prev_models is not b.models and not np.array_equal(b.prev_models, b.models):
                b.prev_models = b.models
                self._upload_instances(b)

    def _upload_instances(self, b: DrawBatch) -> None:
        data = np.concatenate(
            [b.models.reshape(-1, 16), b.prev_models.reshape(-1, 16)], axis=1
        ).astype(np.float32)
        if b.instance_buffer is None:
            b.instance_buffer = self.ctx.buffer(data.tobytes())
        else:
            b.instance_buffer.orphan(data.nbytes)
            b.instance_buffer.write(data.tobytes())
        self.stats["instance_uploads"] += 1

    def vertex_array(
        self, b: DrawBatch, prog: moderngl.Program, depth_only: bool = False
    ) -> moderngl.VertexArray:
        """Instanced VAO of a batch for a program (cached per program). ``depth_only``:
        positions (and texture coordinates, for alpha-tested depth programs) only."""
        key = prog.glo
        vao = b.vaos.get(key)
        if vao is None:
            g = self.geometry[b.geometry_key]
            content: list[tuple[Any, ...]]
            if depth_only:
                content = [
                    (g.vbo, "3f 24x", "in_pos"),
                    (b.instance_buffer, "16f 64x/i", "in_model"),
                ]
                if g.vbo_material is not None and "in_uv" in prog:
                    content.append((g.vbo_material, "2f 32x", "in_uv"))
            else:
                content = [
                    (g.vbo, "3f 3f 3f", "in_pos", "in_normal", "in_color"),
                    (b.instance_buffer, "16f 16f/i", "in_model", "in_prev_model"),
                ]
                if g.vbo_material is not None and "in_uv" in prog:
                    content.append((g.vbo_material, "2f 4f 4f", "in_uv", "in_tangent", "in_attr"))
            vao = self.ctx.vertex_array(
                prog, content, index_buffer=g.ibo, index_element_size=4, skip_errors=True
            )
            b.vaos[key] = vao
        return vao

    # -- lights --
    @property
    def fov_pos_range(self) -> np.ndarray | None:
        """(n, 4) float32 ``pos_range`` (world position, m; range, m) of the uploaded
        in-view light records, in light-buffer order: the SSBO's own floats (None before
        the first upload)."""
        return None if self._fov_packed is None else self._fov_packed[:, 0:4]

    def upload_lights(self, rows: np.ndarray, maps: np.ndarray | None) -> bool:
        """Upload the packed light buffer of ``rows`` (light-table rows in SSBO order)
        with shadow-map slots ``maps`` (per row, -1 = none; None = shadows off) if the
        set, one of its lights or the slot assignment changed; only the changed span
        when the set is the same. Returns True when it uploaded."""
        version = int(self.light_table.version)
        same_rows = self._fov_uploaded_rows is not None and np.array_equal(
            rows, self._fov_uploaded_rows
        )
        prev_maps = self._fov_uploaded_maps
        # FoV positions whose map slot changed (comparable only for the same rows).
        moved = (
            np.nonzero(maps != prev_maps)[0]
            if same_rows and maps is not None and prev_maps is not None
            else np.zeros(0, np.int64)
        )
        same_maps = (maps is None and prev_maps is None) or (
            same_rows and maps is not None and prev_maps is not None and not len(moved)
        )
        changed_rows = (
            np.nonzero(self.light_table.cols["version"][rows] > self._fov_version)[0]
            if version != self._fov_version and len(rows)
            else np.zeros(0, np.int64)
        )
        if same_rows and same_maps and not len(changed_rows) and self.light_ssbo is not None:
            self._fov_version = version
            self.last_upload_records = 0
            return False
        if (
            same_rows
            and self._fov_packed is not None
            and self.light_ssbo is not None
            and (maps is None) == (prev_maps is None)
        ):
            # Same culled set: patch the records that changed (new shadow-map
            # slots, edited lights) and upload their span, not the whole buffer.
            packed = self._fov_packed
            if len(moved) and maps is not None:  # moved is empty when maps is None
                packed[moved, LIGHT_SHADOW_SLOT_COLUMN] = maps[moved]
            if len(changed_rows):
                sub = None if maps is None else maps[changed_rows]
                packed[changed_rows] = pack_lights(self.light_table, rows[changed_rows], sub)
            pos = np.union1d(moved, changed_rows)
            lo, hi = int(pos[0]), int(pos[-1]) + 1
            self.light_ssbo.write(packed[lo:hi].tobytes(), offset=lo * LIGHT_STRIDE_BYTES)
            self._fov_uploaded_maps = None if maps is None else maps.copy()
            self._fov_version = version
            self.last_upload_records = hi - lo
            self.stats["light_uploads"] += 1
            self.stats["light_partial_uploads"] += 1
            return True
        packed = pack_lights(self.light_table, rows, maps)
        nbytes = max(packed.nbytes, LIGHT_STRIDE_BYTES)
        if self.light_ssbo is None or self.light_ssbo.size < nbytes:
            if self.light_ssbo is not None:
                self.light_ssbo.release()
            self.light_ssbo = self.ctx.buffer(reserve=max(nbytes, 64 * LIGHT_STRIDE_BYTES))
        if packed.nbytes:
            self.light_ssbo.write(packed.tobytes())
        self._fov_packed = packed
        self._fov_uploaded_rows = rows
        self._fov_uploaded_maps = None if maps is None else maps.copy()
        self._fov_version = version
        self.last_upload_records = len(rows)
        self.stats["light_uploads"] += 1
        return True

    def _upload_ies(self) -> None:
        from ..scene.light_shaping import load_ies_cached

        layers = self.ies.layers
        n = max(layers.values(), default=-1) + 1
        if self.ies_texture is not None:
            self.ies_texture.release()
            self.ies_texture = None
        if self.ies_cos_texture is not None:
            self.ies_cos_texture.release()
            self.ies_cos_texture = None
        self.ies_layer_count = n
        self._ies_version = self.ies.version
        if n == 0:
            return
        n = min(n, limits.MAX_IES_PROFILES)
        data = np.zeros((n, limits.IES_TABLE_THETA, limits.IES_TABLE_PHI), dtype=np.float32)
        for path, layer in layers.items():
            if layer >= n:
                continue
            try:
                table = load_ies_cached(path).bake_table()
            except Exception:  # noqa: BLE001 - a profile that vanished renders flat
                continue
            mx = float(np.max(table)) if table.size else 0.0
            if mx > 0 and np.isfinite(mx):
                data[layer] = np.nan_to_num(table / mx, nan=0.0, posinf=0.0, neginf=0.0)
        tex = self.ctx.texture_array(
            (limits.IES_TABLE_PHI, limits.IES_TABLE_THETA, n), 1, data.tobytes(), dtype="f4"
        )
        tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
        tex.repeat_x = True
        tex.repeat_y = False
        self.ies_texture = tex
        cos_max = ies_cos_rowmax(data, limits.STB_REUSE_IES_COS_BINS)
        ct = self.ctx.texture_array((cos_max.shape[1], 1, n), 1, cos_max.tobytes(), dtype="f4")
        ct.filter = (moderngl.LINEAR, moderngl.LINEAR)
        ct.repeat_x = False
        ct.repeat_y = False
        self.ies_cos_texture = ct

    @property
    def has_ies(self) -> bool:
        return self.ies_texture is not None

    def _upload_rect_textures(self) -> None:
        """(Re)build the RectLight texture array from the registry: layer k holds
        ``scene.rect_texture.load_rect_texture``'s layer and its mip chain (an
        unreadable file: ones, i.e. the mean)."""
        from ..scene.rect_texture import load_rect_texture
        from .delegate import rect_texture_of

        self._rect_version = self.rect_textures.version
        if self.rect_texture_array is not None:
            self.rect_texture_array.release()
            self.rect_texture_array = None
        layers = {k: v for k, v in self.rect_textures.layers.items()}
        n = min(max(layers.values(), default=-1) + 1, limits.MAX_RECT_TEXTURES)
        if n == 0:
            return
        size = limits.RECT_TEXTURE_PX
        data = np.ones((n, size, size, 3), np.float16)
        for key, layer in layers.items():
            if layer >= n:
                continue
            try:
                tex = load_rect_texture(*rect_texture_of(key))
            except Exception:  # noqa: BLE001 - a file that vanished emits its mean
                continue
            data[layer] = np.minimum(tex.layer, limits.HALF_MAX)
        arr = self.ctx.texture_array((size, size, n), 3, data.tobytes(), dtype="f2")
        # GL's mip generation of a power-of-two layer: 2 x 2 box means, i.e. each texel of
        # level k the mean of the texture over its part of the rect.
        arr.build_mipmaps()
        arr.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
        arr.repeat_x = False
        arr.repeat_y = False
        self.rect_texture_array = arr

    def seen_rect_emitters(self) -> np.ndarray:
        """(k, 4, 4) float32 records of the textured RectLights the camera may see
        (``u_rect_seen`` of common/rect_emitter.glsl, at most ``limits.MAX_RECT_TEXTURES``):
        centre (m) + texture layer; +X half axis (m) + 0; +Y half axis (m) + 0; radiance
        (nits: ``intensity`` x radiance per cd, the texture's mean) + 0. Render frame."""
        t = self.light_table
        key = (int(t.version), self._rect_version, self.rect_texture_array is not None)
        if self._seen_rects is not None and self._seen_rects[0] == key:
            return self._seen_rects[1]
        n = t.n_rows
        c = t.cols
        rows = np.nonzero(
            c["live"][:n]
            & c["enabled"][:n]
            & c["camera_visible"][:n]
            & (c["texture_layer"][:n] >= 0)
            & (c["area_kind"][:n] == sc.AREA_RECT)
        )[0][: limits.MAX_RECT_TEXTURES]
        if self.rect_texture_array is None:
            rows = rows[:0]
        out = np.zeros((len(rows), 4, 4), np.float32)
        self._seen_rects = (key, out)
        if not len(rows):
            return out
        X = c["tangent"][rows].astype(np.float64)
        Z = -c["direction"][rows].astype(np.float64)  # light +Z (it emits along -Z)
        Y = np.cross(Z, X)
        out[:, 0, :3] = c["position"][rows]
        out[:, 0, 3] = c["texture_layer"][rows]
        out[:, 1, :3] = X * c["area_size"][rows, :1]
        out[:, 2, :3] = Y * c["area_size"][rows, 1:2]
        out[:, 3, :3] = c["intensity"][rows] * c["area_radiance"][rows, None]
        return out

    def release(self) -> None:
        for g in self.geometry.values():
            self._release_geometry(g)
        self.textures.release()
        for b in self.batches:
            if b.instance_buffer is not None:
                b.instance_buffer.release()
            for vao in b.vaos.values():
                vao.release()
        if self.light_ssbo is not None:
            self.light_ssbo.release()
        if self.ies_texture is not None:
            self.ies_texture.release()
        if self.ies_cos_texture is not None:
            self.ies_cos_texture.release()
        if self.rect_texture_array is not None:
            self.rect_texture_array.release()
        self.dome_env.release()
        self.geometry.clear()
        self.batches.clear()


def _material_vertices(mesh: prims.MeshPrim) -> np.ndarray | None:
    """(n, 10) float32 texture coordinates, tangent frame and material primvars of a
    mesh that has texture coordinates or material primvars, else None."""
    if mesh.uvs is None and mesh.attrs is None:
        return None
    n = len(mesh.points)
    out = np.zeros((max(n, 1), 10), dtype=np.float32)
    if mesh.uvs is not None:
        out[:n, 0:2] = mesh.uvs[:n]
    if mesh.tangents is not None:
        out[:n, 2:6] = mesh.tangents[:n]
    else:
        out[:n, 2] = 1.0
        out[:n, 5] = 1.0
    if mesh.attrs is not None:
        out[:n, 6:10] = mesh.attrs[:n]
    return out


def ies_cos_rowmax(tables: np.ndarray, bins: int) -> np.ndarray:
    """(layers, bins) float32 from (layers, T, P) normalised IES tables (rows theta 0..pi
    off the light's -Z axis, both ends exact; shaders/common/ies.glsl): bin j at cos
    c_j = -1 + 2 j / (bins - 1) holds the maximum over phi of every row that the theta
    span of [c_(j-1), c_(j+1)] touches (the rows either side of it included), so a
    linear lookup at any cos is >= the table's bilinear value in every direction with
    that cos (unitless, the table's units)."""
    n, t_rows, _ = tables.shape
    rows = tables.max(axis=2)
    c = np.linspace(-1.0, 1.0, bins)
    lo_c = np.clip(c + 2.0 / (bins - 1), -1.0, 1.0)  # cos of the span's low theta
    hi_c = np.clip(c - 2.0 / (bins - 1), -1.0, 1.0)
    scale = (t_rows - 1) / np.pi
    r0 = np.clip(np.floor(np.arccos(lo_c) * scale).astype(int) - 1, 0, t_rows - 1)
    r1 = np.clip(np.ceil(np.arccos(hi_c) * scale).astype(int) + 1, 0, t_rows - 1)
    out = np.empty((n, bins), dtype=np.float32)
    for j in range(bins):
        out[:, j] = rows[:, r0[j] : r1[j] + 1].max(axis=1)
    return np.ascontiguousarray(out)
