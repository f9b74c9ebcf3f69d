"""STB reservoir reuse (issue 31, ``-o reuse=on``): a ReSTIR-style stage on top of
STB's small-tile candidates, replacing the term and lighting passes.

1. ``stb_reuse_temporal.frag`` (per pixel): the initial reservoir resamples the pixel's
   N small-tile samples with a per-pixel target (unshadowed reflected luminance,
   ``common/reuse_target.glsl``); last frame's reservoir of the same surface
   (reprojected with the G-buffer's motion vectors, rejected on depth / normal /
   roughness mismatch, its light index remapped into this frame's FoV list, its
   confidence M capped) is combined with it, its target re-evaluated with this frame's
   light data.
2. ``stb_reuse_shade.frag`` (per pixel): k neighbours within a radius (a fresh random
   draw per pixel and frame) with similar surfaces are combined (the 1/M rule, or the
   generalized balance heuristic: unbiased); the chosen light is shaded with its term
   (shadow x cone x IES) evaluated at the pixel, so shadowed candidates add nothing;
   the final reservoir and the pixel's surface are stored for the next frame.
3. Fused (``reuse_candidates`` > 0, k = 0): one shading pass computes the reservoir
   too, shading picks that light_reflect shades by its point model; a pick that needs
   the area path (polygon, LTC) is listed and ``stb_reuse_area.frag`` shades the list,
   eight listed pixels to an llvmpipe stamp (``common/reuse_area.glsl``: the same
   image, without the area code in every stamp of the first pass).

Reservoirs: rgba32ui (light index in the frame's FoV list, bits of W, M and the stored
target), full resolution. The history (two reservoir and two surface textures, ping-
ponged) is dropped on the first frame, a resize, or when the light table's row count
changes (rows renumbered); a camera cut needs no test of its own: the per-pixel
depth / normal test rejects what no longer matches.

Cost per pixel: N + 1 targets, k neighbours (k + 1 targets for 1/M, (k + 1)^2 for the
balance heuristic), one term (shadow lookup) and one shade -- independent of the
scene's light count, like STB.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import moderngl
import numpy as np

from ... import limits
from ..camera import ViewSetup
from ..fullscreen import draw_fullscreen
from ..gl import set_uniform
from ..graph import Tex
from ..light_changes import Rule, change_uniforms, light_changes, light_snapshot
from ..records import InViewLights
from ..shader_constants import (
    IMAGE_UNIT_REUSE_OUT_ALBEDO,
    IMAGE_UNIT_REUSE_OUT_COLOR,
    IMAGE_UNIT_REUSE_OUT_DEMOD,
    IMAGE_UNIT_REUSE_PARTIAL,
    IMAGE_UNIT_REUSE_RESERVOIR,
    IMAGE_UNIT_REUSE_SURFACE,
    SSBO_STB_REUSE_AREA,
    SSBO_STB_REUSE_REMAP,
    TEX_UNIT_HIZ,
)
from .base import TAA_INPUTS, program

if TYPE_CHECKING:
    from ..frame import FrameContext

#: This frame's reservoirs after temporal reuse (read by the shading pass).
CURRENT = "stb_reuse_cur"
#: Ping-ponged history: reservoirs and surfaces (linear depth m, oct normal, roughness).
HISTORY = ("stb_reuse_res0", "stb_reuse_res1")
SURFACE = ("stb_reuse_geo0", "stb_reuse_geo1")
#: The fused pass's listed pixels' sun + ambient radiance (``stb_reuse_area.frag``).
PARTIAL = "stb_reuse_partial"
#: Per-slot halves of the initial target (``-o reuse_target=tile``, big-tile layout).
SLOTS = ("stb_reuse_slot_pos", "stb_reuse_slot_shape", "stb_reuse_slot_axis")
#: ... and, in scenes with light links, the slot's light's link mask (r32ui): the slot
#: target reads it from a texture, not the link SSBO (``common/reuse_share.glsl``).
SLOT_LINK = "stb_reuse_slot_link"
SLOT_UNIFORMS = ("u_slot_pos", "u_slot_shape", "u_slot_axis", "u_slot_link")
#: MIS weights of the spatial combination (``-o reuse_mis``).
MIS_MODES = {"count": 0, "balance": 1, "pairwise": 2}


def reuse_textures() -> tuple[Tex, ...]:
    """The stage's render buffers (full resolution)."""
    return (
        Tex(CURRENT, "rgba32ui"),
        *(Tex(n, "rgba32ui") for n in HISTORY),
        *(Tex(n, "rgba32f") for n in SURFACE),
        *(Tex(n, "rgba32f") for n in SLOTS),
        Tex(SLOT_LINK, "r32ui"),
        Tex(PARTIAL, "rgba32f"),
    )


def fov_remap(prev_rows: np.ndarray, cur_rows: np.ndarray, n_rows: int) -> np.ndarray:
    """Previous FoV index -> this frame's FoV index (int32, -1: not in view now), from
    the light-table rows of both FoV lists."""
    inv = np.full(max(int(n_rows), 1), -1, dtype=np.int32)
    cur = np.asarray(cur_rows, dtype=np.int64)
    inv[cur] = np.arange(len(cur), dtype=np.int32)
    prev = np.asarray(prev_rows, dtype=np.int64)
    out = np.full(len(prev), -1, dtype=np.int32)
    ok = prev < len(inv)
    out[ok] = inv[prev[ok]]
    return out


def temporal_reuse(mode: str, frame: FrameContext) -> bool:
    """Whether this frame combines last frame's reservoirs (``-o reuse_temporal``).
    ``auto``: not under ``--temporal accumulate``, whose frames are averaged as
    independent estimates: reused reservoirs correlate them, and the average of 16
    correlated frames is worse than of 16 independent ones (docs/STB_NOTES.md)."""
    if mode == "auto":
        return str(frame.settings.temporal) != "accumulate"
    return mode == "on"


def slot_grid(big_tile: int) -> int:
    """Side of the grid of surface points per big-tile slot of ``-o reuse_target=tile``
    (``stb_reuse_slots.frag``) for big tiles of ``big_tile`` px: points at least
    ``limits.STB_REUSE_SLOT_GRID_MIN_PX`` apart over the tile +- half a tile, at most
    ``limits.STB_REUSE_SLOT_GRID`` (4 for 32 px tiles and up, 2 for 16 px)."""
    g = 2 * int(big_tile) // limits.STB_REUSE_SLOT_GRID_MIN_PX
    return max(2, min(limits.STB_REUSE_SLOT_GRID, g))


#: ``limits.STB_REUSE_CHANGE_RULES`` as ``light_changes`` rules (no turn test) and the
#: columns whose change is a switch.
CHANGE_RULES: tuple[Rule, ...] = tuple(
    (c, di, dm, -2.0) for c, di, dm in limits.STB_REUSE_CHANGE_RULES
)
CHANGE_EXACT = ("type",)


class ReuseStage:
    """The reuse passes of one STB method instance and the history they keep."""

    #: Fused pass: shade the picks that need light_reflect's area path in a second,
    #: compacted pass (``stb_reuse_area.frag``; the same image, bit for bit). False:
    #: light_reflect in the shading pass itself (tests and timings compare the two).
    area_pass = True

    def __init__(self) -> None:
        self.count = 0  # frames of history (0: none)
        self._parity = 0
        self._prev_view: ViewSetup | None = None
        self._prev_rows: np.ndarray | None = None
        self._n_rows = -1
        self._size: tuple[int, int] | None = None
        self._remap: moderngl.Buffer | None = None
        self._area_list: moderngl.Buffer | None = None
        self._area_fbo: moderngl.Framebuffer | None = None
        self._lights: dict[str, np.ndarray] | None = None
        self._light_version = -1
        #: Why the history was dropped on the last frame ("" = kept).
        self.last_reset = ""
        #: Did the last frame's temporal pass have a history to reuse?
        self.last_history = False
        #: Pixels the last frame's area pass shaded (0 without one).
        self.last_area_pixels = 0

    def reset(self) -> None:
        """Forget the history (the next frame starts from its own candidates)."""
        self.count = 0

    def _reset_reason(self, method: Any, frame: FrameContext, n_rows: int) -> str:
        size = (int(frame.buffers.size[0]), int(frame.buffers.size[1]))
        reason = ""
        if self.count == 0 or self._prev_view is None or self._prev_rows is None:
            reason = "start"
        elif size != self._size:
            reason = "resize"
        elif n_rows != self._n_rows:
            reason = "lights"
        self._size = size
        return reason

    def _bind_remap(self, frame: FrameContext, rows: np.ndarray, n_rows: int) -> bool:
        """Upload and bind the FoV index remap; False when the FoV list is unchanged."""
        prev = self._prev_rows
        changed = prev is not None and not np.array_equal(prev, rows)
        data = fov_remap(prev, rows, n_rows) if changed and prev is not None else None
        payload = data.tobytes() if data is not None and len(data) else b"\xff\xff\xff\xff"
        if self._remap is None or self._remap.size < len(payload):
            if self._remap is not None:
                self._remap.release()
            self._remap = frame.ctx.buffer(reserve=max(len(payload), 4 * 1024))
        self._remap.write(payload)
        self._remap.bind_to_storage_buffer(SSBO_STB_REUSE_REMAP)
        return changed

    def _set_changes(self, method: Any, prog: moderngl.Program, frame: FrameContext) -> None:
        """Uniforms of the lights that changed since the last frame (spheres, caps)."""
        d = method.delegate
        spheres, caps = np.zeros((0, 4)), np.zeros(0)
        if d is not None:
            table = d.light_table
            if int(table.version) != self._light_version:
                now = light_snapshot(table)
                before = self._lights
                if before is not None and len(before["live"]) == len(now["live"]):
                    spheres, caps = light_changes(before, now, CHANGE_RULES, CHANGE_EXACT)
                self._lights = now
                self._light_version = int(table.version)
        m_cap = float(method.o["reuse_m_cap"])
        sph, cap, everywhere = change_uniforms(spheres, caps, limits.STB_REUSE_MAX_CHANGES)
        n = len(caps)
        if everywhere is not None:  # too many to test per pixel: cap everywhere
            m_cap = min(m_cap, everywhere)
            n = 0
        frame.stats["stb_reuse_light_changes"] = n
        set_uniform(prog, "u_m_cap", m_cap)
        set_uniform(prog, "u_changes", n)
        if n:
            set_uniform(prog, "u_change_spheres", sph)
            set_uniform(prog, "u_change_caps", cap)

    def execute(
        self,
        method: Any,
        frame: FrameContext,
        defines: dict[str, Any],
        small: moderngl.Texture,
        luts: tuple[moderngl.Texture, moderngl.Texture],
    ) -> None:
        """Run both passes; the second writes ``lighting`` (and taa's inputs).
        ``method``: the :class:`~.stb.StbLighting` that owns this stage (its uniform
        and binding helpers; typed loosely to keep the modules acyclic)."""
        o = method.o
        bufs = frame.buffers
        rows = np.asarray(frame.get(InViewLights).rows)
        n_rows = int(method.delegate.light_table.n_rows) if method.delegate is not None else -1
        reason = self._reset_reason(method, frame, n_rows)
        self.last_reset = reason
        frame.stats["stb_reuse_reset"] = reason
        share = o["reuse_res"] == "share"  # the quad's four reservoirs, fused pass only
        temporal = temporal_reuse(o["reuse_temporal"], frame) and not share
        history = 0 if reason or not temporal else 1
        self.last_history = bool(history)
        src, dst = self._parity, 1 - self._parity
        w, h = bufs.size
        quad = o["reuse_res"] == "quad"  # one reservoir per 2x2 quad (both passes read it)
        cur = bufs.texture(CURRENT, 4, "u4", size=((w + 1) // 2, (h + 1) // 2) if quad else None)
        h_src = bufs.texture(HISTORY[src], 4, "u4")
        g_src = bufs.texture(SURFACE[src], 4, "f4")
        remap = self._bind_remap(frame, rows, n_rows) if history else False
        if not history:
            self._bind_remap(frame, rows[:0], n_rows)  # the SSBO must be bound
        lut_inv, lut_fwd = luts

        n_cand = int(o["reuse_candidates"])
        if n_cand and o["reuse_target"] == "cheap":
            defines = dict(defines, STB_REUSE_CHEAP_TARGET=True)
        slots: tuple[moderngl.Texture, ...] = ()
        if n_cand and o["reuse_target"] == "tile":
            slots = self._slots(method, frame, defines, small)
            defines = dict(defines, STB_REUSE_SLOT_TARGET=True)
        if n_cand and not quad and not history and int(o["reuse_k"]) == 0:
            # Fused: one pass, the shading pass resamples the big tile's reservoirs itself.
            fdefines = dict(defines, STB_REUSE_BIGTILE=n_cand, STB_REUSE_FUSED=True)
            if share:
                fdefines.update(STB_REUSE_SHARE=True, GLSL_EXT_GL_ARB_derivative_control=True)
            self._shade(method, frame, fdefines, big_tile=small, slots=slots)
            self._finish(frame, rows, n_rows, reason, dst)
            return

        # 1. initial candidates + temporal reuse
        tdefines = dict(defines, STB_REUSE_BIGTILE=n_cand) if n_cand else dict(defines)
        if quad:
            tdefines["STB_REUSE_QUAD"] = True
            defines = dict(defines, STB_REUSE_QUAD=True)
        prog = program(frame, "stb_reuse_temporal.frag", tdefines)
        method._common_uniforms(frame, prog)
        if n_cand:
            set_uniform(prog, "u_big_tiles", method.grid(w, h)["big_tiles"])
            set_uniform(prog, "u_stochastic_bilinear", 1 if o["stochastic_bilinear"] else 0)
        unit = method.bind_common(frame, prog)
        for name, tex in (
            ("u_smalltile" if not n_cand else "u_bigtile", small),
            ("u_quad_lut", lut_inv),
            ("u_quad_fwd", lut_fwd),
            ("u_motion", bufs.textures["g_motion"]),
            ("u_prev_res", h_src),
            ("u_prev_geo", g_src),
            *zip(SLOT_UNIFORMS, slots),
        ):
            unit = method._bind(frame, prog, unit, name, tex)
        prev = self._prev_view if self._prev_view is not None else frame.view
        set_uniform(prog, "u_prev_view", np.ascontiguousarray(prev.view, dtype=np.float64))
        set_uniform(prog, "u_jitter", tuple(float(j) for j in frame.view.jitter))
        set_uniform(prog, "u_history", history)
        set_uniform(prog, "u_remap", 1 if remap else 0)
        self._set_changes(method, prog, frame)  # u_m_cap and the changed lights
        one = o["select"] != "all"  # independent picks: each a whole estimate
        set_uniform(prog, "u_init_scale", 1.0 / int(o["N"]) if one else 1.0)
        set_uniform(prog, "u_eps", float(o["eps"]))
        set_uniform(prog, "u_shadow_floor", float(o["reuse_shadow_floor"]))
        method._pass(frame, prog, [CURRENT], cur.size)

        # 2. spatial reuse, visibility, shading, history
        self._shade(method, frame, defines, cur=cur)
        self._finish(frame, rows, n_rows, reason, dst)

    def _shade(
        self,
        method: Any,
        frame: FrameContext,
        defines: dict[str, Any],
        cur: moderngl.Texture | None = None,
        big_tile: moderngl.Texture | None = None,
        slots: tuple[moderngl.Texture, ...] = (),
    ) -> None:
        """The shading pass (``stb_reuse_shade.frag``): reads this frame's reservoirs
        ``cur``, or (fused) resamples the big-tile reservoirs ``big_tile`` itself."""
        o = method.o
        bufs = frame.buffers
        h_dst = bufs.texture(HISTORY[1 - self._parity], 4, "u4")
        g_dst = bufs.texture(SURFACE[1 - self._parity], 4, "f4")
        ldefines = method.lighting_defines(frame, defines)
        # Fused: picks that need light_reflect's area path are listed and shaded by a
        # second, compacted pass (common/reuse_area.glsl); not where a textured rect
        # seen by the camera may replace the pixel (write_lighting's RECT_EMITTERS_SEEN).
        area_pass = self.area_pass and big_tile is not None
        area_pass = area_pass and "RECT_EMITTERS_SEEN" not in ldefines
        self.last_area_pixels = 0
        if area_pass:
            ldefines = dict(ldefines, STB_REUSE_AREA_PASS=True)
            self._area_list_reset(frame)
            partial = bufs.texture(PARTIAL, 4, "f4")
            partial.bind_to_image(IMAGE_UNIT_REUSE_PARTIAL, read=False, write=True)
        prog = program(frame, "stb_reuse_shade.frag", ldefines)
        unit = method.bind_common(frame, prog)
        if cur is not None:
            method._bind(frame, prog, unit, "u_reuse", cur)
        if big_tile is not None:
            method._common_uniforms(frame, prog)
            w, h = bufs.size
            set_uniform(prog, "u_big_tiles", method.grid(w, h)["big_tiles"])
            set_uniform(prog, "u_stochastic_bilinear", 1 if o["stochastic_bilinear"] else 0)
            set_uniform(prog, "u_shadow_floor", float(o["reuse_shadow_floor"]))
            unit = method._bind(frame, prog, unit, "u_bigtile", big_tile)
            for name, tex in zip(SLOT_UNIFORMS, slots, strict=False):
                unit = method._bind(frame, prog, unit, name, tex)
        set_uniform(prog, "u_k", int(o["reuse_k"]))
        set_uniform(prog, "u_radius", float(o["reuse_radius"]))
        set_uniform(prog, "u_mis", MIS_MODES[o["reuse_mis"]])
        set_uniform(prog, "u_vis_reuse", 1 if o["reuse_visibility"] else 0)
        set_uniform(prog, "u_eps", float(o["eps"]))
        h_dst.bind_to_image(IMAGE_UNIT_REUSE_RESERVOIR, read=False, write=True)
        g_dst.bind_to_image(IMAGE_UNIT_REUSE_SURFACE, read=False, write=True)
        with frame.timings_scope("stb_lighting"):
            method.fullscreen_pass(frame, prog, "lighting")
        frame.ctx.memory_barrier()
        if area_pass:
            self._area(method, frame, ldefines, h_dst)

    def _area_list_reset(self, frame: FrameContext) -> None:
        """Bind the area pass's pixel list (a count and one uint per pixel), count 0."""
        w, h = frame.buffers.size
        need = 4 * (1 + int(w) * int(h))
        if self._area_list is None or self._area_list.size < need:
            if self._area_list is not None:
                self._area_list.release()
            self._area_list = frame.ctx.buffer(reserve=need)
        self._area_list.write(np.zeros(1, dtype=np.uint32).tobytes())
        self._area_list.bind_to_storage_buffer(SSBO_STB_REUSE_AREA)

    def _area(
        self, method: Any, frame: FrameContext, defines: dict[str, Any], hist: moderngl.Texture
    ) -> None:
        """``stb_reuse_area.frag``: shade the listed pixels' area-path picks into the
        lighting outputs, one fragment per listed pixel over a viewport as wide as the
        frame and as tall as the list needs (its count read back: 4 bytes)."""
        assert self._area_list is not None
        count = int(np.frombuffer(self._area_list.read(4), dtype=np.uint32)[0])
        self.last_area_pixels = count
        if count == 0:
            return
        bufs = frame.buffers
        w, h = (int(v) for v in bufs.size)
        prog = program(frame, "stb_reuse_area.frag", defines)
        method.bind_common(frame, prog)
        set_uniform(prog, "u_list_width", w)
        set_uniform(prog, "u_vis_reuse", 1 if method.o["reuse_visibility"] else 0)
        hist.bind_to_image(IMAGE_UNIT_REUSE_RESERVOIR, read=True, write=True)
        bufs.textures[PARTIAL].bind_to_image(IMAGE_UNIT_REUSE_PARTIAL, read=True, write=False)
        bufs.textures["lighting"].bind_to_image(IMAGE_UNIT_REUSE_OUT_COLOR, read=False, write=True)
        if "TAA_DEMOD_OUT" in defines:
            units = (IMAGE_UNIT_REUSE_OUT_DEMOD, IMAGE_UNIT_REUSE_OUT_ALBEDO)
            for unit, t in zip(units, TAA_INPUTS, strict=True):
                bufs.textures[t.name].bind_to_image(unit, read=False, write=True)
        if self._area_fbo is None or self._area_fbo.size != (w, h):
            if self._area_fbo is not None:
                self._area_fbo.release()
            self._area_fbo = frame.ctx.empty_framebuffer((w, h))
        with frame.timings_scope("stb_reuse_area"):
            draw_fullscreen(frame.ctx, prog, self._area_fbo, (w, -(-count // w)))
        frame.ctx.memory_barrier()

    def _slots(
        self, method: Any, frame: FrameContext, defines: dict[str, Any], big: moderngl.Texture
    ) -> tuple[moderngl.Texture, ...]:
        """``stb_reuse_slots.frag``: each big-tile slot's half of the initial target
        (``-o reuse_target=tile``), three rgba32f textures in the big tiles' layout, and
        the r32ui link masks in scenes with light links."""
        bufs = frame.buffers
        texs = tuple(bufs.texture(n, 4, "f4", size=big.size) for n in SLOTS)
        names = list(SLOTS)
        if method.light_links:
            texs += (bufs.texture(SLOT_LINK, 1, "u4", size=big.size),)
            names.append(SLOT_LINK)
        grid = slot_grid(method.big_px)
        prog = program(frame, "stb_reuse_slots.frag", dict(defines, STB_REUSE_SLOT_GRID=grid))
        method._common_uniforms(frame, prog)
        unit = method.bind_common(frame, prog)
        method._bind(frame, prog, unit, "u_bigtile", big)
        method._bind(frame, prog, TEX_UNIT_HIZ, "u_hiz", method.big_tile_hiz(frame))
        method._pass(frame, prog, names, big.size)
        return texs

    def _finish(
        self, frame: FrameContext, rows: np.ndarray, n_rows: int, reason: str, dst: int
    ) -> None:
        """Remember this frame for the next one's temporal reuse."""
        self._prev_view = frame.view
        self._prev_rows = rows.copy()
        self._n_rows = n_rows
        self.count = 1 if reason else self.count + 1
        self._parity = dst

    def debug_inputs(self) -> tuple[str, str]:
        """Render buffers of the last frame the debug views read: its reservoirs after
        temporal reuse, and the reservoirs it stored (after spatial reuse)."""
        return CURRENT, HISTORY[self._parity]

    def release(self) -> None:
        if self._remap is not None:
            self._remap.release()
            self._remap = None
        if self._area_list is not None:
            self._area_list.release()
            self._area_list = None
        if self._area_fbo is not None:
            self._area_fbo.release()
            self._area_fbo = None
        self.count = 0
