"""CPU side of the 2.5D-grid baselines, GL-free (numpy only), per frame:

1. **Grid** (:class:`ClusterGrid`): screen tiles x depth cells. Depth: a near slice
   ``[0, near_split)`` then ``slices`` exponential slices up to ``far`` (Persson 2013;
   pixels deeper than ``far`` clamp into the last one). ``slices = 0``: one depth cell
   per tile (2D tiles, the tree-only mode of O'Donnell & Chajdas 2017).
2. **Binning** (:func:`bin_lights`): every (light, cell) pair whose cell can contain a
   point within the light's influence sphere, vectorised: per light its depth-cell
   range, per (light, depth cell) the screen rectangle of the sphere clipped to the
   cell's depth slab (exact tangent bounds of the slab cross-section box), then every
   tile of that rectangle. Conservative with margins (``limits.CULL_*``): with no cap
   the methods built on it equal the reference.
3. **CSR lists** (:func:`cell_lists`): pairs sorted by cell (stable: the caller's light
   order survives inside a cell -- FoV index order for ``clustered`` so sums run in
   the reference's order, view-depth order for ``lighttree``), optional cap.
4. **Light trees** (:func:`build_cells`): per cell the Listing 2 heuristic (mean light
   depth extent clipped to the cell < the cell's depth radius -> tree, else list),
   trees as full binary interval trees over the depth-sorted lights (leaves rounded
   up to a power of two, lights spread evenly over them), built bottom-up as a heap
   and permuted to depth-first order with per-size tables, packed as Listing 1
   (min depth, max depth, first light, leaf:1 | count:16 | skip:15). A list is a
   one-node tree whose root is a leaf.
5. :func:`traverse` -- the stack-less walk of Listing 3 (the GPU's, in Python) and
   :func:`brute_force` for the tests.

Depths are linear view depths (m, > 0, the G-buffer's). Pixel coordinates are GL's
(origin bottom-left), as ``gl_FragCoord`` and the min/max depth pyramid.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from ... import limits

if TYPE_CHECKING:
    from ..camera import ViewSetup

#: Node bit fields (Listing 1): bit 0 leaf, bits 1-16 light count, bits 17-31 skip count.
LEAF_BIT = 1
COUNT_SHIFT = 1
COUNT_MASK = 0xFFFF
SKIP_SHIFT = 17
SKIP_MASK = 0x7FFF

HEURISTIC_MODES = ("hybrid", "tree", "list")


# --- view and grid -----------------------------------------------------------------------


@dataclass(frozen=True)
class ViewParams:
    """What binning needs of the camera (a ``render.camera.ViewSetup`` subset)."""

    width: int
    height: int
    view: np.ndarray  # world -> view, row-vector 4x4
    tan_half: tuple[float, float]
    offset: tuple[float, float]
    near: float
    far: float
    orthographic: bool = False

    @classmethod
    def from_setup(cls, v: ViewSetup) -> ViewParams:
        return cls(
            int(v.width),
            int(v.height),
            np.asarray(v.view, dtype=np.float64),
            (float(v.tan_half[0]), float(v.tan_half[1])),
            (float(v.offset[0]), float(v.offset[1])),
            float(v.near),
            float(v.far),
            bool(v.orthographic),
        )

    @property
    def radius_scale(self) -> float:
        """World -> view length scale (largest singular value; 1 for rigid cameras)."""
        return float(np.linalg.norm(self.view[:3, :3], 2))

    def to_view(self, pos: np.ndarray) -> np.ndarray:
        p = np.asarray(pos, dtype=np.float64).reshape(-1, 3)
        return p @ self.view[:3, :3] + self.view[3, :3]


@dataclass(frozen=True)
class ClusterGrid:
    width: int
    height: int
    tile: int = limits.CLUSTER_TILE_PX_DEFAULT
    slices: int = limits.CLUSTER_SLICES_DEFAULT
    near_split: float = 1.0
    far: float = 100.0

    def __post_init__(self) -> None:
        if self.tile < 1 or self.width < 1 or self.height < 1:
            raise ValueError("grid needs a positive size and tile")
        if not 0 <= self.slices <= limits.CLUSTER_SLICES_MAX:
            raise ValueError(f"slices must be 0..{limits.CLUSTER_SLICES_MAX}, got {self.slices}")
        if self.slices and not 0.0 < self.near_split < self.far:
            raise ValueError(
                f"need 0 < near_split < far, got near_split={self.near_split}, far={self.far}"
            )

    @property
    def tiles(self) -> tuple[int, int]:
        return (math.ceil(self.width / self.tile), math.ceil(self.height / self.tile))

    @property
    def depth_cells(self) -> int:
        return self.slices + 1 if self.slices else 1

    @property
    def count(self) -> int:
        tx, ty = self.tiles
        return tx * ty * self.depth_cells

    @property
    def dims(self) -> tuple[int, int, int]:
        return (*self.tiles, self.depth_cells)

    def boundaries(self) -> np.ndarray:
        """(depth_cells + 1,) nominal depth boundaries; the last one is +inf."""
        if not self.slices:
            return np.array([0.0, np.inf])
        j = np.arange(self.slices + 1, dtype=np.float64)
        expo = self.near_split * (self.far / self.near_split) ** (j / self.slices)
        b = np.concatenate([[0.0], expo])
        b[-1] = np.inf
        return b

    def nominal_bounds(self, near: float) -> tuple[np.ndarray, np.ndarray]:
        """Finite depth interval of each depth cell for the Listing 2 heuristic: the
        near slice from the camera near plane, the last slice up to ``far``."""
        b = self.boundaries()
        lo, hi = b[:-1].copy(), b[1:].copy()
        lo[0] = max(lo[0], near)
        hi[-1] = max(self.far, lo[-1]) if self.slices else max(self.far, near)
        return lo, np.maximum(hi, lo)

    def shader_params(self) -> tuple[float, float, float, float]:
        """``u_slices``: near_split, far, slices, slices / ln(far / near_split)."""
        if not self.slices:
            return (1.0, 1.0, 0.0, 0.0)
        return (
            float(self.near_split),
            float(self.far),
            float(self.slices),
            float(self.slices / math.log(self.far / self.near_split)),
        )

    def depth_cell_of(self, depth: np.ndarray) -> np.ndarray:
        """The GPU's pixel -> depth cell mapping (float32 like the shader)."""
        d = np.asarray(depth, dtype=np.float32)
        if not self.slices:
            return np.zeros(d.shape, dtype=np.int64)
        ns, _far, s, k = (np.float32(x) for x in self.shader_params())
        with np.errstate(divide="ignore", invalid="ignore"):
            j = np.floor(np.log(d / ns) * k)
        j = np.clip(np.nan_to_num(j, nan=0.0, neginf=0.0), 0, int(s) - 1).astype(np.int64)
        return np.where(d < ns, 0, 1 + j)

    def cell_index(self, tx: npt.ArrayLike, ty: npt.ArrayLike, s: npt.ArrayLike) -> np.ndarray:
        ntx, nty = self.tiles
        return (np.asarray(s) * nty + np.asarray(ty)) * ntx + np.asarray(tx)


def auto_depth_range(
    vp: ViewParams, bounds: tuple[np.ndarray, np.ndarray] | None
) -> tuple[float, float]:
    """(near_split, far) when not given: far = the deepest corner of the scene's
    geometry bounds (clamped to the camera's clip range), near_split =
    ``CLUSTER_NEAR_FRACTION`` x far (at least twice the near plane)."""
    near, far = max(vp.near, 1e-6), max(vp.far, vp.near * 4.0, 1e-3)
    f = far
    if bounds is not None:
        lo, hi = (np.asarray(b, dtype=np.float64) for b in bounds)
        if np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)) and np.all(hi >= lo):
            corners = np.array(np.meshgrid(*zip(lo, hi), indexing="ij")).reshape(3, -1).T
            d = -vp.to_view(corners)[:, 2]
            if np.isfinite(d).all() and d.max() > near:
                f = float(min(far, d.max() * (1.0 + 1e-3)))
    f = max(f, near * 4.0)
    ns = min(max(limits.CLUSTER_NEAR_FRACTION * f, 2.0 * near), 0.5 * f)
    return float(ns), float(f)


# --- binning -------------------------------------------------------------------------------


@dataclass
class LightBins:
    """(light, cell) pairs plus the per-light view-space data binning derived."""

    cell: np.ndarray  # (P,) int64 cell index
    light: np.ndarray  # (P,) int64 index into the input light arrays
    depth: np.ndarray  # (n,) view depth of each light centre (m)
    radius: np.ndarray  # (n,) widened view-space influence radius (m)

    @property
    def depth_lo(self) -> np.ndarray:
        return self.depth - self.radius

    @property
    def depth_hi(self) -> np.ndarray:
        return self.depth + self.radius


def widened_radius(radius: np.ndarray, depth: np.ndarray, scale: float = 1.0) -> np.ndarray:
    r = np.asarray(radius, dtype=np.float64) * scale
    return r * (1.0 + limits.CULL_RADIUS_REL_MARGIN) + limits.CULL_DEPTH_REL_MARGIN * (
        np.abs(depth) + r
    )


def _axis_tiles(
    a_lo: np.ndarray,
    a_hi: np.ndarray,
    off: float,
    tan: float,
    size: int,
    tile: int,
    ntiles: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Screen-axis slope interval -> inclusive tile range (and a non-empty mask)."""
    pix_lo = ((a_lo - off) / tan + 1.0) * 0.5 * size
    pix_hi = ((a_hi - off) / tan + 1.0) * 0.5 * size
    # pixel p is shaded at p + 0.5; pad a pixel each side against rounding.
    p0 = np.floor(np.clip(pix_lo, -4.0, size + 4.0) - 1.0)
    p1 = np.floor(np.clip(pix_hi, -4.0, size + 4.0))
    ok = (p1 >= 0) & (p0 <= size - 1)
    t0 = np.clip(p0 // tile, 0, ntiles - 1).astype(np.int64)
    t1 = np.clip(p1 // tile, 0, ntiles - 1).astype(np.int64)
    return t0, t1, ok


def _expand(counts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For counts c_i: (owner index per output row, local 0..c_i-1 per row)."""
    counts = np.asarray(counts, dtype=np.int64)
    owner = np.repeat(np.arange(len(counts), dtype=np.int64), counts)
    start = np.cumsum(counts) - counts
    local = np.arange(len(owner), dtype=np.int64) - start[owner]
    return owner, local


def bin_lights(
    grid: ClusterGrid, vp: ViewParams, position: np.ndarray, radius: np.ndarray
) -> LightBins:
    """Every (light, cell) pair where the light's influence sphere may reach a pixel
    of the cell (conservative). Pairs come light-major in input order."""
    pos = np.asarray(position, dtype=np.float64).reshape(-1, 3)
    n = len(pos)
    c = vp.to_view(pos)
    xc, yc, dc = c[:, 0], c[:, 1], -c[:, 2]
    r = widened_radius(radius, dc, vp.radius_scale)
    empty = np.zeros(0, dtype=np.int64)
    if n == 0:
        return LightBins(empty, empty, dc, r)
    m = 1.0 + limits.CULL_RADIUS_REL_MARGIN
    b = grid.boundaries()
    lo_s, hi_s = b[:-1] / m, b[1:] * m  # widened cell depth bounds
    near_eff = vp.near / m
    dlo = np.maximum(dc - r, near_eff)
    dhi = dc + r
    s0 = np.searchsorted(hi_s, dlo, side="left")
    s1 = np.searchsorted(lo_s, dhi, side="right") - 1
    ns = np.where(dhi >= near_eff, np.maximum(s1 - s0 + 1, 0), 0)

    li, k = _expand(ns)
    s = s0[li] + k
    x, y, d, rr = xc[li], yc[li], dc[li], r[li]
    cl, ch = lo_s[s], hi_s[s]
    d0 = np.maximum(dlo[li], cl)
    d1 = np.minimum(dhi[li], ch)
    delta = np.maximum(np.maximum(cl - d, d - ch), 0.0)
    rho = np.sqrt(np.maximum(rr * rr - delta * delta, 0.0))
    (tx, ty), (ox, oy) = vp.tan_half, vp.offset
    if vp.orthographic:
        ax = (x - rho, x + rho)
        ay = (y - rho, y + rho)
    else:
        inv0, inv1 = 1.0 / d0, 1.0 / np.maximum(d1, d0)
        ax = (
            np.minimum((x - rho) * inv0, (x - rho) * inv1),
            np.maximum((x + rho) * inv0, (x + rho) * inv1),
        )
        ay = (
            np.minimum((y - rho) * inv0, (y - rho) * inv1),
            np.maximum((y + rho) * inv0, (y + rho) * inv1),
        )
    ntx, nty = grid.tiles
    tx0, tx1, okx = _axis_tiles(*ax, ox, tx, grid.width, grid.tile, ntx)
    ty0, ty1, oky = _axis_tiles(*ay, oy, ty, grid.height, grid.tile, nty)
    wx = tx1 - tx0 + 1
    cnt = np.where(okx & oky, wx * (ty1 - ty0 + 1), 0)

    own, q = _expand(cnt)
    cell = grid.cell_index(tx0[own] + q % wx[own], ty0[own] + q // wx[own], s[own])
    return LightBins(cell.astype(np.int64), li[own], dc, r)


# --- per-cell lists -------------------------------------------------------------------------


@dataclass
class CellLists:
    """CSR light lists: cell c holds ``light[offset[c] : offset[c] + count[c]]``."""

    offset: np.ndarray  # (C,) int64
    count: np.ndarray  # (C,) int64 (after the cap)
    light: np.ndarray  # (E,) int64 light indices (the caller's numbering)
    total: np.ndarray  # (C,) int64 before the cap
    dropped: int = 0

    @property
    def entries(self) -> int:
        return len(self.light)


def cell_lists(
    cells: int, cell: np.ndarray, light: np.ndarray, cap: int | None = None
) -> CellLists:
    """Group pairs by cell (stable, so each cell keeps the pair order) and keep at
    most ``cap`` lights per cell (the first ones)."""
    cell = np.asarray(cell, dtype=np.int64)
    order = np.argsort(cell, kind="stable")
    cs, ls = cell[order], np.asarray(light, dtype=np.int64)[order]
    total = np.bincount(cs, minlength=cells).astype(np.int64)
    start = np.cumsum(total) - total
    dropped = 0
    if cap is not None and len(cs) and int(total.max()) > cap:
        rank = np.arange(len(cs), dtype=np.int64) - start[cs]
        keep = rank < cap
        dropped = int((~keep).sum())
        ls = ls[keep]
        count = np.minimum(total, cap)
    else:
        count = total
    offset = np.cumsum(count) - count
    return CellLists(offset, count, ls, total, dropped)


# --- light trees ----------------------------------------------------------------------------


def next_pow2(x: np.ndarray) -> np.ndarray:
    x = np.maximum(np.asarray(x, dtype=np.int64), 1)
    return (1 << np.ceil(np.log2(x)).astype(np.int64)).astype(np.int64)


@lru_cache(maxsize=32)
def dfs_order(leaves: int) -> np.ndarray:
    """Heap (breadth-first) index of each node of a full binary tree with ``leaves``
    leaves (a power of two), in depth-first pre-order: the conversion table."""
    if leaves < 1 or leaves & (leaves - 1):
        raise ValueError("leaves must be a power of two")
    total = 2 * leaves - 1
    out = np.empty(total, dtype=np.int64)
    stack, k = [0], 0
    while stack:
        h = stack.pop()
        out[k] = h
        k += 1
        if h < leaves - 1:
            stack.append(2 * h + 2)
            stack.append(2 * h + 1)
    out.setflags(write=False)
    return out


@lru_cache(maxsize=32)
def heap_skip(leaves: int) -> np.ndarray:
    """Subtree size of each heap node (the skip count)."""
    depth = round(math.log2(leaves))
    h = np.arange(2 * leaves - 1)
    level = np.floor(np.log2(h + 1)).astype(np.int64)
    out = (1 << (depth - level + 1)) - 1
    out.setflags(write=False)
    return out


def pack_bits(leaf: np.ndarray, count: np.ndarray, skip: np.ndarray) -> np.ndarray:
    c = np.minimum(np.asarray(count, dtype=np.int64), COUNT_MASK)
    s = np.asarray(skip, dtype=np.int64)
    if np.any(s > SKIP_MASK) or np.any(s < 1):
        raise ValueError("skip count out of the 15-bit range")
    bits = (np.asarray(leaf, dtype=np.int64) & 1) | (c << COUNT_SHIFT) | (s << SKIP_SHIFT)
    return bits.astype(np.uint32)


def unpack_bits(bits: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    b = np.asarray(bits, dtype=np.int64)
    return b & LEAF_BIT, (b >> COUNT_SHIFT) & COUNT_MASK, (b >> SKIP_SHIFT) & SKIP_MASK


def _segment_minmax(
    lo: npt.ArrayLike, hi: npt.ArrayLike, first: npt.ArrayLike, count: npt.ArrayLike
) -> tuple[np.ndarray, np.ndarray]:
    """min(lo), max(hi) over index ranges [first, first + count) (empty -> inf, -inf)."""
    first = np.asarray(first, dtype=np.int64).ravel()
    count = np.asarray(count, dtype=np.int64).ravel()
    out_lo = np.full(len(first), np.inf)
    out_hi = np.full(len(first), -np.inf)
    ne = count > 0
    if ne.any():
        f, e = first[ne], first[ne] + count[ne]
        order = np.argsort(f, kind="stable")
        idx = np.empty(2 * len(f), dtype=np.int64)
        idx[0::2], idx[1::2] = f[order], e[order]
        lo_p = np.append(np.asarray(lo, dtype=np.float64), np.inf)
        hi_p = np.append(np.asarray(hi, dtype=np.float64), -np.inf)
        mn = np.minimum.reduceat(lo_p, idx)[0::2]
        mx = np.maximum.reduceat(hi_p, idx)[0::2]
        tmp_lo, tmp_hi = np.empty_like(mn), np.empty_like(mx)
        tmp_lo[order], tmp_hi[order] = mn, mx
        out_lo[ne], out_hi[ne] = tmp_lo, tmp_hi
    return out_lo, out_hi


@dataclass
class PackedTrees:
    """GPU-ready per-cell structures (Listing 1 nodes, depth-first per cell)."""

    cell_first: np.ndarray  # (C,) uint32 first node of each cell
    cell_nodes: np.ndarray  # (C,) uint32 node count (0 = empty cell)
    node_min: np.ndarray  # (M,) float32 min depth
    node_max: np.ndarray  # (M,) float32 max depth
    node_first: np.ndarray  # (M,) uint32 first light (index into ``lights``)
    node_bits: np.ndarray  # (M,) uint32 leaf | count << 1 | skip << 17
    lights: np.ndarray  # (E,) uint32 light indices (the caller's numbering)
    is_tree: np.ndarray  # (C,) bool

    @property
    def tree_cells(self) -> int:
        return int(self.is_tree.sum())

    @property
    def list_cells(self) -> int:
        return int(((self.cell_nodes > 0) & ~self.is_tree).sum())

    def nodes_of(self, cell: int) -> np.ndarray:
        """(k, 4) [min, max, first, bits] of one cell (float64 view, tests)."""
        a, k = int(self.cell_first[cell]), int(self.cell_nodes[cell])
        s = slice(a, a + k)
        return np.stack(
            [self.node_min[s], self.node_max[s], self.node_first[s], self.node_bits[s]], -1
        ).astype(np.float64)

    def gpu_nodes(self) -> np.ndarray:
        """(M, 4) uint32 records: float bits of min/max, first, bits (std430 16 B)."""
        out = np.empty((len(self.node_min), 4), dtype=np.uint32)
        out[:, 0] = self.node_min.view(np.uint32)
        out[:, 1] = self.node_max.view(np.uint32)
        out[:, 2] = self.node_first
        out[:, 3] = self.node_bits
        return out


def choose_trees(
    lists: CellLists,
    cell_of_entry: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    cell_lo: np.ndarray,
    cell_hi: np.ndarray,
    leaf: int,
    mode: str = "hybrid",
) -> np.ndarray:
    """Listing 2 per cell: sum of the lights' depth extents clipped to the cell,
    divided by the count, below the cell's radius (half its depth extent) -> tree.
    ``lo``/``hi``/``cell_of_entry`` are per list entry; cell_lo/hi per cell."""
    C = len(lists.count)
    if mode not in HEURISTIC_MODES:
        raise ValueError(f"mode must be one of {', '.join(HEURISTIC_MODES)}")
    many = lists.count > leaf
    if mode == "list":
        return lists.count > limits.LIGHTTREE_MAX_NODE_LIGHTS
    if mode == "tree":
        return many
    clipped = np.maximum(
        np.minimum(hi, cell_hi[cell_of_entry]) - np.maximum(lo, cell_lo[cell_of_entry]), 0.0
    )
    s = np.bincount(cell_of_entry, weights=clipped, minlength=C)
    avg = s / np.maximum(lists.count, 1)
    radius = 0.5 * (cell_hi - cell_lo)
    return (many & (avg < radius)) | (lists.count > limits.LIGHTTREE_MAX_NODE_LIGHTS)


def build_cells(
    lists: CellLists, lo: np.ndarray, hi: np.ndarray, is_tree: np.ndarray, leaf: int
) -> PackedTrees:
    """Nodes for every cell. ``lo``/``hi``: depth interval of each list entry (its
    light's view-depth extent, entries of a cell in increasing centre depth)."""
    if leaf < 1:
        raise ValueError("leaf size must be >= 1")
    C = len(lists.count)
    cnt = lists.count.astype(np.int64)
    is_tree = np.asarray(is_tree, dtype=bool) & (cnt > 0)
    leaves = np.ones(C, dtype=np.int64)
    if is_tree.any():
        want = -(-cnt[is_tree] // leaf)
        leaves[is_tree] = np.minimum(next_pow2(want), limits.LIGHTTREE_MAX_LEAVES)
    nodes = np.where(cnt > 0, 2 * leaves - 1, 0)
    first_node = np.cumsum(nodes) - nodes
    M = int(nodes.sum())
    if M > limits.LIGHTTREE_MAX_NODES:
        raise ValueError(f"light trees need {M} nodes (limit {limits.LIGHTTREE_MAX_NODES})")
    n_min = np.full(M, np.inf)
    n_max = np.full(M, -np.inf)
    n_first = np.zeros(M, dtype=np.int64)
    n_bits = np.zeros(M, dtype=np.uint32)

    # lists: one leaf node per non-empty cell
    lc = np.nonzero((cnt > 0) & ~is_tree)[0]
    if len(lc):
        mn, mx = _segment_minmax(lo, hi, lists.offset[lc], cnt[lc])
        at = first_node[lc]
        n_min[at], n_max[at], n_first[at] = mn, mx, lists.offset[lc]
        n_bits[at] = pack_bits(np.ones(len(lc), np.int64), cnt[lc], np.ones(len(lc), np.int64))

    # Leaf boundaries (list starts), for the ascending order inside each leaf below.
    marks = np.zeros(len(lists.light) + 1, dtype=np.int64)
    marks[lists.offset[cnt > 0]] = 1

    # trees, grouped by leaf count
    tc = np.nonzero(is_tree)[0]
    for L in np.unique(leaves[tc]):
        L = int(L)
        g = tc[leaves[tc] == L]
        m = len(g)
        j = np.arange(L + 1, dtype=np.int64)
        bnd = lists.offset[g][:, None] + (j[None, :] * cnt[g][:, None]) // L
        lf, lcnt = bnd[:, :-1], np.diff(bnd, axis=1)
        marks[lf.ravel()] = 1
        lmin, lmax = _segment_minmax(lo, hi, lf, lcnt)
        H = 2 * L - 1
        hmin = np.empty((m, H))
        hmax = np.empty((m, H))
        hfirst = np.empty((m, H), dtype=np.int64)
        hcount = np.empty((m, H), dtype=np.int64)
        hmin[:, L - 1 :] = lmin.reshape(m, L)
        hmax[:, L - 1 :] = lmax.reshape(m, L)
        hfirst[:, L - 1 :] = lf
        hcount[:, L - 1 :] = lcnt
        a = L - 1
        while a > 0:  # levels bottom-up: nodes [a//2 .. a-1] from children [a .. 2a]
            p0 = (a - 1) // 2
            left, right = slice(2 * p0 + 1, 2 * a, 2), slice(2 * p0 + 2, 2 * a + 1, 2)
            hmin[:, p0:a] = np.minimum(hmin[:, left], hmin[:, right])
            hmax[:, p0:a] = np.maximum(hmax[:, left], hmax[:, right])
            hfirst[:, p0:a] = hfirst[:, left]
            hcount[:, p0:a] = hcount[:, left] + hcount[:, right]
            a = p0
        perm = dfs_order(L)
        skip = heap_skip(L)[perm]
        leaf_flag = (perm >= L - 1).astype(np.int64)
        at = (first_node[g][:, None] + np.arange(H)[None, :]).ravel()
        n_min[at] = hmin[:, perm].ravel()
        n_max[at] = hmax[:, perm].ravel()
        n_first[at] = hfirst[:, perm].ravel()
        n_bits[at] = pack_bits(
            np.broadcast_to(leaf_flag, (m, H)).ravel(),
            hcount[:, perm].ravel(),
            np.broadcast_to(skip, (m, H)).ravel(),
        )

    # Each leaf's lights in ascending light-buffer order (a leaf evaluates all of them,
    # in any order): the shader's leaf loop then runs the point, sphere and other lights
    # in parts, each with only its model's code, like tiled and clustered (issue 34).
    seg = np.cumsum(marks[:-1])
    order = np.lexsort((lists.light, seg))
    return PackedTrees(
        first_node.astype(np.uint32),
        nodes.astype(np.uint32),
        _f32_down(n_min),
        _f32_up(n_max),
        n_first.astype(np.uint32),
        n_bits,
        np.asarray(lists.light)[order].astype(np.uint32),
        is_tree,
    )


def _f32_down(x: np.ndarray) -> np.ndarray:
    """float64 -> float32 never above the input (interval bounds stay conservative)."""
    f = np.asarray(x, dtype=np.float64).astype(np.float32)
    return np.where(f.astype(np.float64) > x, np.nextafter(f, np.float32(-np.inf)), f)


def _f32_up(x: np.ndarray) -> np.ndarray:
    f = np.asarray(x, dtype=np.float64).astype(np.float32)
    return np.where(f.astype(np.float64) < x, np.nextafter(f, np.float32(np.inf)), f)


# --- traversal (Listing 3) and its brute-force twin --------------------------------------


def traverse(nodes: np.ndarray, q_lo: float, q_hi: float | None = None) -> tuple[list, int]:
    """Walk one cell's depth-first nodes ((k, 4): min, max, first, bits) for the depth
    interval [q_lo, q_hi] (a point when q_hi is None) exactly as the GPU does: a hit
    node steps to the next node (a hit leaf first yields its light range), a missed
    node jumps its skip count. Returns ([(node position, first light, count) of each
    hit leaf], nodes read)."""
    q_hi = q_lo if q_hi is None else q_hi
    out, i, reads = [], 0, 0
    k = len(nodes)
    while i < k:
        mn, mx, first, bits = nodes[i]
        reads += 1
        leaf, count, skip = unpack_bits(np.int64(bits))
        if mn <= q_hi and mx >= q_lo:
            if leaf:
                out.append((i, int(first), int(count)))
            i += 1
        else:
            i += int(skip)
    return out, reads


def brute_force(
    lo: np.ndarray, hi: np.ndarray, q_lo: float, q_hi: float | None = None
) -> np.ndarray:
    """Indices of the intervals [lo_i, hi_i] overlapping [q_lo, q_hi]."""
    q_hi = q_lo if q_hi is None else q_hi
    return np.nonzero((np.asarray(lo) <= q_hi) & (np.asarray(hi) >= q_lo))[0]


def build_single(lo: np.ndarray, hi: np.ndarray, leaf: int, tree: bool = True) -> PackedTrees:
    """One cell holding every interval (sorted by centre depth first): tests/tools."""
    lo = np.asarray(lo, dtype=np.float64)
    hi = np.asarray(hi, dtype=np.float64)
    order = np.argsort(0.5 * (lo + hi), kind="stable")
    n = len(lo)
    lists = CellLists(
        np.zeros(1, np.int64),
        np.array([n], np.int64),
        order.astype(np.int64),
        np.array([n], np.int64),
    )
    return build_cells(lists, lo[order], hi[order], np.array([tree and n > leaf]), leaf)
