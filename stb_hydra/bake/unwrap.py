"""Lightmap UVs for static meshes: xatlas charts packed into one atlas per mesh.

A mesh is read from USD in its authored topology (fan-triangulated exactly as the
renderer's ``scene.geometry`` does), in the render frame (metres, Y up) so the texel
density is per world metre. Each face-vertex gets one lightmap UV: that is what the
``faceVarying`` primvar ``primvars:stb:lightmap:uv`` can hold. Results are cached on
disk by a hash of the mesh content (world positions, triangles, density, options).

A mesh that cannot be unwrapped (non-manifold edges, zero-area faces, more than
``limits.BAKE_MAX_TRIANGLES`` triangles, a polygon split across two charts, xatlas
failing) yields :class:`UnwrapError` with a one-line reason; the caller warns and
leaves the mesh unbaked.
"""

from __future__ import annotations

import hashlib
import math
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pxr import Usd, UsdGeom

from .. import limits
from ..scene.geometry import (
    IMPLICIT_TYPES,
    _authored_normals,
    _corner_normals,
    _read_topology,
    _Topology,
    implicit_lightmap_triangles,
    tessellate_implicit,
)

#: Bump when the unwrap options or the cache layout change (old entries are ignored).
CACHE_VERSION = 3


class UnwrapError(ValueError):
    """The mesh cannot get lightmap UVs (one-line reason)."""


@dataclass
class MeshLayout:
    """One mesh ready to bake: render-frame geometry per triangle corner and its UVs.

    ``corners`` (m, 3): face-vertex index of each triangle corner (authored order);
    ``uv_fv`` (n_fv, 2): lightmap UV per face-vertex in [0, 1] (v up, GL convention);
    ``P``/``N`` (m, 3, 3): world position (m) and unit normal per triangle corner;
    ``size``: lightmap (width, height) in texels; ``density``: the ``texels_per_unit``
    xatlas packed with (texels per metre; ``achieved`` is what the UVs get).
    """

    path: str
    corners: np.ndarray
    uv_fv: np.ndarray
    P: np.ndarray
    N: np.ndarray
    size: tuple[int, int]
    density: float
    content_hash: str
    cached: bool = False
    #: Set when the mesh must be re-authored as triangles (``corners`` then index its
    #: 3 m face-vertices): (m, 3) point indices, and object-space normals per corner.
    tri_points: np.ndarray | None = None
    tri_normals_fv: np.ndarray | None = None
    #: Texel density the lightmap achieves (texels per metre): sqrt(lightmap texel
    #: area of the triangles / their world area, m^2). Measured on the UVs, not the
    #: density asked of xatlas.
    achieved: float = 0.0
    #: The prim is an implicit shape (Cube, Sphere, ...): its UVs are per corner of the
    #: renderer's tessellation (``scene.geometry.tessellate_implicit``), 3 per triangle.
    implicit: bool = False
    #: The size cap (``limits.BAKE_LIGHTMAP_MAX_SIZE``) lowered the density.
    capped: bool = False

    @property
    def tri_uv(self) -> np.ndarray:
        """(m, 3, 2) UV per triangle corner."""
        return self.uv_fv[self.corners]


def default_cache_dir() -> Path:
    """``$STB_BAKE_CACHE``, else ``$XDG_CACHE_HOME/stb_hydra/xatlas`` (~/.cache)."""
    env = os.environ.get("STB_BAKE_CACHE")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "stb_hydra" / "xatlas"


@dataclass
class MeshSource:
    """A mesh's authored topology with render-frame points (n, 3) (metres) and unit
    normals per face-vertex, in the render frame and as authored (object space)."""

    prim: Usd.Prim
    topo: _Topology
    points: np.ndarray
    normals_fv: np.ndarray
    normals_fv_object: np.ndarray


def mesh_world_data(prim: Usd.Prim, world: np.ndarray, time: Usd.TimeCode) -> MeshSource:
    """The mesh (or implicit shape, :func:`implicit_topology`) at ``time`` in the
    render frame.

    ``world``: 4x4 object -> render frame, row-vector convention (``MeshPrim.transform``).
    """
    if prim.GetTypeName() in IMPLICIT_TYPES:
        topo_i, normals = implicit_topology(prim, time)
        return _to_world(prim, topo_i, normals, world)
    topo = _read_topology(prim, UsdGeom.Mesh(prim), time)
    if not isinstance(topo, _Topology):
        raise UnwrapError("no usable topology")
    nvals, ninterp = _authored_normals(prim, UsdGeom.Mesh(prim), time)
    normals_fv, _ = _corner_normals(topo, nvals, ninterp, None, None)
    return _to_world(prim, topo, normals_fv, world)


def implicit_topology(prim: Usd.Prim, time: Usd.TimeCode) -> tuple[_Topology, np.ndarray]:
    """An implicit shape (``Cube``, ``Sphere``, ``Cylinder``, ``Cone``, ``Capsule``,
    ``Plane``) as the renderer draws it (``tessellate_implicit``, object space), in
    the form of a triangle mesh whose face-vertices are the corners of its
    non-degenerate triangles (``implicit_lightmap_triangles``: 3 per triangle, in the
    tessellation's order), and its unit normals per face-vertex. UnwrapError when the
    shape does not tessellate."""
    g = tessellate_implicit(prim, time)
    if g is None or len(g.indices) == 0:
        raise UnwrapError(f"implicit {prim.GetTypeName()} does not tessellate")
    if not (np.all(np.isfinite(g.points)) and np.all(np.isfinite(g.normals))):
        raise UnwrapError(f"implicit {prim.GetTypeName()} has a non-finite size")
    tris = implicit_lightmap_triangles(g)
    if len(tris) == 0:
        raise UnwrapError(f"implicit {prim.GetTypeName()} has zero size")
    m = len(tris)
    fvi = tris.reshape(-1)
    topo = _Topology(
        str(prim.GetPath()),
        np.asarray(g.points, dtype=np.float32),
        np.full(m, 3, dtype=np.int64),
        fvi,
        np.arange(3 * m, dtype=np.int64).reshape(m, 3),
        np.arange(m, dtype=np.int64),
        np.repeat(np.arange(m, dtype=np.int64), 3),
        [],
    )
    return topo, np.asarray(g.normals, dtype=np.float64)[fvi]


def _to_world(
    prim: Usd.Prim, topo: _Topology, normals_fv: np.ndarray, world: np.ndarray
) -> MeshSource:
    pts = np.c_[topo.points.astype(np.float64), np.ones(len(topo.points))] @ world
    nm = np.linalg.inv(world[:3, :3]).T  # row-vector normals: n @ inv(M)^T
    n_obj = np.asarray(normals_fv, dtype=np.float64)
    n = n_obj @ nm
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-20)
    return MeshSource(prim, topo, pts[:, :3], n, n_obj)


def check_mesh(points: np.ndarray, tris: np.ndarray) -> None:
    """Raise UnwrapError for inputs xatlas cannot chart well (see module doc)."""
    m = len(tris)
    if m == 0:
        raise UnwrapError("no triangles")
    if m > limits.BAKE_MAX_TRIANGLES:
        raise UnwrapError(
            f"{m} triangles (limit {limits.BAKE_MAX_TRIANGLES}, limits.BAKE_MAX_TRIANGLES)"
        )
    p = points[tris]
    area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
    bad = int(np.count_nonzero(~(area > limits.BAKE_MIN_FACE_AREA_M2)))
    if bad:
        raise UnwrapError(f"{bad} zero-area face(s)")


def non_manifold_edges(tris: np.ndarray) -> int:
    """Edges shared by more than two triangles (xatlas cuts charts there; the result
    is checked triangle by triangle in :func:`unwrap_mesh`)."""
    e = np.sort(np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]], tris[:, [2, 0]]]), axis=1)
    _, counts = np.unique(e, axis=0, return_counts=True)
    return int(np.count_nonzero(counts > 2))


def _hash(points: np.ndarray, tris: np.ndarray, density: float) -> str:
    h = hashlib.sha256()
    h.update(f"v{CACHE_VERSION} d{density:.6g} p{limits.BAKE_PADDING_TEXELS}".encode())
    h.update(np.ascontiguousarray(points, dtype=np.float32).tobytes())
    h.update(np.ascontiguousarray(tris, dtype=np.uint32).tobytes())
    return h.hexdigest()[:32]


def _xatlas(points: np.ndarray, tris: np.ndarray, density: float) -> tuple[np.ndarray, ...]:
    """(vmapping, indices, uvs, [w, h]) from xatlas; uvs normalised to [0, 1]. In a
    child process (:mod:`.xatlas_process`: destroying an xatlas ``Atlas`` can hang)."""
    from .xatlas_process import generate

    vmap, idx, uvs, size, count = generate(points, tris, density, limits.BAKE_PADDING_TEXELS)
    if count != 1:
        raise UnwrapError(f"xatlas made {count} atlases (expected 1)")
    return vmap, idx, uvs, size


def _pack(points: np.ndarray, tris: np.ndarray, density: float) -> tuple[np.ndarray, ...]:
    """xatlas at the density (texels/m) that gives ``density`` on the UVs, capped by
    ``limits.BAKE_LIGHTMAP_MAX_SIZE``: (vmap, idx, uvs, size, texels_per_unit used,
    whether the cap lowered it).

    xatlas's ``texels_per_unit`` is not the density its charts get: the charts of a
    curved or finely tessellated mesh are flattened with some stretch and rounded up
    to whole texels (a 0.15 m sphere came out at 18.5 texels/m for 16). So the
    achieved density (:func:`achieved_density`) is measured and ``texels_per_unit``
    corrected by the ratio, up to ``BAKE_DENSITY_PASSES`` packings; a lightmap over
    the size cap lowers it instead (the caller warns)."""
    cap = limits.BAKE_LIGHTMAP_MAX_SIZE
    P = points[tris]
    d = float(density)
    best: tuple[float, tuple[np.ndarray, ...]] | None = None
    capped = False
    for _ in range(limits.BAKE_DENSITY_PASSES):
        try:
            vmap, idx, uvs, size = _xatlas(points, tris, d)
        except UnwrapError:
            raise
        except Exception as exc:  # noqa: BLE001 - xatlas raises bare RuntimeErrors
            raise UnwrapError(f"xatlas failed: {exc}") from None
        if max(size) > cap:
            # Chart sizes scale with the density, the padding does not: aim 2 % under.
            capped = True
            d *= 0.98 * (cap - 2 * limits.BAKE_PADDING_TEXELS) / float(max(size))
            continue
        res = (vmap, idx, uvs, size, np.array(d), np.array(capped))
        tri_uv = np.asarray(uvs, dtype=np.float64)[np.asarray(idx, np.int64).reshape(-1, 3)]
        got = achieved_density(P, tri_uv, (int(size[0]), int(size[1])))
        if capped or got <= 0.0:
            return res
        err = abs(got / density - 1.0)
        if best is None or err < best[0]:
            best = (err, res)
        if err <= limits.BAKE_DENSITY_TOLERANCE:
            return res
        d *= density / got
    if best is not None:
        return best[1]
    raise UnwrapError("charts do not fit one lightmap")


def unwrap_mesh(src: MeshSource, density: float, cache_dir: Path | None = None) -> MeshLayout:
    """Lightmap layout of one mesh (render frame, metres). Raises UnwrapError."""
    path = str(src.prim.GetPath())
    topo, points, normals_fv = src.topo, src.points, src.normals_fv
    corners = np.asarray(topo.corners, dtype=np.int64)
    tris = topo.fvi[corners].astype(np.int64)
    check_mesh(points, tris)
    d = float(density)
    key = _hash(points, tris, d)
    cached = False
    res: tuple[np.ndarray, ...] | None = None
    cfile = (cache_dir / f"{key}.npz") if cache_dir is not None else None
    if cfile is not None and cfile.exists():
        try:
            with np.load(cfile) as z:
                res = (z["vmap"], z["idx"], z["uvs"], z["size"], z["density"], z["capped"])
            cached = True
        except (OSError, ValueError, KeyError):
            res = None
    if res is None:
        res = _pack(points, tris, d)
        if cfile is not None:
            _save_npz(cfile, res)
    _vmap, idx, uvs, size, dens, capped_ = res
    idx = np.asarray(idx, dtype=np.int64).reshape(-1, 3)
    if len(idx) != len(tris):
        raise UnwrapError(f"xatlas returned {len(idx)} triangles for {len(tris)}")
    uv_fv = np.full((len(topo.fvi), 2), np.nan, dtype=np.float64)
    flat_c = corners.reshape(-1)
    flat_uv = np.asarray(uvs, dtype=np.float64)[idx.reshape(-1)]
    uv_fv[flat_c] = flat_uv
    retri = False
    if not np.allclose(uv_fv[flat_c], flat_uv, atol=1e-6):
        # A polygon whose fan triangles went to different charts has a face-vertex with
        # two UVs, which a faceVarying primvar cannot hold: the output layer re-authors
        # the mesh as its triangles (same points, same triangulation as the renderer's).
        _check_retriangulable(src.prim)
        retri = True
        corners = np.arange(3 * len(tris), dtype=np.int64).reshape(-1, 3)
        uv_fv = flat_uv
        normals_fv = normals_fv[flat_c]
    t_uv = uv_fv[corners]
    e1, e2 = t_uv[:, 1] - t_uv[:, 0], t_uv[:, 2] - t_uv[:, 0]
    a_uv = np.abs(e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])
    flat = int(np.count_nonzero(~(a_uv > 0.0)))
    if flat:
        nm = non_manifold_edges(tris)
        why = f" ({nm} non-manifold edge(s))" if nm else ""
        raise UnwrapError(f"xatlas left {flat} triangle(s) without lightmap area{why}")
    unused = np.isnan(uv_fv[:, 0])
    uv_fv[unused] = 0.0
    if not np.all(np.isfinite(uv_fv)) or uv_fv.min() < 0.0 or uv_fv.max() > 1.0:
        raise UnwrapError("xatlas UVs outside [0, 1]")
    P = points[tris]
    N = normals_fv[corners]
    return MeshLayout(
        path,
        corners,
        uv_fv.astype(np.float32),
        P,
        N,
        (int(size[0]), int(size[1])),
        float(dens),
        key,
        cached,
        tri_points=tris if retri else None,
        tri_normals_fv=src.normals_fv_object[flat_c].astype(np.float32) if retri else None,
        achieved=achieved_density(P, t_uv, (int(size[0]), int(size[1]))),
        implicit=src.prim.GetTypeName() in IMPLICIT_TYPES,
        capped=bool(capped_),
    )


def achieved_density(P: np.ndarray, tri_uv: np.ndarray, size: tuple[int, int]) -> float:
    """Texels per metre a lightmap gives its triangles: sqrt(lightmap area in texels /
    world area in m^2). ``P`` (m, 3, 3) world corners (m), ``tri_uv`` (m, 3, 2) UVs in
    [0, 1], ``size`` (width, height) in texels."""
    w, h = size
    e1, e2 = P[:, 1] - P[:, 0], P[:, 2] - P[:, 0]
    a_world = float(np.sum(0.5 * np.linalg.norm(np.cross(e1, e2), axis=1)))
    u = np.asarray(tri_uv, dtype=np.float64) * np.array([w, h], dtype=np.float64)
    f1, f2 = u[:, 1] - u[:, 0], u[:, 2] - u[:, 0]
    a_tex = float(np.sum(0.5 * np.abs(f1[:, 0] * f2[:, 1] - f1[:, 1] * f2[:, 0])))
    return math.sqrt(a_tex / a_world) if a_world > 0 else 0.0


def _check_retriangulable(prim: Usd.Prim) -> None:
    """Re-authoring a mesh as triangles keeps its look only when no per-face or
    per-face-vertex primvar (other than normals) and no left-handed winding is authored."""
    mesh = UsdGeom.Mesh(prim)
    if mesh.GetOrientationAttr().Get() == UsdGeom.Tokens.leftHanded:
        raise UnwrapError("a polygon was split across lightmap charts (left-handed mesh)")
    per_face = (UsdGeom.Tokens.uniform, UsdGeom.Tokens.faceVarying)
    for pv in UsdGeom.PrimvarsAPI(prim).GetPrimvarsWithAuthoredValues():
        if pv.GetPrimvarName() != "normals" and pv.GetInterpolation() in per_face:
            raise UnwrapError(
                f"a polygon was split across lightmap charts and primvar "
                f"'{pv.GetPrimvarName()}' is per face"
            )


def _save_npz(path: Path, res: tuple[np.ndarray, ...]) -> None:
    """Atomic cache write (a crashed bake never leaves a truncated entry)."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".npz.tmp")
        with os.fdopen(fd, "wb") as f:
            np.savez(
                f,
                vmap=res[0],
                idx=res[1],
                uvs=res[2],
                size=res[3],
                density=res[4],
                capped=res[5],
            )
        os.replace(tmp, path)
    except OSError:
        pass  # the cache is an optimisation


__all__ = [
    "MeshLayout",
    "MeshSource",
    "UnwrapError",
    "achieved_density",
    "check_mesh",
    "default_cache_dir",
    "implicit_topology",
    "mesh_world_data",
    "unwrap_mesh",
]
