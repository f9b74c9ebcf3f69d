"""Geometry extraction: UsdGeom.Mesh triangulation and implicit-shape tessellation.

Everything returned is in the prim's object space (stage units) with
counter-clockwise (right-handed) triangle winding. Vectorised with numpy: no
Python loop over faces or vertices.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pxr import Usd, UsdGeom

#: Corners whose smooth vertex normal deviates from the face normal by more than
#: this use the face normal (hard edge) -- cubes stay faceted, spheres smooth.
CREASE_ANGLE_DEG = 45.0
#: Segments of tessellated implicit shapes around their axis / along latitude.
IMPLICIT_SEGMENTS = 32
IMPLICIT_RINGS = 16

IMPLICIT_TYPES = (
    "Sphere",
    "Cube",
    "Cylinder",
    "Cylinder_1",
    "Cone",
    "Capsule",
    "Capsule_1",
    "Plane",
)
MESH_TYPES = ("Mesh", *IMPLICIT_TYPES)


@dataclass
class MeshGeometry:
    points: np.ndarray  # (n, 3) float32
    normals: np.ndarray  # (n, 3) float32
    indices: np.ndarray  # (m, 3) uint32
    vertex_colors: np.ndarray | None = None  # (n, 3) float32
    display_color: np.ndarray | None = None  # (3,) constant colour
    double_sided: bool = False
    warnings: tuple[str, ...] = ()
    #: (n, 2) float32 texture coordinates (the requested st primvar), else None.
    uvs: np.ndarray | None = None
    #: (n, 4) float32 object-space tangents along +s (xyz, unit, orthogonal to the
    #: normal) and the bitangent sign (w): bitangent = w * cross(normal, tangent)
    #: points along +t (MikkTSpace's convention); present with ``uvs``.
    tangents: np.ndarray | None = None
    #: (n, 4) float32 values of the requested material primvars (float3 in xyz,
    #: float in w; see :class:`PrimvarRequest`), else None.
    attrs: np.ndarray | None = None


@dataclass(frozen=True)
class PrimvarRequest:
    """Primvars a mesh's material reads besides points and normals: the texture
    coordinates (``uv``: the first of these names the mesh has) and up to one float3
    (``vec3``) and one float (``scalar``) primvar for ``UsdPrimvarReader`` inputs."""

    uv: tuple[str, ...] = ()
    vec3: str | None = None
    scalar: str | None = None


#: The request of a mesh whose material reads no texture or primvar: nothing beyond
#: points, normals and displayColor (no texture coordinates are kept or uploaded).
DEFAULT_PRIMVARS = PrimvarRequest()


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.where(n > 1e-20, v / np.maximum(n, 1e-30), np.array([0.0, 1.0, 0.0]))


def triangulate(
    counts: np.ndarray, indices: np.ndarray, holes: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Fan-triangulate polygons. Returns (tri_corner_index (m,3) into the
    face-vertex array, tri_face (m,) the source face of each triangle)."""
    counts = np.asarray(counts, dtype=np.int64)
    nface = len(counts)
    starts = np.zeros(nface, dtype=np.int64)
    if nface:
        starts[1:] = np.cumsum(counts)[:-1]
    valid = counts >= 3
    if holes is not None and len(holes):
        h = np.asarray(holes, dtype=np.int64)
        h = h[(h >= 0) & (h < nface)]
        valid[h] = False
    ntri = np.where(valid, counts - 2, 0)
    total = int(ntri.sum())
    face = np.repeat(np.arange(nface), ntri)
    # k-th triangle within its face
    first = np.zeros(nface, dtype=np.int64)
    if nface:
        first[1:] = np.cumsum(ntri)[:-1]
    k = np.arange(total) - first[face]
    s = starts[face]
    corners = np.stack([s, s + k + 1, s + k + 2], axis=1)
    return corners, face


def _primvar(prim: Usd.Prim, name: str, time: Usd.TimeCode) -> tuple[np.ndarray | None, str | None]:
    """(flattened values, interpolation) of an authored primvar, else (None, None)."""
    pv = UsdGeom.PrimvarsAPI(prim).GetPrimvar(name)
    if not pv or not pv.HasAuthoredValue():
        return None, None
    val = pv.ComputeFlattened(time)
    if val is None:
        return None, None
    return np.asarray(val), pv.GetInterpolation()


def _expand(
    values: np.ndarray,
    interp: str,
    n_points: int,
    n_faces: int,
    fv_index: np.ndarray,
    face_of_corner: np.ndarray,
) -> np.ndarray | None:
    """Per-face-vertex array for a primvar of any interpolation (None when sizes mismatch)."""
    v = np.asarray(values)
    if interp == UsdGeom.Tokens.constant:
        return np.broadcast_to(
            v.reshape(-1)[:3] if v.ndim == 1 else v[0],
            (len(fv_index), v.shape[-1] if v.ndim > 1 else 3),
        )
    if interp in (UsdGeom.Tokens.vertex, UsdGeom.Tokens.varying):
        if len(v) < n_points:
            return None
        return v[fv_index]
    if interp == UsdGeom.Tokens.uniform:
        if len(v) < n_faces:
            return None
        return v[face_of_corner]
    if interp == UsdGeom.Tokens.faceVarying:
        if len(v) < len(fv_index):
            return None
        return v[: len(fv_index)]
    return None


@dataclass
class _Topology:
    """A Mesh's checked points and face-vertex topology, fan-triangulated."""

    prim_path: str
    points: np.ndarray  # (n, 3) float32, finite
    counts: np.ndarray  # (faces,) int64
    fvi: np.ndarray  # (face-vertices,) int64 indices into points
    corners: np.ndarray  # (m, 3) triangle corners: indices into fvi, right-handed
    tri_face: np.ndarray  # (m,) source face of each triangle
    face_of_corner: np.ndarray  # (face-vertices,) face of each face-vertex
    warnings: list[str]

    def expand(self, values: np.ndarray, interp: str) -> np.ndarray | None:
        """A primvar per face-vertex (None when its size does not match)."""
        return _expand(
            values, interp, len(self.points), len(self.counts), self.fvi, self.face_of_corner
        )


def read_mesh_geometry(
    prim: Usd.Prim, time: Usd.TimeCode, request: PrimvarRequest = DEFAULT_PRIMVARS
) -> MeshGeometry | None:
    """Triangulated geometry of a Mesh or implicit gprim; None when empty/invalid.
    ``request``: the texture-coordinate and material primvars to read (any
    interpolation, indexed or not); tangents come with the texture coordinates."""
    tname = prim.GetTypeName()
    if tname in IMPLICIT_TYPES:
        return tessellate_implicit(prim, time)
    mesh = UsdGeom.Mesh(prim)
    topo = _read_topology(prim, mesh, time)
    if not isinstance(topo, _Topology):
        return topo  # None (nothing authored) or an empty mesh with a warning
    nvals, ninterp = _authored_normals(prim, mesh, time)
    cvals, cinterp = _primvar(prim, "displayColor", time)
    display = None
    if cvals is not None and cinterp == UsdGeom.Tokens.constant and len(cvals):
        display = np.asarray(cvals[0], dtype=np.float32)
        cvals = None
    extra = _ExtraPrimvars.read(prim, time, request, topo)
    normals_fv, need_fv = _corner_normals(topo, nvals, ninterp, cvals, cinterp)
    need_fv = need_fv or extra.per_corner
    colors_fv = None
    if cvals is not None:
        colors_fv = topo.expand(cvals, cinterp)
    if (
        not need_fv
        and ninterp in (UsdGeom.Tokens.vertex, UsdGeom.Tokens.varying)
        and nvals is not None
    ):
        g = _shared_vertex_mesh(prim, topo, nvals, cvals, cinterp, display)
        extra.attach(g, topo, None)
        return g
    g, used = _face_varying_mesh(prim, topo, normals_fv, colors_fv, display)
    extra.attach(g, topo, used)
    return g


_PER_CORNER = (UsdGeom.Tokens.faceVarying, UsdGeom.Tokens.uniform)


@dataclass
class _ExtraPrimvars:
    """The requested texture-coordinate / material primvars of one mesh, read and
    checked: per point (``vertex``/``varying``/``constant``) or per face-vertex."""

    uv: np.ndarray | None = None  # (points or face-vertices, 2)
    uv_per_corner: bool = False
    attr: np.ndarray | None = None  # (points or face-vertices, 4)
    attr_per_corner: bool = False

    @property
    def per_corner(self) -> bool:
        return self.uv_per_corner or self.attr_per_corner

    @classmethod
    def read(
        cls, prim: Usd.Prim, time: Usd.TimeCode, req: PrimvarRequest, topo: _Topology
    ) -> _ExtraPrimvars:
        out = cls()
        for name in req.uv:
            vals, interp = _primvar(prim, name, time)
            if vals is None:
                continue
            v = np.asarray(vals, dtype=np.float64)
            if v.ndim != 2 or v.shape[1] < 2:
                topo.warnings.append(f"mesh <{topo.prim_path}>: primvar '{name}' is not a float2")
                continue
            uv, per_corner = _per_point_or_corner(v[:, :2], interp, topo)
            if uv is None:
                topo.warnings.append(
                    f"mesh <{topo.prim_path}>: primvar '{name}' has the wrong size; ignored"
                )
                continue
            out.uv, out.uv_per_corner = uv, per_corner
            break
        cols: list[tuple[np.ndarray, bool] | None] = []
        for name, width in ((req.vec3, 3), (req.scalar, 1)):
            col = None
            if name:
                vals, interp = _primvar(prim, name, time)
                if vals is not None:
                    v = np.asarray(vals, dtype=np.float64).reshape(len(vals), -1)
                    v = np.pad(v, ((0, 0), (0, max(0, width - v.shape[1]))))[:, :width]
                    a, pc = _per_point_or_corner(v, interp, topo)
                    col = None if a is None else (a, pc)
            cols.append(col)
        if any(c is not None for c in cols):
            pc = any(c is not None and c[1] for c in cols)
            n = len(topo.fvi) if pc else len(topo.points)
            attr = np.zeros((n, 4), dtype=np.float64)
            for c, sl in zip(cols, (slice(0, 3), slice(3, 4))):
                if c is None:
                    continue
                a, a_pc = c
                attr[:, sl] = a[topo.fvi] if pc and not a_pc else a
            out.attr, out.attr_per_corner = attr, pc
        return out

    def attach(self, g: MeshGeometry, topo: _Topology, used: np.ndarray | None) -> None:
        """Store the primvars on ``g``'s vertices -- the points (shared-vertex layout,
        ``used`` None) or the face-vertices ``used`` (face-varying layout: output vertex
        k is face-vertex ``used[k]``) -- then tangents from the texture coordinates."""

        def on_vertices(a: np.ndarray, per_corner: bool) -> np.ndarray:
            if used is None:
                return a  # per point (a per-corner primvar forces the other layout)
            return a[used] if per_corner else a[topo.fvi[used]]

        if self.uv is not None:
            g.uvs = on_vertices(self.uv, self.uv_per_corner).astype(np.float32)
            g.tangents = compute_tangents(g.points, g.normals, g.uvs, g.indices)
        if self.attr is not None:
            g.attrs = on_vertices(self.attr, self.attr_per_corner).astype(np.float32)


def _per_point_or_corner(
    v: np.ndarray, interp: str | None, topo: _Topology
) -> tuple[np.ndarray | None, bool]:
    """(values per point, False) for vertex/varying/constant primvars, (values per
    face-vertex, True) for faceVarying/uniform; (None, _) when the size is wrong."""
    if interp in _PER_CORNER:
        return topo.expand(v, interp), True
    if interp == UsdGeom.Tokens.constant:
        return np.broadcast_to(v[0], (len(topo.points), v.shape[1])).copy(), False
    if len(v) < len(topo.points):
        return None, False
    return v[: len(topo.points)], False


def _read_topology(
    prim: Usd.Prim, mesh: UsdGeom.Mesh, time: Usd.TimeCode
) -> _Topology | MeshGeometry | None:
    """Points, counts and indices, checked and triangulated (left-handed winding
    flipped). None when nothing is authored; an empty MeshGeometry with a warning when
    the topology is inconsistent. Non-finite points become 0 (with a warning)."""
    pts = mesh.GetPointsAttr().Get(time)
    counts = mesh.GetFaceVertexCountsAttr().Get(time)
    fvi = mesh.GetFaceVertexIndicesAttr().Get(time)
    if pts is None or counts is None or fvi is None or len(pts) == 0 or len(counts) == 0:
        return None
    points = np.asarray(pts, dtype=np.float32).reshape(-1, 3)
    counts = np.asarray(counts, dtype=np.int64)
    fvi = np.asarray(fvi, dtype=np.int64)
    warnings: list[str] = []
    if counts.sum() != len(fvi) or (len(fvi) and (fvi.min() < 0 or fvi.max() >= len(points))):
        return MeshGeometry(
            np.zeros((0, 3), np.float32),
            np.zeros((0, 3), np.float32),
            np.zeros((0, 3), np.uint32),
            warnings=(f"mesh <{prim.GetPath()}>: inconsistent topology; skipped",),
        )
    if not np.all(np.isfinite(points)):
        warnings.append(f"mesh <{prim.GetPath()}>: non-finite points replaced by 0")
        points = np.where(np.isfinite(points), points, 0.0).astype(np.float32)
    holes = mesh.GetHoleIndicesAttr().Get(time)
    corners, tri_face = triangulate(counts, fvi, np.asarray(holes) if holes else None)
    if mesh.GetOrientationAttr().Get(time) == UsdGeom.Tokens.leftHanded:
        corners = corners[:, [0, 2, 1]]
    face_of_corner = np.repeat(np.arange(len(counts)), counts)
    return _Topology(
        str(prim.GetPath()), points, counts, fvi, corners, tri_face, face_of_corner, warnings
    )


def _authored_normals(
    prim: Usd.Prim, mesh: UsdGeom.Mesh, time: Usd.TimeCode
) -> tuple[np.ndarray | None, str | None]:
    """(values, interpolation) of authored normals: ``primvars:normals`` wins over
    ``normals``, as in UsdGeom; (None, None) without either."""
    nvals, ninterp = _primvar(prim, "normals", time)
    if nvals is None:
        a = mesh.GetNormalsAttr()
        v = a.Get(time) if a.HasAuthoredValue() else None
        if v is not None and len(v):
            nvals, ninterp = np.asarray(v), mesh.GetNormalsInterpolation()
    return nvals, ninterp


def _corner_normals(
    topo: _Topology,
    nvals: np.ndarray | None,
    ninterp: str | None,
    cvals: np.ndarray | None,
    cinterp: str | None,
) -> tuple[np.ndarray, bool]:
    """(normals per face-vertex, whether the face-varying layout is needed): authored
    normals as authored (for the stated orientation), else computed ones (which, like a
    face-varying or uniform primvar, need the face-varying layout)."""
    per_corner = (UsdGeom.Tokens.faceVarying, UsdGeom.Tokens.uniform)
    need_fv = (nvals is not None and ninterp in per_corner) or (
        cvals is not None and cinterp in per_corner
    )
    if nvals is not None:
        normals_fv = topo.expand(nvals, ninterp)
        if normals_fv is not None:
            return normals_fv, need_fv
        topo.warnings.append(f"mesh <{topo.prim_path}>: normals have the wrong size; recomputed")
    return _auto_normals(topo), True


def _shared_vertex_mesh(
    prim: Usd.Prim,
    topo: _Topology,
    nvals: np.ndarray,
    cvals: np.ndarray | None,
    cinterp: str | None,
    display: np.ndarray | None,
) -> MeshGeometry:
    """Per-vertex normals (and colours): triangles index the authored points."""
    points = topo.points
    normals = _unit(np.asarray(nvals, dtype=np.float32)[: len(points)]).astype(np.float32)
    vcols = None
    if cvals is not None and cinterp in (UsdGeom.Tokens.vertex, UsdGeom.Tokens.varying):
        vcols = np.asarray(cvals, dtype=np.float32)[: len(points)]
    tri = topo.fvi[topo.corners].astype(np.uint32)
    return MeshGeometry(
        points, normals, tri, vcols, display, _double_sided(prim), tuple(topo.warnings)
    )


def _face_varying_mesh(
    prim: Usd.Prim,
    topo: _Topology,
    normals_fv: np.ndarray,
    colors_fv: np.ndarray | None,
    display: np.ndarray | None,
) -> tuple[MeshGeometry, np.ndarray]:
    """One vertex per face-vertex that a triangle uses; also returns those
    face-vertices (``used``: output vertex k is face-vertex ``used[k]``)."""
    mask = np.zeros(len(topo.fvi), dtype=bool)
    mask[topo.corners] = True
    used = np.flatnonzero(mask)  # np.unique(topo.corners) in O(n), without the sort
    remap = np.full(len(topo.fvi), -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    out_pts = topo.points[topo.fvi[used]]
    out_n = _unit(np.asarray(normals_fv, dtype=np.float32)[used]).astype(np.float32)
    out_c = None
    if colors_fv is not None:
        out_c = np.asarray(colors_fv, dtype=np.float32)[used]
    tri = remap[topo.corners].astype(np.uint32)
    g = MeshGeometry(out_pts, out_n, tri, out_c, display, _double_sided(prim), tuple(topo.warnings))
    return g, used


def _double_sided(prim: Usd.Prim) -> bool:
    a = prim.GetAttribute("doubleSided")
    return bool(a.Get()) if a and a.HasAuthoredValue() else False


def _sum_rows(index: np.ndarray, rows: np.ndarray, n: int) -> np.ndarray:
    """(n, 3) float64: ``rows`` summed by ``index`` (``np.add.at`` on zeros, in the same
    order, so to the same bits; ``np.bincount`` per column is ~10x faster)."""
    out = np.empty((n, 3))
    for k in range(3):  # the three columns, not a per-row loop
        out[:, k] = np.bincount(index, weights=rows[:, k], minlength=n)
    return out


def _auto_normals(topo: _Topology) -> np.ndarray:
    """Per face-vertex normals: smooth, but faceted where the smooth normal
    deviates from the face normal by more than ``CREASE_ANGLE_DEG``."""
    points, fvi, face_of_corner = topo.points, topo.fvi, topo.face_of_corner
    p = points.astype(np.float64)
    tri_pts = p[fvi[topo.corners]]
    tn = np.cross(tri_pts[:, 1] - tri_pts[:, 0], tri_pts[:, 2] - tri_pts[:, 0])  # area-weighted
    face_n = _sum_rows(topo.tri_face, tn, len(topo.counts))
    face_unit = _unit(face_n)
    vert_n = _sum_rows(fvi, face_n[face_of_corner], len(points))
    vert_unit = _unit(vert_n)
    smooth = vert_unit[fvi]
    flat = face_unit[face_of_corner]
    cos_c = math.cos(math.radians(CREASE_ANGLE_DEG))
    use_flat = np.sum(smooth * flat, axis=1) < cos_c
    return np.where(use_flat[:, None], flat, smooth)


def compute_tangents(
    points: np.ndarray, normals: np.ndarray, uvs: np.ndarray, tris: np.ndarray
) -> np.ndarray:
    """(n, 4) float32 per-vertex tangent frames from texture coordinates, in the
    manner of MikkTSpace: each triangle's dP/ds and dP/dt, projected onto the
    tangent plane of each corner's normal, normalised and weighted by the corner's
    angle, summed per vertex; the tangent is then orthonormalised against the normal
    (Gram-Schmidt) and ``w`` = +1 when (normal x tangent) points along the summed
    dP/dt, else -1. Shaders rebuild the bitangent per pixel as
    ``w * cross(N, T)`` from the interpolated (not renormalised) vectors. Vertices
    are not split where the handedness flips (mirrored uv islands), unlike MikkTSpace:
    such seams shade with the average frame. A vertex with no usable triangle gets
    any unit tangent perpendicular to its normal and w = +1."""
    n = len(points)
    out = np.zeros((n, 4), dtype=np.float32)
    if n == 0:
        return out
    p = points.astype(np.float64)
    nrm = normals.astype(np.float64)
    uv = uvs.astype(np.float64)
    t = np.asarray(tris, dtype=np.int64).reshape(-1, 3)
    p0, p1, p2 = p[t[:, 0]], p[t[:, 1]], p[t[:, 2]]
    w0, w1, w2 = uv[t[:, 0]], uv[t[:, 1]], uv[t[:, 2]]
    e1, e2 = p1 - p0, p2 - p0
    d1, d2 = w1 - w0, w2 - w0
    det = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
    ok = np.abs(det) > 1e-20
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)[:, None]
    ds = (e1 * d2[:, 1:2] - e2 * d1[:, 1:2]) * inv  # dP/ds
    dt = (e2 * d1[:, 0:1] - e1 * d2[:, 0:1]) * inv  # dP/dt
    idx, tparts, bparts = [], [], []  # each corner's share, summed per vertex below
    corners = ((0, p1 - p0, p2 - p0), (1, p2 - p1, p0 - p1), (2, p0 - p2, p1 - p2))
    for k, a, b in corners:
        la = np.linalg.norm(a, axis=1)
        lb = np.linalg.norm(b, axis=1)
        cosang = np.einsum("ij,ij->i", a, b) / np.maximum(la * lb, 1e-30)
        ang = np.where(ok, np.arccos(np.clip(cosang, -1.0, 1.0)), 0.0)[:, None]
        vn = nrm[t[:, k]]
        ts = ds - vn * np.einsum("ij,ij->i", ds, vn)[:, None]
        tb = dt - vn * np.einsum("ij,ij->i", dt, vn)[:, None]
        ts = ts / np.maximum(np.linalg.norm(ts, axis=1, keepdims=True), 1e-30)
        tb = tb / np.maximum(np.linalg.norm(tb, axis=1, keepdims=True), 1e-30)
        idx.append(t[:, k])
        tparts.append(ts * ang)
        bparts.append(tb * ang)
    # Corner 0 of every triangle, then 1, then 2: the order of three np.add.at calls.
    order = np.concatenate(idx)
    tsum = _sum_rows(order, np.concatenate(tparts), n)
    bsum = _sum_rows(order, np.concatenate(bparts), n)
    tan = tsum - nrm * np.einsum("ij,ij->i", tsum, nrm)[:, None]
    ln = np.linalg.norm(tan, axis=1)
    bad = ln < 1e-12
    if bad.any():
        # Any perpendicular: the normal crossed with the axis it is least along.
        nb = nrm[bad]
        axis = np.eye(3)[np.argmin(np.abs(nb), axis=1)]
        tan[bad] = np.cross(nb, axis)
        ln[bad] = np.linalg.norm(tan[bad], axis=1)
    tan = tan / np.maximum(ln, 1e-30)[:, None]
    sign = np.where(np.einsum("ij,ij->i", np.cross(nrm, tan), bsum) < 0.0, -1.0, 1.0)
    out[:, :3] = tan
    out[:, 3] = sign
    return out


# --- implicit shapes ---------------------------------------------------------------------


def _axis_frame(axis: str) -> np.ndarray:
    """Rows: the shape's local (u, v, axis) in object space."""
    if axis == "X":
        return np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
    if axis == "Y":
        return np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    return np.eye(3)


def _grid_indices(rows: int, cols: int) -> np.ndarray:
    """Quads of a (rows+1) x (cols+1) vertex grid (cols wraps not duplicated)."""
    r, c = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    a = r * (cols + 1) + c
    b = a + 1
    d = a + (cols + 1)
    e = d + 1
    t1 = np.stack([a, b, d], axis=-1).reshape(-1, 3)
    t2 = np.stack([b, e, d], axis=-1).reshape(-1, 3)
    return np.concatenate([t1, t2]).astype(np.uint32)


def _surface_of_revolution(profile_r: np.ndarray, profile_z: np.ndarray, prof_nr, prof_nz, frame):
    """Revolve a (r, z) profile about the axis. Returns points, normals, tris."""
    seg = IMPLICIT_SEGMENTS
    phi = np.linspace(0.0, 2.0 * math.pi, seg + 1)
    cp, sp = np.cos(phi), np.sin(phi)
    r = profile_r[:, None]
    shape = (len(profile_r), seg + 1)
    pts = np.stack([r * cp, r * sp, np.broadcast_to(profile_z[:, None], shape)], axis=-1)
    nr = prof_nr[:, None]
    nrm = np.stack([nr * cp, nr * sp, np.broadcast_to(prof_nz[:, None], shape)], axis=-1)
    pts = pts.reshape(-1, 3) @ frame
    nrm = nrm.reshape(-1, 3) @ frame
    tris = _grid_indices(len(profile_r) - 1, seg)
    return pts, nrm, tris


def _disk(radius: float, z: float, up: bool, frame):
    seg = IMPLICIT_SEGMENTS
    phi = np.linspace(0.0, 2.0 * math.pi, seg, endpoint=False)
    ring = np.stack([radius * np.cos(phi), radius * np.sin(phi), np.full(seg, z)], axis=1)
    pts = np.vstack([[0.0, 0.0, z], ring])
    i = np.arange(seg)
    tris = np.stack([np.zeros(seg, int), 1 + i, 1 + (i + 1) % seg], axis=1)
    if not up:
        tris = tris[:, [0, 2, 1]]
    n = np.tile([0.0, 0.0, 1.0 if up else -1.0], (len(pts), 1))
    return pts @ frame, n @ frame, tris.astype(np.uint32)


def _merge(parts):
    pts, nrm, tris, off = [], [], [], 0
    for p, n, t in parts:
        pts.append(p)
        nrm.append(n)
        tris.append(t + off)
        off += len(p)
    return np.vstack(pts), np.vstack(nrm), np.vstack(tris)


def _get(prim: Usd.Prim, name: str, default, time):
    a = prim.GetAttribute(name)
    v = a.Get(time) if a else None
    return default if v is None else v


def tessellate_implicit(prim: Usd.Prim, time: Usd.TimeCode) -> MeshGeometry | None:
    t = prim.GetTypeName()
    axis = str(_get(prim, "axis", "Z", time))
    frame = _axis_frame(axis)
    rings = IMPLICIT_RINGS
    if t == "Sphere":
        r = float(_get(prim, "radius", 1.0, time))
        th = np.linspace(0.0, math.pi, rings + 1)
        pr, pz = np.sin(th), -np.cos(th)
        pts, nrm, tris = _surface_of_revolution(r * pr, r * pz, pr, pz, np.eye(3))
    elif t == "Cube":
        s = float(_get(prim, "size", 2.0, time)) * 0.5
        pts, nrm, tris = _cube(s)
    elif t in ("Cylinder", "Cylinder_1", "Cone"):
        h = float(_get(prim, "height", 2.0, time)) * 0.5
        if t == "Cone":
            rb, rt = float(_get(prim, "radius", 1.0, time)), 0.0
        elif t == "Cylinder_1":
            rb = float(_get(prim, "radiusBottom", 1.0, time))
            rt = float(_get(prim, "radiusTop", 1.0, time))
        else:
            rb = rt = float(_get(prim, "radius", 1.0, time))
        slope = math.atan2(rb - rt, 2 * h)
        pr = np.array([rb, rt])
        pz = np.array([-h, h])
        nr = np.full(2, math.cos(slope))
        nz = np.full(2, math.sin(slope))
        parts = [_surface_of_revolution(pr, pz, nr, nz, frame)]
        if rb > 0:
            parts.append(_disk(rb, -h, False, frame))
        if rt > 0:
            parts.append(_disk(rt, h, True, frame))
        pts, nrm, tris = _merge(parts)
    elif t in ("Capsule", "Capsule_1"):
        r = float(_get(prim, "radius", 0.5, time))
        h = float(_get(prim, "height", 1.0, time)) * 0.5
        th = np.linspace(0.0, math.pi, rings + 1)
        pr, pz = np.sin(th), -np.cos(th)
        z = r * pz + np.where(th < math.pi / 2, -h, h)
        # duplicate the equator so the cylinder band exists
        half = rings // 2
        z = np.insert(z, half + 1, h)
        z[half] = -h
        prr = np.insert(pr, half + 1, 1.0)
        pzz = np.insert(pz, half + 1, 0.0)
        pts, nrm, tris = _surface_of_revolution(r * prr, z, prr, pzz, frame)
    elif t == "Plane":
        w = float(_get(prim, "width", 2.0, time)) * 0.5
        ln = float(_get(prim, "length", 2.0, time)) * 0.5
        pts = np.array([[-w, -ln, 0], [w, -ln, 0], [w, ln, 0], [-w, ln, 0]], dtype=np.float64)
        nrm = np.tile([0.0, 0.0, 1.0], (4, 1))
        tris = np.array([[0, 1, 2], [0, 2, 3]], dtype=np.uint32)
        pfr = {
            "X": np.array([[0, 1, 0], [0, 0, 1], [1, 0, 0]]),
            "Y": np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]]),
        }
        f = pfr.get(axis, np.eye(3)).astype(np.float64)
        pts, nrm = pts @ f, nrm @ f
    else:
        return None
    col, _ = _primvar(prim, "displayColor", time)
    display = np.asarray(col[0], dtype=np.float32) if col is not None and len(col) else None
    return MeshGeometry(
        np.asarray(pts, np.float32),
        _unit(np.asarray(nrm, np.float64)).astype(np.float32),
        np.asarray(tris, np.uint32),
        None,
        display,
        _double_sided(prim) or t == "Plane",
    )


def _cube(s: float):
    faces = []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            n = np.zeros(3)
            n[axis] = sign
            u = np.zeros(3)
            u[(axis + 1) % 3] = 1.0
            v = np.cross(n, u)
            c = n * s
            quad = np.array(
                [c - u * s - v * s, c + u * s - v * s, c + u * s + v * s, c - u * s + v * s]
            )
            faces.append(
                (quad, np.tile(n, (4, 1)), np.array([[0, 1, 2], [0, 2, 3]], dtype=np.uint32))
            )
    return _merge(faces)


#: Triangles of a tessellated implicit shape whose area is under this fraction of the
#: squared bounding-box diagonal are degenerate (a sphere's or cone's collapsed pole
#: row): the renderer draws them as nothing, and the lightmap UVs of an implicit shape
#: (``stb bake``) skip them -- the bake and the runtime's lightmap pass both use
#: :func:`implicit_lightmap_triangles`, so their triangle lists agree.
IMPLICIT_DEGENERATE_REL_AREA = 1e-10


def implicit_lightmap_triangles(g: MeshGeometry) -> np.ndarray:
    """(k, 3) vertex indices of the non-degenerate triangles of a tessellated implicit
    shape (object space), in the tessellation's order."""
    p = np.asarray(g.points, dtype=np.float64)
    tris = np.asarray(g.indices, dtype=np.int64).reshape(-1, 3)
    if len(p) == 0 or len(tris) == 0:
        return tris
    diag2 = float(np.sum((p.max(axis=0) - p.min(axis=0)) ** 2))
    t = p[tris]
    area = 0.5 * np.linalg.norm(np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), axis=1)
    return tris[area > IMPLICIT_DEGENERATE_REL_AREA * diag2]
