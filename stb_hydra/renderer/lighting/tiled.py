"""`tiled`: tiled deferred lighting (Andersson 2009, "Parallel graphics in Frostbite").

1. Culling (``tiled_cull.comp``): one compute workgroup per 16x16 px tile tests every
   FoV light's influence sphere against the tile's frustum -- the four side planes
   through its pixel edges and the tile's min/max view depth from the depth pyramid
   (level 4) -- and compacts the hits, in FoV order, into the tile's list.
2. Shading (``tiled_lighting.frag``): per pixel the reference light loop over its
   tile's list, with per-pixel shadows (``local_shadow``) for every listed light. The
   cull also copies each kept entry's ``pos_range`` beside its index (within
   ``limits.CELL_POS_RANGE_MAX_BYTES``), so the walk over the list's entries out of
   the pixel's reach reads one vec4 a step instead of an index and then a record.

The list holds at most ``tile_cap`` lights (default 64, as Unity HDRP's FPTL; ``None``
/ ``"none"`` / 0 = no cap). Lights past the cap are dropped -- the lowest FoV indices
are kept, so which lights survive is deterministic -- and counted per frame in
``frame.stats``: ``dropped_lights`` (light-tile pairs), ``tiles_over_cap``,
``max_tile_lights`` (longest uncapped list), ``list_entries``. Without a cap the
image equals ``reference`` (same includes, same summation order).

Options: ``tile_cap`` (int >= 1 or none), ``stats`` (read the four counters back each
frame: a small sync; default on).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import moderngl
import numpy as np

from ... import limits
from ..gl import set_uniform, shader_library
from ..records import LightBuffer
from ..shader_constants import (
    SSBO_CELL_EXTRA,
    SSBO_CELL_HEADERS,
    SSBO_CELL_LISTS,
    SSBO_CELL_POS_RANGE,
    SSBO_LIGHTS,
    TEX_UNIT_HIZ,
)
from .base import LightingMethod, Warn, program
from .options import Opt, Schema

if TYPE_CHECKING:
    from ..frame import FrameContext
    from ..gl_delegate import GLRenderDelegate

#: SSBO bindings (0 = lights, 1 = shadow maps are shared).
BIND_HEADERS, BIND_LISTS, BIND_EXTRA = SSBO_CELL_HEADERS, SSBO_CELL_LISTS, SSBO_CELL_EXTRA

OPTIONS = Schema(
    Opt(
        "tile_cap",
        int,
        limits.TILED_CAP_DEFAULT,
        nullable=True,
        doc="most lights per 16 px tile list (none or <= 0: no cap)",
    ),
    Opt("stats", bool, True, doc="read the dropped-light counters back each frame"),
)


def parse_cap(value: str | float | None) -> int | None:
    """None / "none" / "off" / 0 / negative / False -> None (no cap), else int >= 1."""
    if value is None or value is False:
        return None
    if isinstance(value, str):
        v = value.strip().lower()
        if v in ("none", "off", "no", "inf", ""):
            return None
        value = int(v)
    cap = int(value)
    return None if cap <= 0 else cap


class SSBOPool:
    """Grow-only storage buffers by name (re-used across frames)."""

    def __init__(self, ctx: moderngl.Context) -> None:
        self.ctx = ctx
        self.buffers: dict[str, moderngl.Buffer] = {}

    def get(self, name: str, nbytes: int) -> moderngl.Buffer:
        nbytes = max(int(nbytes), 16)
        b = self.buffers.get(name)
        if b is None or b.size < nbytes:
            if b is not None:
                b.release()
            size = 1 << max(4, math.ceil(math.log2(nbytes)))  # amortise growth
            b = self.ctx.buffer(reserve=size)
            self.buffers[name] = b
        return b

    def upload(self, name: str, data: np.ndarray, binding: int) -> moderngl.Buffer:
        raw = np.ascontiguousarray(data).tobytes()
        b = self.get(name, len(raw))
        if raw:
            b.write(raw)
        b.bind_to_storage_buffer(binding)
        return b

    def release(self) -> None:
        for b in self.buffers.values():
            b.release()
        self.buffers.clear()


def entry_pos_range(pool: SSBOPool, entries: int) -> moderngl.Buffer | None:
    """The per-entry ``pos_range`` buffer of GPU-built lists (``entries`` = cells x
    list stride; the cull kernel fills it beside the indices, ``CELL_POS_RANGE``), or
    None past ``limits.CELL_POS_RANGE_MAX_BYTES`` (the walk then reads the light
    buffer: same image)."""
    nbytes = 16 * int(entries)
    if nbytes > limits.CELL_POS_RANGE_MAX_BYTES:
        return None
    return pool.get("entry_pos_range", nbytes)


def walk_defines(defines: dict[str, object], pos_range: moderngl.Buffer | None) -> dict:
    """Shading / cull defines with ``CELL_POS_RANGE`` when the lists carry each entry's
    ``pos_range`` (bound at ``SSBO_CELL_POS_RANGE``)."""
    if pos_range is None:
        return defines
    pos_range.bind_to_storage_buffer(SSBO_CELL_POS_RANGE)
    return {**defines, "CELL_POS_RANGE": True}


def shade_direct(method: LightingMethod, frame: FrameContext) -> None:
    """No local lights in view: sun + ambient only (the reference's light-less path)."""
    prog = program(frame, "lighting_direct.frag", method.lighting_defines(frame))
    method.bind_common(frame, prog)
    method.fullscreen_pass(frame, prog, "lighting")


def cull_uniforms(prog: moderngl.ComputeShader, frame: FrameContext) -> None:
    """Margins and the world -> view radius scale of ``tiled_cull.comp`` (the GPU twin
    of ``light_tree_build.widened_radius``)."""
    set_uniform(prog, "u_rel_margin", float(limits.CULL_RADIUS_REL_MARGIN))
    set_uniform(prog, "u_depth_margin", float(limits.CULL_DEPTH_REL_MARGIN))
    scale = np.linalg.norm(np.asarray(frame.view.view, dtype=np.float64)[:3, :3], 2)
    set_uniform(prog, "u_radius_scale", float(scale))


def light_ssbo(frame: FrameContext) -> moderngl.Buffer:
    """The frame's light SSBO (uploaded whenever lights are in view)."""
    ssbo = frame.get(LightBuffer).ssbo
    assert ssbo is not None, "no light buffer with lights in view"
    return ssbo


def read_stats(buf: moderngl.Buffer) -> dict[str, int]:
    v = np.frombuffer(buf.read(size=16), dtype=np.uint32)
    return {
        "dropped_lights": int(v[0]),
        "cells_over_cap": int(v[1]),
        "max_cell_lights": int(v[2]),
        "list_entries": int(v[3]),
    }


def read_totals(buf: moderngl.Buffer, cells: int) -> np.ndarray:
    """Uncapped light count per cell (tile / cluster) the GPU assignment wrote after the
    four counters of ``read_stats``."""
    raw = buf.read(size=4 * cells, offset=16)
    return np.frombuffer(raw, dtype=np.uint32).astype(np.int64)


def cell_count_stats(totals: np.ndarray, fov_lights: int) -> dict[str, float]:
    """Per-cell light counts as bench numbers (``frame.stats``): mean, median, p95 and
    max lights per tile / cluster (uncapped), and ``cell_light_share``: the mean count
    over the in-view lights -- the fraction of the brute-force (reference) light-pixel
    work a cell-list method keeps, 1 when culling culls nothing."""
    t = np.asarray(totals, dtype=np.float64).reshape(-1)
    if t.size == 0:
        return {}
    mean = float(t.mean())
    return {
        "cell_lights_mean": round(mean, 3),
        "cell_lights_p50": float(np.percentile(t, 50)),
        "cell_lights_p95": float(np.percentile(t, 95)),
        "cell_lights_max": int(t.max()),
        "cell_light_share": round(mean / fov_lights, 5) if fov_lights > 0 else 0.0,
    }


class TiledLighting(LightingMethod):
    name = "tiled"
    points_first = True
    area_shadows_per_frame = True
    exact_rect_textures = True
    options = OPTIONS
    hiz_level = int(math.log2(limits.TILED_TILE_PX))

    @classmethod
    def check_options(cls, o: dict) -> None:
        o["tile_cap"] = parse_cap(o["tile_cap"])

    def __init__(
        self, delegate: GLRenderDelegate | None, warn: Warn | None = None, **options: Any
    ) -> None:
        super().__init__(delegate, warn, **options)
        self.cap: int | None = self.o["tile_cap"]
        self.tile = limits.TILED_TILE_PX
        self.pool: SSBOPool | None = None
        self.tiles = (0, 0)
        self.stats_buffer: moderngl.Buffer | None = None

    def grid(self, width: int, height: int) -> tuple[int, int]:
        return (math.ceil(width / self.tile), math.ceil(height / self.tile))

    def execute(self, frame: FrameContext) -> None:
        w, h = frame.buffers.size
        gx, gy = self.grid(w, h)
        if frame.light_count == 0:
            self.tiles, self.stats_buffer = (gx, gy), None
            shade_direct(self, frame)
            return
        ctx = frame.ctx
        if self.pool is None:
            self.pool = SSBOPool(ctx)
        tiles = gx * gy
        n = frame.light_count
        want = self.cap if self.cap is not None else n
        stride = min(want, max(1, limits.GRID_MAX_LIST_ENTRIES // tiles))
        if stride < want:
            self.warn(
                f"tiled: {tiles} tiles x {want} lights exceed {limits.GRID_MAX_LIST_ENTRIES} "
                f"list entries; lists capped at {stride}",
            )
        headers = self.pool.get("headers", tiles * 8)
        lists = self.pool.get("lists", tiles * stride * 4)
        stats = self.pool.get("stats", 16 + tiles * 4)
        stats.write(np.zeros(4, dtype=np.uint32).tobytes())
        self.stats_buffer, self.tiles = stats, (gx, gy)
        pos_range = entry_pos_range(self.pool, tiles * stride)

        with frame.timings_scope("tiled_cull"):
            cs = shader_library(ctx).compute(
                "tiled_cull.comp",
                walk_defines({"CULL_GROUP_SIZE": limits.CULL_GROUP_SIZE}, pos_range),
            )
            light_ssbo(frame).bind_to_storage_buffer(SSBO_LIGHTS)
            headers.bind_to_storage_buffer(BIND_HEADERS)
            lists.bind_to_storage_buffer(BIND_LISTS)
            stats.bind_to_storage_buffer(BIND_EXTRA)
            hiz = frame.buffers.textures[f"hiz{int(math.log2(self.tile))}"]
            hiz.use(TEX_UNIT_HIZ)
            set_uniform(cs, "u_hiz", TEX_UNIT_HIZ)
            set_uniform(cs, "u_grid", (gx, gy))
            set_uniform(cs, "u_tile_px", self.tile)
            set_uniform(cs, "u_stride", stride)
            set_uniform(cs, "u_cap", stride)
            cull_uniforms(cs, frame)
            cs.run(gx, gy, 1)
            ctx.memory_barrier()

        with frame.timings_scope("tiled_shade"):
            defines = walk_defines(self.lighting_defines(frame), pos_range)
            prog = program(frame, "tiled_lighting.frag", defines)
            self.bind_common(frame, prog)
            headers.bind_to_storage_buffer(BIND_HEADERS)
            lists.bind_to_storage_buffer(BIND_LISTS)
            set_uniform(prog, "u_grid", (gx, gy))
            set_uniform(prog, "u_tile_px", self.tile)
            self.fullscreen_pass(frame, prog, "lighting")

        frame.stats["tile_cap"] = self.cap if self.cap is not None else 0
        if self.o["stats"]:
            s = read_stats(stats)
            frame.stats["dropped_lights"] = s["dropped_lights"]
            frame.stats["tiles_over_cap"] = s["cells_over_cap"]
            frame.stats["max_tile_lights"] = s["max_cell_lights"]
            frame.stats["list_entries"] = s["list_entries"]
            frame.stats.update(cell_count_stats(read_totals(stats, tiles), frame.light_count))

    def tile_totals(self) -> np.ndarray:
        """(tiles_y, tiles_x) uncapped light count per tile of the last frame (GL rows:
        row 0 is the bottom of the image). Tests and debugging."""
        gx, gy = self.tiles
        if self.stats_buffer is None:
            return np.zeros((gy, gx), dtype=np.int64)
        raw = self.stats_buffer.read(size=4 * gx * gy, offset=16)
        return np.frombuffer(raw, dtype=np.uint32).reshape(gy, gx).astype(np.int64)

    def release(self) -> None:
        if self.pool is not None:
            self.pool.release()
            self.pool = None
