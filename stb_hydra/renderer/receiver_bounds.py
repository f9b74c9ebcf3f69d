"""Leaf boxes of a mesh's triangles: a finer receiver bound for narrow sphere lights.

``light_buffer.narrow_spheres`` proves a sphere light narrow against every lobe it can
reach from a lower bound on the distance (m) from the light to any receiver: the
nearest of a set of world AABBs that together hold every triangle. One AABB per mesh is
valid but loose (a mesh of scattered boxes spans them all); each mesh's triangles split
into up to ``limits.RECEIVER_LEAVES_PER_MESH`` groups, one AABB each, is as valid (every
triangle lies inside its leaf's box) and much tighter (issue 34 item 2)."""

from __future__ import annotations

import hashlib
from collections import OrderedDict

import numpy as np

from .. import limits

#: ``leaf_boxes`` results by the content of their mesh (blake2b of points, indices and
#: the leaf count), most recently used last: a stage opened again (a reload, the next
#: render of a script, another engine) does not split its meshes again.
_leaf_cache: OrderedDict[bytes, tuple[np.ndarray, np.ndarray]] = OrderedDict()


def leaf_boxes(
    points: np.ndarray, indices: np.ndarray, max_leaves: int = limits.RECEIVER_LEAVES_PER_MESH
) -> tuple[np.ndarray, np.ndarray]:
    """``split_leaf_boxes``, remembered for the last ``limits.RECEIVER_LEAF_CACHE_MESHES``
    meshes (by content; the arrays returned are read-only)."""
    pts = np.ascontiguousarray(points)
    idx = np.ascontiguousarray(indices)
    h = hashlib.blake2b(digest_size=16)
    h.update(f"{pts.dtype.str}{pts.shape}{idx.dtype.str}{idx.shape}".encode())
    h.update(pts.data)  # the buffers themselves, not copies
    h.update(idx.data)
    h.update(int(max_leaves).to_bytes(8, "little"))
    key = h.digest()
    hit = _leaf_cache.get(key)
    if hit is not None:
        _leaf_cache.move_to_end(key)
        return hit
    lo, hi = split_leaf_boxes(pts, idx, max_leaves)
    lo.setflags(write=False)
    hi.setflags(write=False)
    _leaf_cache[key] = (lo, hi)
    while len(_leaf_cache) > limits.RECEIVER_LEAF_CACHE_MESHES:
        _leaf_cache.popitem(last=False)
    return lo, hi


def split_leaf_boxes(
    points: np.ndarray, indices: np.ndarray, max_leaves: int = limits.RECEIVER_LEAVES_PER_MESH
) -> tuple[np.ndarray, np.ndarray]:
    """Object-space AABBs ((G, 3) lo, hi; G <= max_leaves) that hold every triangle of
    ``points`` (n, 3) indexed by ``indices`` ((m, 3) or flat): the triangles are split
    at the median of their box centres along the longest axis of those centres, level
    by level, while the leaf count stays within ``max_leaves``. No triangles: (0, 3)."""
    tri = np.asarray(indices, dtype=np.int64).reshape(-1, 3)
    if len(tri) == 0 or len(points) == 0:
        return np.zeros((0, 3)), np.zeros((0, 3))
    corners = np.asarray(points, dtype=np.float64)[tri]  # (m, 3, 3)
    tlo, thi = corners.min(axis=1), corners.max(axis=1)
    centre = 0.5 * (tlo + thi)
    # The groups as one permutation of the triangles cut into segments (``starts``),
    # split level by level for all segments at once: each segment sorted (stably) on
    # its centres' longest axis by one lexsort, then cut at its half.
    order = np.arange(len(tri))
    starts = np.zeros(1, dtype=np.int64)
    while 2 * len(starts) <= max_leaves:
        ends = np.append(starts[1:], len(order))
        sizes = ends - starts
        if not (sizes >= 2).any():
            break
        c = centre[order]
        extent = np.maximum.reduceat(c, starts, axis=0) - np.minimum.reduceat(c, starts, axis=0)
        axis = np.argmax(extent, axis=1)  # per segment (the first longest, as argmax)
        seg = np.repeat(np.arange(len(starts)), sizes)
        order = order[np.lexsort((c[np.arange(len(order)), axis[seg]], seg))]
        halves = (starts + sizes // 2)[sizes >= 2]
        starts = np.sort(np.concatenate([starts, halves]))
    lo = np.minimum.reduceat(tlo[order], starts, axis=0)
    hi = np.maximum.reduceat(thi[order], starts, axis=0)
    return lo, hi


def box_corners(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(G, 8, 4) the eight corners of each object-space box ``lo``, ``hi`` (G, 3), as
    homogeneous row vectors (w = 1): ``world_boxes``' input, made once per geometry."""
    sel = np.array(np.meshgrid([0, 1], [0, 1], [0, 1], indexing="ij")).reshape(3, -1).T
    corners = np.where(sel[None, :, :] == 0, lo[:, None, :], hi[:, None, :])  # (G, 8, 3)
    return np.concatenate([corners, np.ones((*corners.shape[:2], 1))], axis=2)


def world_boxes(
    lo: np.ndarray,
    hi: np.ndarray,
    transforms: np.ndarray,
    corners: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """World AABBs ((K x G, 3) lo, hi) of object-space boxes ``lo``, ``hi`` (G, 3) under
    each of ``transforms`` ((K, 4, 4), row vectors: p_world = [p, 1] @ M): the AABB of
    each box's eight transformed corners; boxes with a non-finite corner are dropped.
    ``corners``: ``box_corners(lo, hi)`` when the caller keeps it."""
    if len(lo) == 0 or len(transforms) == 0:
        return np.zeros((0, 3)), np.zeros((0, 3))
    if corners is None:
        corners = box_corners(lo, hi)
    wc = np.einsum("gci,kij->kgcj", corners, np.asarray(transforms, np.float64))[..., :3]
    wlo, whi = wc.min(axis=2).reshape(-1, 3), wc.max(axis=2).reshape(-1, 3)
    if np.isfinite(wlo).all() and np.isfinite(whi).all():
        return wlo, whi
    ok = np.all(np.isfinite(wlo), axis=1) & np.all(np.isfinite(whi), axis=1)
    return wlo[ok], whi[ok]
