"""`clustered`: practical clustered shading (Persson 2013, Just Cause 3).

A 2.5D grid in view space: ``tile`` px screen tiles (default 16: tiled's; Persson's 64
made each pixel walk a 4x4 tiles' list on llvmpipe) x depth cells -- a
near slice ``[0, near_split)`` then ``slices`` exponential slices (default 16) up to
``far``; deeper pixels use the last slice. ``near_split``/``far`` default to the
scene's geometry bounds seen from the camera (``light_tree_build.auto_depth_range``).

Light assignment (``assign``):

* ``"cpu"`` (default): vectorised numpy binning (``light_tree_build.bin_lights``):
  per light its slice range, per (light, slice) the screen rectangle of the sphere
  clipped to the slice, every cluster of that rectangle; CSR lists sorted by cluster
  (FoV order inside a cluster), uploaded per frame.
* ``"gpu"``: one compute workgroup per cluster tests every FoV light against the
  cluster's frustum (``clustered_assign.comp`` = ``tiled_cull.comp`` with slice depth
  bounds).

Shading (``clustered_lighting.frag``): the pixel's cluster from its tile and the slice
of its view depth, then the reference light loop over the list (per-pixel shadows);
each list entry carries its light's ``pos_range`` for the walk's range test. The CPU
lists (and their upload) are kept while the grid, view and lights' positions and ranges
are unchanged.
``cap`` (default none) keeps at most that many lights per cluster (lowest FoV indices;
drops counted in ``frame.stats["dropped_lights"]``). Without a cap the image equals
``reference``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import moderngl
import numpy as np

from ... import limits
from ..gl import set_uniform, shader_library
from ..records import InViewLights
from ..shader_constants import SSBO_CELL_POS_RANGE, SSBO_LIGHTS
from .base import LightingMethod, Warn, program
from .light_tree_build import (
    CellLists,
    ClusterGrid,
    ViewParams,
    auto_depth_range,
    bin_lights,
    cell_lists,
)
from .options import Opt, OptionError, Schema
from .tiled import (
    BIND_EXTRA,
    BIND_HEADERS,
    BIND_LISTS,
    SSBOPool,
    cell_count_stats,
    cull_uniforms,
    entry_pos_range,
    light_ssbo,
    parse_cap,
    read_stats,
    read_totals,
    shade_direct,
    walk_defines,
)

if TYPE_CHECKING:
    from ..frame import FrameContext
    from ..gl_delegate import GLRenderDelegate


def grid_options(tile_default: int) -> Schema:
    """The grid's options (clustered, light tree) with ``tile_default`` px tiles."""
    return Schema(
        Opt(
            "tile",
            int,
            tile_default,
            range=limits.CLUSTER_TILE_PX_RANGE,
            doc="screen tile size of the grid, px",
        ),
        *DEPTH_OPTIONS,
    )


DEPTH_OPTIONS = (
    Opt(
        "slices",
        int,
        limits.CLUSTER_SLICES_DEFAULT,
        range=(0, limits.CLUSTER_SLICES_MAX),
        doc="exponential depth slices after the near slice (0: 2D tiles)",
    ),
    Opt(
        "near_split",
        float,
        None,
        nullable=True,
        doc="end of the near slice, m (none: from the scene bounds)",
    ),
    Opt("far", float, None, nullable=True, doc="far end of the grid, m (none: scene bounds)"),
)
#: The light tree's grid (Persson's 64 px tiles).
GRID_OPTIONS = grid_options(limits.CLUSTER_TILE_PX_DEFAULT)
OPTIONS = grid_options(limits.CLUSTERED_TILE_PX_DEFAULT) + Schema(
    Opt("assign", str, "cpu", choices=("cpu", "gpu"), doc="light assignment on CPU or GPU"),
    Opt("cap", int, None, nullable=True, doc="most lights per cluster (none: no cap)"),
)


def check_grid_options(name: str, o: dict) -> None:
    """Depth range options: positive metres, near_split < far."""
    for k in ("near_split", "far"):
        v = o[k]
        if v is not None and not v > 0:
            raise OptionError(f"{name} option {k}: expected a positive number of metres, got {v}")
    if o["near_split"] is not None and o["far"] is not None and o["near_split"] >= o["far"]:
        raise OptionError(f"{name} options: need near_split < far")


def frame_grid(
    delegate: GLRenderDelegate | None, frame: FrameContext, o: dict
) -> tuple[ClusterGrid, ViewParams]:
    """This frame's grid: options, else the automatic depth range."""
    vp = ViewParams.from_setup(frame.view)
    w, h = frame.buffers.size if frame.buffers.size[0] else (vp.width, vp.height)
    ns, far = o["near_split"], o["far"]
    if ns is None or far is None:
        a_ns, a_far = auto_depth_range(vp, getattr(delegate, "scene_bounds", None))
        far = float(far) if far is not None else max(a_far, (ns or 0.0) * 2.0)
        ns = float(ns) if ns is not None else min(a_ns, 0.5 * far)
    grid = ClusterGrid(w, h, int(o["tile"]), int(o["slices"]), float(ns), float(far))
    return grid, vp


def fov_lights(
    delegate: GLRenderDelegate | None, frame: FrameContext
) -> tuple[np.ndarray, np.ndarray]:
    """(n, 3) positions and (n,) ranges of the FoV lights, in ``lights[]`` order."""
    assert delegate is not None, "in-view lights need the delegate's light table"
    t, rows = delegate.light_table, frame.get(InViewLights).rows
    return (
        np.asarray(t.position[rows], dtype=np.float64),
        np.asarray(t.range[rows], dtype=np.float64),
    )


def grid_uniforms(prog: moderngl.Program | moderngl.ComputeShader, grid: ClusterGrid) -> None:
    set_uniform(prog, "u_grid", grid.tiles)
    set_uniform(prog, "u_tile_px", grid.tile)
    set_uniform(prog, "u_slices", grid.shader_params())


class ClusteredLighting(LightingMethod):
    name = "clustered"
    points_first = True
    area_shadows_per_frame = True
    exact_rect_textures = True
    options = OPTIONS

    @classmethod
    def check_options(cls, o: dict) -> None:
        check_grid_options(cls.name, o)
        o["cap"] = parse_cap(o["cap"])

    def __init__(
        self, delegate: GLRenderDelegate | None, warn: Warn | None = None, **options: Any
    ) -> None:
        super().__init__(delegate, warn, **options)
        self.pool: SSBOPool | None = None
        self.grid: ClusterGrid | None = None
        self.lists: CellLists | None = None
        #: What the CPU lists were built from (grid, view, light positions and ranges);
        #: the same next frame -> the same lists, kept and not uploaded again.
        self._lists_key: tuple | None = None
        self._lists_uploaded = False

    def prepare(self, frame: FrameContext) -> None:
        if frame.light_count == 0:
            self.lists, self._lists_key = None, None
            return
        grid, vp = frame_grid(self.delegate, frame, self.o)
        self.grid = grid
        if self.o["assign"] != "cpu":
            self.lists = None
            return
        pos, rng = fov_lights(self.delegate, frame)
        key = (
            grid,
            vp.view.tobytes(),
            vp.tan_half,
            vp.offset,
            vp.near,
            vp.orthographic,
            pos.tobytes(),
            rng.tobytes(),
        )
        if self.lists is not None and key == self._lists_key:
            return  # a still camera and lights: last frame's lists (and upload) hold
        self._lists_key, self._lists_uploaded = key, False
        bins = bin_lights(grid, vp, pos, rng)
        C = grid.count
        cap = self.o["cap"]
        if len(bins.cell) > limits.GRID_MAX_LIST_ENTRIES:
            budget = max(1, limits.GRID_MAX_LIST_ENTRIES // C)
            cap = budget if cap is None else min(cap, budget)
            self.warn(
                f"clustered: {len(bins.cell)} light-cluster pairs exceed "
                f"{limits.GRID_MAX_LIST_ENTRIES}; lists capped at {cap}"
            )
        self.lists = cell_lists(C, bins.cell, bins.light, cap)

    def execute(self, frame: FrameContext) -> None:
        if frame.light_count == 0:
            shade_direct(self, frame)
            return
        ctx = frame.ctx
        if self.pool is None:
            self.pool = SSBOPool(ctx)
        grid = self.grid
        assert grid is not None  # prepare made it (lights in view)
        C = grid.count
        pos_range: moderngl.Buffer | None
        if self.lists is not None:
            L = self.lists
            if not self._lists_uploaded:
                with frame.timings_scope("clustered_upload"):
                    hdr = np.empty((C, 2), dtype=np.uint32)
                    hdr[:, 0], hdr[:, 1] = L.offset, L.count
                    self.pool.upload("headers", hdr, BIND_HEADERS)
                    self.pool.upload("lists", L.light.astype(np.uint32), BIND_LISTS)
                    # each entry's pos_range, the light buffer's floats (the walk's test)
                    assert self.delegate is not None
                    assert self.delegate.fov_pos_range is not None
                    pr = self.delegate.fov_pos_range[L.light]
                    self.pool.upload("entry_pos_range", pr, SSBO_CELL_POS_RANGE)
                self._lists_uploaded = True
            headers = self.pool.buffers["headers"]
            lists = self.pool.buffers["lists"]
            pos_range = self.pool.buffers["entry_pos_range"]
            frame.stats["dropped_lights"] = int(L.dropped)
            frame.stats["list_entries"] = int(L.entries)
            frame.stats["max_cell_lights"] = int(L.total.max()) if C else 0
            frame.stats.update(cell_count_stats(L.total, frame.light_count))
        else:
            headers, lists, pos_range = self._assign_gpu(frame, grid, self.pool)

        with frame.timings_scope("clustered_shade"):
            defines = walk_defines(self.lighting_defines(frame), pos_range)
            prog = program(frame, "clustered_lighting.frag", defines)
            self.bind_common(frame, prog)
            headers.bind_to_storage_buffer(BIND_HEADERS)
            lists.bind_to_storage_buffer(BIND_LISTS)
            grid_uniforms(prog, grid)
            self.fullscreen_pass(frame, prog, "lighting")
        if self.lists is None:
            frame.stats.update(
                {k: v for k, v in read_stats(self._stats).items() if k != "cells_over_cap"}
            )
            frame.stats.update(cell_count_stats(read_totals(self._stats, C), frame.light_count))
        frame.stats["clusters"] = C
        frame.stats["cluster_depth_range"] = [grid.near_split, grid.far]

    def _assign_gpu(
        self, frame: FrameContext, grid: ClusterGrid, pool: SSBOPool
    ) -> tuple[moderngl.Buffer, moderngl.Buffer, moderngl.Buffer | None]:
        ctx = frame.ctx
        gx, gy, gz = grid.dims
        C = grid.count
        n = frame.light_count
        want = self.o["cap"] if self.o["cap"] is not None else n
        stride = min(want, max(1, limits.GRID_MAX_LIST_ENTRIES // C))
        if stride < want:
            self.warn(
                f"clustered: {C} clusters x {want} lights exceed "
                f"{limits.GRID_MAX_LIST_ENTRIES} list entries; lists capped at {stride}"
            )
        headers = pool.get("headers", C * 8)
        lists = pool.get("lists", C * stride * 4)
        stats = pool.get("stats", 16 + C * 4)
        stats.write(np.zeros(4, dtype=np.uint32).tobytes())
        self._stats = stats
        pos_range = entry_pos_range(pool, C * stride)
        with frame.timings_scope("clustered_assign"):
            cs = shader_library(ctx).compute(
                "clustered_assign.comp",
                walk_defines({"CULL_GROUP_SIZE": limits.CULL_GROUP_SIZE}, pos_range),
            )
            light_ssbo(frame).bind_to_storage_buffer(SSBO_LIGHTS)
            headers.bind_to_storage_buffer(BIND_HEADERS)
            lists.bind_to_storage_buffer(BIND_LISTS)
            stats.bind_to_storage_buffer(BIND_EXTRA)
            grid_uniforms(cs, grid)
            set_uniform(cs, "u_stride", stride)
            set_uniform(cs, "u_cap", stride)
            cull_uniforms(cs, frame)
            cs.run(gx, gy, gz)
            ctx.memory_barrier()
        return headers, lists, pos_range

    def release(self) -> None:
        self.lists, self._lists_key, self._lists_uploaded = None, None, False
        if self.pool is not None:
            self.pool.release()
            self.pool = None
