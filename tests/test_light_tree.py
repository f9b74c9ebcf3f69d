"""Light-tree construction (GL-free): node layout, skip counts, packing, the Listing 3
traversal against a brute-force interval list, the Listing 2 heuristic, and the
2.5D binning's conservativeness (every light that reaches a pixel is in its cell)."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from stb_hydra import limits
from stb_hydra.renderer.lighting.light_tree_build import (
    CellLists,
    ClusterGrid,
    ViewParams,
    auto_depth_range,
    bin_lights,
    brute_force,
    build_cells,
    build_single,
    cell_lists,
    choose_trees,
    dfs_order,
    heap_skip,
    next_pow2,
    pack_bits,
    traverse,
    unpack_bits,
)

SETTINGS = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def intervals(rng: np.random.Generator, n: int, spread: float = 50.0):
    c = rng.uniform(0.5, spread, n)
    r = rng.exponential(1.0, n) * rng.choice([0.05, 0.5, 5.0], n)
    return c - r, c + r


def hit_lights(trees, cell: int, lo_sorted, hi_sorted, q_lo, q_hi=None):
    """Positions (in the cell's depth-sorted list) the walk evaluates, filtered by each
    light's own interval, plus the walk's leaf ranges and reads."""
    nodes = trees.nodes_of(cell)
    ranges, reads = traverse(nodes, q_lo, q_hi)
    q_hi = q_lo if q_hi is None else q_hi
    out = []
    for _pos, first, count in ranges:
        for k in range(first, first + count):
            if lo_sorted[k] <= q_hi and hi_sorted[k] >= q_lo:
                out.append(k)
    return sorted(out), ranges, reads


# --- layout ------------------------------------------------------------------------------


@pytest.mark.parametrize("L", [1, 2, 4, 8, 16, 64])
def test_dfs_table_is_preorder_with_subtree_skips(L):
    perm = dfs_order(L)
    skip = heap_skip(L)
    assert sorted(perm.tolist()) == list(range(2 * L - 1))
    assert perm[0] == 0 and skip[0] == 2 * L - 1
    pos = {int(h): p for p, h in enumerate(perm)}
    for p, h in enumerate(perm):
        if h < L - 1:  # inner: left child next, right child after the left subtree
            assert pos[2 * h + 1] == p + 1
            assert pos[2 * h + 2] == p + 1 + skip[2 * h + 1]
        else:
            assert skip[h] == 1
    # leaves appear left to right
    leaves = [int(h) for h in perm if h >= L - 1]
    assert leaves == list(range(L - 1, 2 * L - 1))


def test_pack_bits_round_trip_and_limits():
    leaf = np.array([0, 1, 1, 0])
    count = np.array([0, 1, 65535, 70000])  # inner counts saturate
    skip = np.array([1, 1, 32767, 5])
    bits = pack_bits(leaf, count, skip)
    assert bits.dtype == np.uint32
    l2, c2, s2 = unpack_bits(bits)
    assert l2.tolist() == leaf.tolist()
    assert c2.tolist() == [0, 1, 65535, 65535]
    assert s2.tolist() == skip.tolist()
    with pytest.raises(ValueError):
        pack_bits(np.array([0]), np.array([1]), np.array([32768]))
    assert limits.LIGHTTREE_MAX_TREE_NODES == 2 * limits.LIGHTTREE_MAX_LEAVES - 1


@SETTINGS
@given(n=st.integers(1, 300), leaf=st.integers(1, 9), seed=st.integers(0, 2**31 - 1))
def test_node_layout_and_skip_counts(n, leaf, seed):
    rng = np.random.default_rng(seed)
    lo, hi = intervals(rng, n)
    t = build_single(lo, hi, leaf, tree=True)
    nodes = t.nodes_of(0)
    order = t.lights.astype(np.int64)
    assert sorted(order.tolist()) == list(range(n))
    centre = 0.5 * (lo + hi)[order]
    k = len(nodes)
    L = (k + 1) // 2
    assert k == 2 * L - 1 and L & (L - 1) == 0
    if n > leaf:
        assert L == next_pow2(math.ceil(n / leaf))
    mn, mx, first = nodes[:, 0], nodes[:, 1], nodes[:, 2].astype(np.int64)
    isleaf, count, skip = unpack_bits(nodes[:, 3].astype(np.uint32))
    assert skip[0] == k
    lo_s, hi_s = lo[order], hi[order]
    # Leaves in depth order (each leaf's lights nearer than the next leaf's, by centre);
    # inside a leaf the lights ascend in light index (the shader's loops by light model).
    leaves = [(int(first[p]), int(count[p])) for p in range(k) if isleaf[p] and count[p]]
    leaves.sort()
    for (a, c), (b, d) in itertools.pairwise(leaves):
        assert centre[a : a + c].max() <= centre[b : b + d].min()
    for a, c in leaves:
        assert np.all(np.diff(order[a : a + c]) > 0)

    def check(p: int) -> int:
        """Validate the subtree at DFS position p; return its size."""
        if isleaf[p]:
            assert skip[p] == 1
            a, c = first[p], count[p]
            if c:
                assert mn[p] <= lo_s[a : a + c].min() and mx[p] >= hi_s[a : a + c].max()
                assert np.isclose(mn[p], lo_s[a : a + c].min(), rtol=1e-6, atol=1e-6)
                assert np.isclose(mx[p], hi_s[a : a + c].max(), rtol=1e-6, atol=1e-6)
            else:
                assert mn[p] > mx[p]  # empty leaf never hit
            return 1
        left = p + 1
        sl = check(left)
        right = left + sl
        sr = check(right)
        assert sl == sr  # full binary tree
        assert skip[p] == 1 + sl + sr
        assert first[p] == first[left] and first[right] == first[left] + count[left]
        assert count[p] == min(count[left] + count[right], 0xFFFF)
        assert mn[p] == min(mn[left], mn[right]) and mx[p] == max(mx[left], mx[right])
        return skip[p]

    assert check(0) == k
    # leaves, in memory order, tile [0, n) contiguously; sizes differ by at most 1
    leaves = np.nonzero(isleaf)[0]
    assert len(leaves) == L
    assert first[leaves[0]] == 0 and first[leaves[-1]] + count[leaves[-1]] == n
    assert np.all(first[leaves[1:]] == first[leaves[:-1]] + count[leaves[:-1]])
    if n >= L:
        assert count[leaves].max() - count[leaves].min() <= 1
        assert count[leaves].max() <= max(leaf, math.ceil(n / L))


@SETTINGS
@given(
    n=st.integers(1, 250),
    leaf=st.integers(1, 8),
    seed=st.integers(0, 2**31 - 1),
    queries=st.lists(st.tuples(st.floats(-5, 60), st.floats(0, 10)), min_size=1, max_size=12),
)
def test_traversal_visits_exactly_the_overlapping_lights(n, leaf, seed, queries):
    rng = np.random.default_rng(seed)
    lo, hi = intervals(rng, n)
    t = build_single(lo, hi, leaf, tree=True)
    order = t.lights.astype(np.int64)
    lo_s, hi_s = lo[order], hi[order]
    nodes = t.nodes_of(0)
    # add queries exactly at interval end points (closed intervals)
    qs = [(a, a + w) for a, w in queries] + [(float(lo[0]), None), (float(hi[-1]), None)]
    for q_lo, q_hi in qs:
        for qh in [q_hi] if q_hi is not None else [None]:
            got, ranges, reads = hit_lights(t, 0, lo_s, hi_s, q_lo, qh)
            want = sorted(brute_force(lo_s, hi_s, q_lo, qh).tolist())
            assert got == want
            assert reads <= len(nodes)
            # every visited leaf overlaps the query; every overlapping light is in one
            qh2 = q_lo if qh is None else qh
            in_leaves = {k for _p, f, c in ranges for k in range(f, f + c)}
            assert set(want) <= in_leaves
            positions = [p for p, _f, _c in ranges]
            assert positions == sorted(set(positions))  # forward only, each leaf once
            for p, _f, _c in ranges:
                assert unpack_bits(np.uint32(nodes[p, 3]))[0] == 1
                assert nodes[p, 0] <= qh2 and nodes[p, 1] >= q_lo


def test_traversal_only_moves_forward_and_skips_subtrees():
    """Two far-apart groups: a query in one group never reads the other's leaves."""
    lo = np.r_[np.linspace(1, 2, 16), np.linspace(50, 51, 16)]
    hi = lo + 0.1
    t = build_single(lo, hi, leaf=2)
    nodes = t.nodes_of(0)
    _ranges, reads = traverse(nodes, 1.5)
    assert len(nodes) == 31
    assert reads < len(nodes) // 2 + 3  # the right half was skipped in one step


@SETTINGS
@given(cells=st.integers(1, 12), leaf=st.integers(1, 6), seed=st.integers(0, 2**31 - 1))
def test_multi_cell_build_matches_brute_force_per_cell(cells, leaf, seed):
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 120))
    lo, hi = intervals(rng, n)
    order = np.argsort(0.5 * (lo + hi), kind="stable")
    # random (light, cell) pairs, light-major in depth order
    pair_cell, pair_light = [], []
    for li in order:
        for c in np.nonzero(rng.random(cells) < 0.4)[0]:
            pair_cell.append(c)
            pair_light.append(li)
    lists = cell_lists(cells, np.array(pair_cell, np.int64), np.array(pair_light, np.int64))
    e_lo, e_hi = lo[lists.light], hi[lists.light]
    is_tree = rng.random(cells) < 0.6
    t = build_cells(lists, e_lo, e_hi, is_tree, leaf)
    assert t.list_cells + t.tree_cells == int((lists.count > 0).sum())
    for c in range(cells):
        if lists.count[c] == 0:
            assert t.cell_nodes[c] == 0
            continue
        a, k = int(lists.offset[c]), int(lists.count[c])
        members = lists.light[a : a + k]
        for q in rng.uniform(-1, 55, 6):
            got, _r, _n = hit_lights(t, c, e_lo, e_hi, float(q))
            want = sorted((a + brute_force(lo[members], hi[members], float(q))).tolist())
            assert got == want
        if not (is_tree[c] and k > 0):
            assert (
                t.cell_nodes[c] == 1 and unpack_bits(t.nodes_of(c)[0, 3].astype(np.uint32))[1] == k
            )


def test_cap_keeps_first_lights_and_counts_drops():
    cell = np.array([0, 1, 0, 0, 1, 0])
    light = np.array([5, 6, 7, 8, 9, 10])
    L = cell_lists(2, cell, light, cap=2)
    assert L.total.tolist() == [4, 2] and L.count.tolist() == [2, 2]
    assert L.light.tolist() == [5, 7, 6, 9] and L.dropped == 2


# --- Listing 2 -----------------------------------------------------------------------------


def test_heuristic_lists_for_covering_lights_trees_for_small_ones():
    # cell 0: 8 lights covering the whole cell depth [10, 20]; cell 1: 8 tiny lights
    lo = np.r_[np.full(8, 0.0), np.linspace(10, 19, 8)]
    hi = np.r_[np.full(8, 30.0), np.linspace(10, 19, 8) + 0.2]
    lists = CellLists(np.array([0, 8]), np.array([8, 8]), np.arange(16), np.array([8, 8]))
    coe = np.repeat([0, 1], 8)
    cl, ch = np.array([10.0, 10.0]), np.array([20.0, 20.0])
    hyb = choose_trees(lists, coe, lo, hi, cl, ch, leaf=2, mode="hybrid")
    assert hyb.tolist() == [False, True]
    assert choose_trees(lists, coe, lo, hi, cl, ch, 2, "tree").tolist() == [True, True]
    assert choose_trees(lists, coe, lo, hi, cl, ch, 2, "list").tolist() == [False, False]
    # a cell with no more lights than a leaf stays a list
    assert choose_trees(lists, coe, lo, hi, cl, ch, 8, "hybrid").tolist() == [False, False]


def test_oversized_list_cell_becomes_a_tree():
    n = limits.LIGHTTREE_MAX_NODE_LIGHTS + 10
    lists = CellLists(np.array([0]), np.array([n]), np.arange(n), np.array([n]))
    lo = np.zeros(n)
    hi = np.ones(n)
    t = choose_trees(lists, np.zeros(n, np.int64), lo, hi, np.zeros(1), np.ones(1), 4, "list")
    assert t.tolist() == [True]


# --- binning conservativeness -------------------------------------------------------------


def _view(yaw: float, pitch: float, eye) -> np.ndarray:
    """Row-vector world -> view matrix of a camera at ``eye`` (degrees)."""
    cy, sy = math.cos(math.radians(yaw)), math.sin(math.radians(yaw))
    cp, sp = math.cos(math.radians(pitch)), math.sin(math.radians(pitch))
    ry = np.array([[cy, 0, -sy], [0, 1, 0], [sy, 0, cy]])
    rx = np.array([[1, 0, 0], [0, cp, sp], [0, -sp, cp]])
    cam = np.eye(4)
    cam[:3, :3] = rx @ ry  # rows: camera axes in world
    cam[3, :3] = eye
    return np.linalg.inv(cam)


@settings(max_examples=25, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    ortho=st.booleans(),
    slices=st.sampled_from([0, 3, 16]),
    tile=st.sampled_from([16, 32, 64]),
)
def test_binning_never_misses_a_light_that_reaches_a_pixel(seed, ortho, slices, tile):
    rng = np.random.default_rng(seed)
    W, H = 160, 90
    view = _view(rng.uniform(-30, 30), rng.uniform(-30, 10), rng.uniform(-2, 2, 3))
    tan = (0.7, 0.7 * H / W) if not ortho else (8.0, 8.0 * H / W)
    vp = ViewParams(W, H, view, tan, tuple(rng.uniform(-0.05, 0.05, 2)), 0.1, 100.0, ortho)
    ns, far = auto_depth_range(vp, (np.array([-30.0, -30, -60]), np.array([30.0, 30, 5])))
    grid = ClusterGrid(W, H, tile, slices, ns, far)
    # pixels with random depths, reconstructed as the shader does
    m = 4000
    px = np.c_[rng.integers(0, W, m), rng.integers(0, H, m)]
    depth = rng.uniform(0.1, 60.0, m)
    ndc = (px + 0.5) / [W, H] * 2.0 - 1.0
    a = ndc * tan + vp.offset
    xy = a if ortho else a * depth[:, None]
    pv = np.c_[xy, -depth, np.ones(m)]
    pw = (pv @ np.linalg.inv(view))[:, :3]
    # lights near those points, small and large
    n = 200
    lp = pw[rng.integers(0, m, n)] + rng.normal(0, 1.5, (n, 3))
    lr = rng.exponential(1.0, n) * rng.choice([0.3, 1.0, 6.0], n)
    bins = bin_lights(grid, vp, lp, lr)
    lists = cell_lists(grid.count, bins.cell, bins.light)
    tx, ty = px[:, 0] // tile, px[:, 1] // tile
    cell = grid.cell_index(tx, ty, grid.depth_cell_of(depth))
    d2 = ((pw[:, None, :] - lp[None, :, :]) ** 2).sum(-1)
    reach = d2 < lr[None, :] ** 2
    for i in np.nonzero(reach.any(1))[0]:
        c = int(cell[i])
        a0, k = int(lists.offset[c]), int(lists.count[c])
        have = set(lists.light[a0 : a0 + k].tolist())
        need = set(np.nonzero(reach[i])[0].tolist())
        assert need <= have, (i, c, need - have)


def test_grid_slices_and_auto_range():
    g = ClusterGrid(745, 360, 64, 16, 2.0, 200.0)
    assert g.tiles == (12, 6) and g.depth_cells == 17 and g.count == 12 * 6 * 17
    b = g.boundaries()
    assert b[0] == 0 and b[1] == 2.0 and np.isinf(b[-1])
    assert np.isclose(b[-2], 200.0 * (200 / 2.0) ** (-1 / 16))
    d = np.array([0.5, 1.99, 2.0, 2.01, 199.0, 200.0, 1e4])
    s = g.depth_cell_of(d)
    assert s.tolist()[:3] == [0, 0, 1] and s[-1] == 16 and s[-2] == 16
    # every depth falls inside its (nominal) cell
    mid = np.exp(np.linspace(np.log(2.0), np.log(199.0), 200))
    cells = g.depth_cell_of(mid)
    assert np.all(b[cells] <= mid * (1 + 1e-6)) and np.all(mid <= b[cells + 1] * (1 + 1e-6))
    with pytest.raises(ValueError):
        ClusterGrid(10, 10, 8, 4, 5.0, 2.0)
