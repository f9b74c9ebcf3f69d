"""Draw-batch culling for shadow captures (no GL; numpy, vectorised over batches/lights).

A batch (its world AABB) is drawn into a capture's face only if the box touches the
light's range sphere and the face's clip volume. The clip-volume test takes the six
planes of the face's view-projection (row-vector convention, ``clip = [p, 1] @ M``;
inside: ``-w <= x, y, z <= w``) and keeps a box unless it lies wholly outside one plane
(box centre distance + the box's extent along the plane normal). The test is
conservative: a box that straddles a frustum corner may be kept, but nothing that
could put a fragment into the face is dropped -- the rasteriser clips at the same
planes.
"""

from __future__ import annotations

import numpy as np

__all__ = ["boxes_in_sphere", "frustum_planes", "triangles_submitted", "visible_faces"]

#: Lights per chunk of the (lights x faces x planes x batches) test.
_CHUNK = 128


def frustum_planes(view_proj: np.ndarray) -> np.ndarray:
    """(..., 6, 4) planes (n.xyz, d), inside where ``n . p + d >= 0``, of row-vector
    view-projections (..., 4, 4)."""
    m = np.asarray(view_proj, dtype=np.float64)
    w = m[..., :, 3]
    cols = [m[..., :, i] for i in range(3)]
    return np.stack(
        [w + cols[0], w - cols[0], w + cols[1], w - cols[1], w + cols[2], w - cols[2]], axis=-2
    )


def boxes_in_sphere(
    center: np.ndarray, radius: np.ndarray, lo: np.ndarray, hi: np.ndarray
) -> np.ndarray:
    """(..., B) bool: AABBs (B, 3) touching spheres (centre (..., 3), radius (...))."""
    c = np.asarray(center, dtype=np.float64)[..., None, :]
    d = c - np.clip(c, lo, hi)
    r = np.asarray(radius, dtype=np.float64)[..., None]
    return (d * d).sum(-1) <= r * r


def visible_faces(planes: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(..., F, B) bool: AABB b may cover a fragment of face f, for planes (..., F, 6, 4)."""
    lo = np.asarray(lo, dtype=np.float64)
    hi = np.asarray(hi, dtype=np.float64)
    cen = 0.5 * (lo + hi)
    ext = 0.5 * (hi - lo)
    n = planes[..., :3]  # (..., F, 6, 3)
    dist = n @ cen.T + planes[..., 3:4] + np.abs(n) @ ext.T  # (..., F, 6, B)
    return np.all(dist >= 0.0, axis=-2)


def triangles_submitted(
    view_projs: np.ndarray,
    face_valid: np.ndarray,
    centers: np.ndarray,
    radii: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    triangles: np.ndarray,
    *,
    per_face: bool = False,
) -> np.ndarray:
    """(L,) triangles each capture submits after culling (every face counts its own);
    ``per_face``: (L, F), each face's own.

    ``view_projs`` (L, F, 4, 4) per light and face, ``face_valid`` (L, F) bool (a spot
    light has one face), ``centers`` (L, 3) / ``radii`` (L,) the range spheres, ``lo``/
    ``hi`` (B, 3) batch bounds, ``triangles`` (B,) per batch (instances included;
    zero for batches a light must not draw, e.g. dynamic ones into a static map).
    """
    n, n_faces = face_valid.shape
    out = np.zeros((n, n_faces), dtype=np.float64)
    if n == 0 or len(lo) == 0:
        return out if per_face else out.sum(axis=1)
    tri = np.asarray(triangles, dtype=np.float64)
    for s in range(0, n, _CHUNK):
        e = min(s + _CHUNK, n)
        vis = visible_faces(frustum_planes(view_projs[s:e]), lo, hi)  # (l, F, B)
        vis &= face_valid[s:e, :, None]
        vis &= boxes_in_sphere(centers[s:e], radii[s:e], lo, hi)[:, None, :]
        out[s:e] = vis @ tri
    return out if per_face else out.sum(axis=1)
