"""Receiver leaf boxes for the narrow-sphere bound (issue 34 item 2,
renderer/receiver_bounds.py): every point of every triangle lies in a leaf box, so the
distance to the nearest leaf box is a lower bound on the distance to any receiver; and
on scattered geometry it is much tighter than the mesh's AABB."""

from __future__ import annotations

import numpy as np

from stb_hydra.renderer.receiver_bounds import leaf_boxes, world_boxes


def _boxes_mesh(centres: np.ndarray, half: float = 0.5) -> tuple[np.ndarray, np.ndarray]:
    """Points and (m, 3) triangles of axis-aligned cubes (12 triangles each)."""
    cube = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1], indexing="ij")).reshape(3, -1).T
    faces = [(0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1)]
    faces += [(2, 3, 7), (2, 7, 6), (0, 2, 6), (0, 6, 4), (1, 5, 7), (1, 7, 3)]
    pts = np.concatenate([c + half * cube for c in centres])
    tri = np.concatenate([np.array(faces) + 8 * i for i in range(len(centres))])
    return pts, tri


def _inside_some(p: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    return np.any(
        np.all((p[:, None] >= lo[None] - 1e-12) & (p[:, None] <= hi[None] + 1e-12), axis=2), axis=1
    )


def test_leaf_boxes_hold_every_triangle_and_are_tighter_than_the_mesh_box():
    rng = np.random.default_rng(3)
    centres = rng.uniform(-30, 30, (100, 3)) * np.array([1, 0, 1]) + np.array([0, 1, 0])
    pts, tri = _boxes_mesh(centres)
    lo, hi = leaf_boxes(pts, tri, max_leaves=64)
    assert 32 < len(lo) <= 64
    # random points on every triangle (barycentric) lie in some leaf box
    u = rng.uniform(size=(len(tri), 8, 2))
    u = np.where(u.sum(axis=2, keepdims=True) > 1, 1 - u, u)
    a, b, c = (pts[tri[:, k]][:, None] for k in range(3))
    p = (a + u[..., :1] * (b - a) + u[..., 1:] * (c - a)).reshape(-1, 3)
    assert _inside_some(p, lo, hi).all()
    # a point 1 m above the ground, between the boxes: the mesh AABB holds it (distance
    # 0), the leaves keep it at least as far as the nearest cube really is
    q = np.array([[0.0, 1.0, 0.0]])
    gap = np.maximum(np.maximum(lo - q, 0), q - hi)
    d_leaf = np.sqrt((gap * gap).sum(axis=1)).min()
    d_true = np.sqrt((np.maximum(np.abs(centres - q) - 0.5, 0) ** 2).sum(axis=1)).min()
    assert d_leaf <= d_true + 1e-12
    assert d_leaf > 0.2 * d_true > 0


def test_leaf_boxes_of_tiny_and_empty_meshes():
    pts, tri = _boxes_mesh(np.zeros((1, 3)))
    lo, hi = leaf_boxes(pts, tri[:1], max_leaves=64)  # one triangle: one box, its own
    assert len(lo) == 1
    np.testing.assert_allclose(lo[0], pts[tri[0]].min(axis=0))
    np.testing.assert_allclose(hi[0], pts[tri[0]].max(axis=0))
    lo, hi = leaf_boxes(pts, np.zeros((0, 3), np.int64))
    assert lo.shape == (0, 3) and hi.shape == (0, 3)


def test_world_boxes_hold_the_transformed_boxes():
    rng = np.random.default_rng(5)
    lo = rng.uniform(-1, 0, (4, 3))
    hi = lo + rng.uniform(0.1, 1, (4, 3))
    xf = np.repeat(np.eye(4)[None], 3, axis=0)
    for k in range(3):  # rotation about y, scale, translation (row vectors: p @ M)
        t = rng.uniform(0, 2 * np.pi)
        r = np.array([[np.cos(t), 0, -np.sin(t)], [0, 1, 0], [np.sin(t), 0, np.cos(t)]])
        xf[k, :3, :3] = r * rng.uniform(0.5, 2)
        xf[k, 3, :3] = rng.uniform(-5, 5, 3)
    wlo, whi = world_boxes(lo, hi, xf)
    assert wlo.shape == (12, 3)
    s = rng.uniform(size=(4, 200, 3))
    p = lo[:, None] + s * (hi - lo)[:, None]  # points in each object box
    for k in range(3):
        w = np.c_[p.reshape(-1, 3), np.ones(800)] @ xf[k]
        assert _inside_some(w[:, :3], wlo[4 * k : 4 * k + 4], whi[4 * k : 4 * k + 4]).all()


def test_leaf_boxes_are_remembered_by_content():
    """The same mesh again (another engine, a reload) gets the remembered boxes; a mesh
    whose points moved gets its own, split afresh; remembered arrays are read-only."""
    from stb_hydra.renderer.receiver_bounds import split_leaf_boxes

    rng = np.random.default_rng(5)
    pts, tri = _boxes_mesh(rng.uniform(-10.0, 10.0, (40, 3)))
    a = leaf_boxes(pts, tri, max_leaves=16)
    b = leaf_boxes(pts.copy(), tri.copy(), max_leaves=16)
    assert a[0] is b[0] and not a[0].flags.writeable
    moved = pts + np.array([0.0, 3.0, 0.0])
    c = leaf_boxes(moved, tri, max_leaves=16)
    fresh = split_leaf_boxes(moved, tri, max_leaves=16)
    assert np.array_equal(c[0], fresh[0]) and np.array_equal(c[1], fresh[1])
    assert np.array_equal(c[0], a[0] + [0.0, 3.0, 0.0])
    assert leaf_boxes(pts, tri, max_leaves=8)[0].shape[0] <= 8  # the leaf count is in the key
