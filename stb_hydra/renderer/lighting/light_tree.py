"""`lighttree`: tiled light trees, hybrid (O'Donnell & Chajdas, I3D 2017).

CPU, per frame (numpy, ``light_tree_build``): the FoV lights are sorted globally by
view depth; binned into the same 2.5D grid as ``clustered`` (``tile`` px tiles x a
near slice + ``slices`` exponential slices; ``slices=0``: 2D tiles only), so every
cell's list comes out depth-sorted; per cell the Listing 2 heuristic picks a plain
list (one leaf node) or a light tree: a full binary interval tree over the lights'
view-depth extents, ``leaf`` lights per leaf (leaf count rounded up to a power of
two), stored depth-first as the packed 16-byte nodes of Listing 1 (min depth, max
depth, first light, leaf | count << 1 | skip << 17).

GPU (``lighttree_lighting.frag``): the pixel's cell, then the stack-less Listing 3
walk with the pixel's view depth: a node containing it is entered (a leaf evaluates
its lights with the reference loop), a missed one is skipped with its skip count.

Options: ``tile``, ``slices``, ``near_split``, ``far`` (as ``clustered``), ``leaf``
(lights per leaf, default 4), ``mode`` ("hybrid" -- Listing 2; "tree" -- a tree in
every cell with more than ``leaf`` lights; "list" -- lists only, i.e. clustered).
The paper's tree-only method is ``mode="tree", slices=0``. Exact: the image equals
``reference`` up to the summation order (lights are summed in depth order).
Stats: ``tree_cells``, ``list_cells``, ``tree_nodes``, ``list_entries``,
``max_cell_lights``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from ... import limits
from .base import LightingMethod, Warn, program
from .clustered import GRID_OPTIONS, check_grid_options, fov_lights, frame_grid, grid_uniforms
from .light_tree_build import (
    HEURISTIC_MODES,
    ClusterGrid,
    PackedTrees,
    bin_lights,
    build_cells,
    cell_lists,
    choose_trees,
)
from .options import Opt, Schema
from .tiled import (
    BIND_EXTRA,
    BIND_HEADERS,
    BIND_LISTS,
    SSBOPool,
    cell_count_stats,
    shade_direct,
)

if TYPE_CHECKING:
    from ..frame import FrameContext
    from ..gl_delegate import GLRenderDelegate

OPTIONS = GRID_OPTIONS + Schema(
    Opt(
        "leaf",
        int,
        limits.LIGHTTREE_LEAF_LIGHTS_DEFAULT,
        range=(1, limits.LIGHTTREE_MAX_NODE_LIGHTS),
        doc="lights per tree leaf",
    ),
    Opt(
        "mode",
        str,
        "hybrid",
        choices=tuple(HEURISTIC_MODES),
        doc="hybrid (Listing 2), tree in every cell, or list only",
    ),
)


class LightTreeLighting(LightingMethod):
    name = "lighttree"
    points_first = True
    options = OPTIONS
    area_shadows_per_frame = True
    exact_rect_textures = True

    @classmethod
    def check_options(cls, o: dict) -> None:
        check_grid_options(cls.name, o)

    def __init__(
        self, delegate: GLRenderDelegate | None, warn: Warn | None = None, **options: Any
    ) -> None:
        super().__init__(delegate, warn, **options)
        self.pool: SSBOPool | None = None
        self.grid: ClusterGrid | None = None
        self.trees: PackedTrees | None = None

    def prepare(self, frame: FrameContext) -> None:
        self.trees = None
        if frame.light_count == 0:
            return
        grid, vp = frame_grid(self.delegate, frame, self.o)
        self.grid = grid
        pos, rng = fov_lights(self.delegate, frame)
        # 1. global sort by view depth (the light centre's)
        depth = -vp.to_view(pos)[:, 2]
        order = np.argsort(depth, kind="stable")
        # 2. binning: pairs come light-major in depth order -> depth-sorted cell lists
        bins = bin_lights(grid, vp, pos[order], rng[order])
        C = grid.count
        cap = None
        if len(bins.cell) > limits.GRID_MAX_LIST_ENTRIES:
            cap = max(1, limits.GRID_MAX_LIST_ENTRIES // C)
            self.warn(
                f"lighttree: {len(bins.cell)} light-cell pairs exceed "
                f"{limits.GRID_MAX_LIST_ENTRIES}; lists capped at {cap}"
            )
        lists = cell_lists(C, bins.cell, bins.light, cap)
        lo, hi = bins.depth_lo[lists.light], bins.depth_hi[lists.light]
        # 3. per cell: list or tree (Listing 2), then build + pack
        cell_of_entry = np.repeat(np.arange(C, dtype=np.int64), lists.count)
        dlo, dhi = grid.nominal_bounds(vp.near)
        per_layer = grid.tiles[0] * grid.tiles[1]
        layer = np.arange(C) // per_layer
        leaf = int(self.o["leaf"])
        is_tree = choose_trees(
            lists, cell_of_entry, lo, hi, dlo[layer], dhi[layer], leaf, self.o["mode"]
        )
        trees = build_cells(lists, lo, hi, is_tree, leaf)
        trees.lights = order[trees.lights.astype(np.int64)].astype(np.uint32)  # -> FoV index
        self.trees = trees
        frame.stats["tree_cells"] = trees.tree_cells
        frame.stats["list_cells"] = trees.list_cells
        frame.stats["tree_nodes"] = len(trees.node_min)
        frame.stats["list_entries"] = lists.entries
        frame.stats["max_cell_lights"] = int(lists.total.max()) if C else 0
        frame.stats.update(cell_count_stats(lists.total, frame.light_count))
        frame.stats["dropped_lights"] = int(lists.dropped)

    def execute(self, frame: FrameContext) -> None:
        if frame.light_count == 0 or self.trees is None:
            shade_direct(self, frame)
            return
        grid = self.grid
        assert grid is not None  # prepare made it with the trees
        if self.pool is None:
            self.pool = SSBOPool(frame.ctx)
        t = self.trees
        with frame.timings_scope("lighttree_upload"):
            hdr = np.empty((len(t.cell_first), 2), dtype=np.uint32)
            hdr[:, 0], hdr[:, 1] = t.cell_first, t.cell_nodes
            headers = self.pool.upload("headers", hdr, BIND_HEADERS)
            nodes = self.pool.upload("nodes", t.gpu_nodes(), BIND_LISTS)
            lights = self.pool.upload("lights", t.lights, BIND_EXTRA)
        with frame.timings_scope("lighttree_shade"):
            prog = program(frame, "lighttree_lighting.frag", self.lighting_defines(frame))
            self.bind_common(frame, prog)
            headers.bind_to_storage_buffer(BIND_HEADERS)
            nodes.bind_to_storage_buffer(BIND_LISTS)
            lights.bind_to_storage_buffer(BIND_EXTRA)
            grid_uniforms(prog, grid)
            self.fullscreen_pass(frame, prog, "lighting")
        frame.stats["clusters"] = grid.count

    def release(self) -> None:
        if self.pool is not None:
            self.pool.release()
            self.pool = None
