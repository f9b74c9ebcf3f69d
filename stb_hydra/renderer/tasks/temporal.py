"""Temporal reuse for a moving camera (``RenderSettings.temporal == "taa"``).

Reprojects last frame's history with the G-buffer's motion vectors (camera motion
and animated transforms), rejects it where the surface was not visible (previous
depth and normal) and clips it against the statistics of a depth-weighted
neighbourhood of albedo-demodulated lighting, then blends 1/n with a per-pixel
history length n (``shaders/temporal.frag`` says how; the lighting pass writes this
frame's demodulated lighting + depth, ``taa_demod``, and albedo, ``taa_albedo``,
beside its radiance: ``lighting.base.TAA_INPUTS``, so the neighbourhood is one fetch
a tap and no pass of its own re-reads the G-buffer). History lives in
ping-pong buffers (``taa_hist_*``: demodulated lighting + n; ``taa_geo_*``: depth +
normal) and survives across frames of an engine; it is dropped on the first frame,
a viewport resize, a camera cut (a large view change: :func:`is_camera_cut`) and a
change of the light table (a light switched off, moved or re-coloured must not
linger: ``LightTable.version``).

Subpixel jitter: :func:`halton_jitter` gives the camera's per-frame offset (the
engine applies it through ``view_setup(jitter=...)``); motion vectors are made
unjittered here by subtracting this frame's jitter (the previous view-projection
the G-buffer uses is the unjittered one)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import moderngl
import numpy as np

from ... import limits
from ..camera import ViewSetup
from ..frame import FrameContext
from ..fullscreen import draw_fullscreen
from ..gl import set_uniform, shader_library
from ..graph import Imported, Rec, Tex
from ..lighting.base import TAA_INPUTS
from ..records import FrameBlock, SceneColor
from .base import Pass

if TYPE_CHECKING:
    from ..gl_delegate import GLRenderDelegate
    from ..light_table import LightTable

HISTORY = ("taa_hist_a", "taa_hist_b")
GEOMETRY = ("taa_geo_a", "taa_geo_b")
#: The display colour of a taa frame (``SceneColor.buffer``).
OUTPUT = "taa_color"
#: Lighting / albedo + linear depth; albedo + lighting alpha of this frame (written
#: by the lighting pass, ``shaders/common/lighting_out.glsl``).
DEMOD, ALBEDO = (t.name for t in TAA_INPUTS)

#: History length cap (frames) of a moving / a still pixel (its surface moved by
#: less than half a pixel): the noise falls like a 1/n average up to this many
#: frames, then like an exponential average with weight 1/MAX. Measured on the
#: courtyard (96x54, 64 still frames, relMSE against the jittered reference):
#: 32/2.0 gave 0.125, 64/2.0 0.100, 64/4.0 0.074, 64/8.0 0.062, no clipping 0.061
#: (accumulate 0.034; before the edge-aware disocclusion test): every clip of noisy
#: input is a bias, so a still pixel clips less (8 sigma: lighting changes are
#: caught by the light caps and disocclusion, not the box).
MAX_HISTORY = (32, 64)
#: Clip box half extent (standard deviations of the neighbourhood, or of the pixel's
#: own temporal spread where larger): moving / still pixel. Moving 3 rather than 2
#: once moving pixels blend the neighbourhood mean (CURRENT_WEIGHT_MOVING): orbits of
#: issue 14 at 320x180, 60 frames, HDR-FLIP / instability: courtyard 0.176 / 1.39x ->
#: 0.168 / 1.29x, 256-light chess 0.306 / 1.42x -> 0.300 / 1.23x; the sliding box of
#: tests/test_temporal.py still settles within 8 frames (the uncovered floor is still).
CLIP_GAMMA = (3.0, 8.0)
#: Weight of a moving pixel's own sample in what it blends into its history, against
#: the depth-weighted 13-tap neighbourhood mean (a still pixel: 1, its own sample; in
#: between by how far the surface moved, as for the box). Measured on the orbits of
#: issue 14 (320x180, 60 frames, 1 deg/frame, frames 8+; HDR-FLIP / relMSE / temporal
#: instability over the reference's): courtyard 1.0: 0.179 / 0.93 / 1.68x, 0.25: 0.176
#: / 0.32 / 1.42x, 0.125: 0.176 / 0.26 / 1.41x, 0: 0.176 / 0.22 / 1.39x; 256-light
#: chess 1.0: 0.314 / 0.19 / 1.90x, 0.25: 0.308 / 0.10 / 1.50x, 0.125: 0.307 / 0.09 /
#: 1.46x, 0: 0.306 / 0.08 / 1.42x. The mean's blur (lighting only: the input is
#: demodulated; within 2 px) goes once the camera stops.
CURRENT_WEIGHT_MOVING = 0.0
#: Camera cut: the view direction turned by more than this (degrees) or the
#: camera moved by more than this fraction of the scene's diagonal in one frame.
CUT_ANGLE_DEG = 30.0
CUT_MOVE_FRACTION = 0.25
#: Light changes that shorten the history where the light reaches (its influence
#: sphere, grown by how far it moved): (history cap, relative intensity change,
#: move as a fraction of its range, cos of the turn). The first row that applies
#: wins; smaller changes (a flicker of a few %) are left to the clip box.
LIGHT_CHANGE_RULES = ((1, 0.5, 0.25, 0.9), (8, 0.2, 0.05, 0.99))
#: Changed lights passed to the shader; more than this: the smallest cap everywhere.
MAX_LIGHT_CHANGES = limits.MAX_LIGHT_CHANGES
#: Light-table columns whose change is a switch (history cap 1).
_LIGHT_EXACT = ("enabled", "live", "type", "emission", "ies_layer")
#: Jitter sequence length (Halton 2, 3).
JITTER_PERIOD = 16


def _halton(i: int, base: int) -> float:
    f, r = 1.0, 0.0
    while i > 0:
        f /= base
        r += f * (i % base)
        i //= base
    return r


def halton_jitter(frame_index: int) -> tuple[float, float]:
    """Subpixel camera offset (px, in (-0.5, 0.5)) of a frame: Halton (2, 3)."""
    i = frame_index % JITTER_PERIOD + 1
    return _halton(i, 2) - 0.5, _halton(i, 3) - 0.5


def light_changes(
    before: dict[str, np.ndarray] | None, table: LightTable
) -> tuple[np.ndarray, np.ndarray] | None:
    """Lights that changed a lot since the ``before`` snapshot (:func:`light_snapshot`):
    ``(spheres (k, 4): centre xyz + radius, caps (k,))``, the history-length cap
    inside each sphere (``LIGHT_CHANGE_RULES``: a light switched on or off, added,
    removed or re-typed gets cap 1 over its whole influence range). None: nothing to
    compare with (the history is dropped everywhere). Rows rewritten with the same
    values (every time change does that) are no change."""
    if before is None:
        return None
    now = light_snapshot(table)
    n = len(now["enabled"])
    if len(before["enabled"]) != n:
        return None
    on0 = before["enabled"] & before["live"]
    on1 = now["enabled"] & now["live"]
    cap = np.full(n, np.inf)
    switched = np.zeros(n, dtype=bool)
    for k in _LIGHT_EXACT:
        a, b = before[k], now[k]
        switched |= (a != b) if a.ndim == 1 else np.any(a != b, axis=1)
    i0 = np.linalg.norm(np.asarray(before["intensity"], np.float64), axis=1)
    i1 = np.linalg.norm(np.asarray(now["intensity"], np.float64), axis=1)
    rel = np.abs(i1 - i0) / np.maximum(np.maximum(i0, i1), 1e-30)
    rng = np.maximum(np.asarray(now["range"], np.float64), np.asarray(before["range"], np.float64))
    moved = np.linalg.norm(now["position"] - before["position"], axis=1)
    move = moved / np.maximum(rng, 1e-3)
    d0 = np.asarray(before["direction"], np.float64)
    d1 = np.asarray(now["direction"], np.float64)
    norms = np.linalg.norm(d0, axis=1) * np.linalg.norm(d1, axis=1)
    cos = np.where(norms > 0, np.sum(d0 * d1, axis=1) / np.maximum(norms, 1e-30), 1.0)
    for c, di, dm, dc in reversed(LIGHT_CHANGE_RULES):
        hit = (rel > di) | (move > dm) | (cos < dc)
        cap[hit] = c
    cap[switched] = LIGHT_CHANGE_RULES[0][0]
    cap[~(on0 | on1)] = np.inf  # off before and after: nothing to see
    rows = np.nonzero(np.isfinite(cap))[0]
    if not len(rows):
        return np.zeros((0, 4)), np.zeros(0)
    centre = np.asarray(now["position"], np.float64)[rows]
    radius = np.minimum(rng[rows] + moved[rows], 1e30)
    return np.column_stack([centre, radius]), cap[rows]


def light_snapshot(table: LightTable) -> dict[str, np.ndarray]:
    """The light-table columns :func:`lights_changed` compares (copies)."""
    n = table.n_rows
    keys = (*_LIGHT_EXACT, "intensity", "range", "position", "direction")
    return {k: np.array(table.cols[k][:n]) for k in keys}


def is_camera_cut(prev: ViewSetup, cur: ViewSetup, scene_diagonal: float) -> bool:
    """A view change too large to reproject (a cut, not motion)."""
    cosang = float(np.clip(np.dot(prev.forward, cur.forward), -1.0, 1.0))
    if math.degrees(math.acos(cosang)) > CUT_ANGLE_DEG:
        return True
    move = float(np.linalg.norm(cur.position - prev.position))
    if move > CUT_MOVE_FRACTION * max(scene_diagonal, 1e-6):
        return True
    if prev.orthographic != cur.orthographic:
        return True
    pt, ct = np.asarray(prev.tan_half), np.asarray(cur.tan_half)
    return bool(np.any(np.abs(ct - pt) > 0.05 * np.abs(pt)))


class TemporalTask(Pass):
    name = "temporal"
    reads = (
        *TAA_INPUTS,
        Tex("g_normal", "rg16f"),
        Tex("g_motion", "rg16f"),
        Rec(SceneColor),
        Rec(FrameBlock),
        Imported("light_table"),
    )
    writes = (
        Rec(SceneColor),
        Tex(OUTPUT, "rgba16f"),
        *(Tex(n, "rgba32f") for n in HISTORY),
        *(Tex(n, "rgba32f") for n in GEOMETRY),
    )

    def __init__(
        self, delegate: GLRenderDelegate, max_history: tuple[int, int] = MAX_HISTORY
    ) -> None:
        super().__init__(delegate)
        self.max_history = max_history
        self.count = 0
        self._parity = 0
        self._prev_view: ViewSetup | None = None
        self._size: tuple[int, int] | None = None
        self._light_version: int | None = None
        self._lights: dict[str, np.ndarray] | None = None
        self._changes: tuple[np.ndarray, np.ndarray] = (np.zeros((0, 4)), np.zeros(0))
        #: Why the history was dropped on the last frame ("" = kept).
        self.last_reset = ""

    @property
    def latest(self) -> tuple[str, str]:
        """(history, geometry) textures the last frame wrote (``tasks/taa_filter.py``)."""
        return HISTORY[self._parity], GEOMETRY[self._parity]

    def reset(self) -> None:
        """Forget the history (the next frame starts from its own samples)."""
        self.count = 0

    def _reset_reason(self, frame: FrameContext) -> str:
        """Why the history is dropped everywhere this frame ("" = kept); sets
        ``self._changes`` (lights that changed: spheres and history caps)."""
        size = tuple(frame.buffers.size)
        table = self.delegate.light_table
        version = int(table.version)
        reason = ""
        self._changes = (np.zeros((0, 4)), np.zeros(0))
        if version != self._light_version:
            changes = light_changes(self._lights, table)
            self._lights = light_snapshot(table)
            if changes is None:
                reason = "lights"
            else:
                self._changes = changes
        self._light_version = version
        if self.count == 0 or self._prev_view is None:
            reason = "start"
        elif size != self._size:
            reason = "resize"
        elif not reason:
            lo, hi = self.delegate.scene_bounds
            diag = float(np.linalg.norm(np.asarray(hi) - np.asarray(lo)))
            if not math.isfinite(diag) or diag <= 0.0:
                diag = 1.0
            if is_camera_cut(self._prev_view, frame.view, diag):
                reason = "cut"
        self._size = (int(size[0]), int(size[1]))
        return reason

    def execute(self, frame: FrameContext) -> None:
        ctx = frame.ctx
        bufs = frame.buffers
        reason = self._reset_reason(frame)
        self.last_reset = reason
        frame.stats["temporal_reset"] = reason
        src = self._parity
        h_src, h_dst = HISTORY[src], HISTORY[1 - src]
        g_src, g_dst = GEOMETRY[src], GEOMETRY[1 - src]
        tex = bufs.textures
        hist = tex[h_src]
        hist.filter = (moderngl.LINEAR, moderngl.LINEAR)  # Catmull-Rom's bilinear taps
        prog = shader_library(ctx).program("fullscreen.vert", "temporal.frag")
        units = (
            ("u_demod", DEMOD),
            ("u_albedo", ALBEDO),
            ("u_normal", "g_normal"),
            ("u_motion", "g_motion"),
            ("u_history", h_src),
            ("u_prev_geo", g_src),
        )
        for unit, (uniform, name) in enumerate(units):
            tex[name].use(unit)
            set_uniform(prog, uniform, unit)
        prev = self._prev_view if self._prev_view is not None else frame.view
        set_uniform(prog, "u_prev_view", np.ascontiguousarray(prev.view, dtype=np.float64))
        set_uniform(prog, "u_jitter", tuple(float(j) for j in frame.view.jitter))
        set_uniform(prog, "u_reset", 1.0 if reason else 0.0)
        spheres, caps = self._changes
        max_len = tuple(float(m) for m in self.max_history)
        if len(caps) > MAX_LIGHT_CHANGES:  # too many to test per pixel: cap everywhere
            max_len = tuple(min(m, float(caps.min())) for m in max_len)
            spheres, caps = spheres[:0], caps[:0]
        frame.stats["temporal_light_changes"] = len(caps)
        set_uniform(prog, "u_max_len", max_len)
        set_uniform(prog, "u_light_changes", len(caps))
        if len(caps):
            sph = np.zeros((MAX_LIGHT_CHANGES, 4), np.float32)
            cap = np.ones(MAX_LIGHT_CHANGES, np.float32)
            sph[: len(caps)] = np.minimum(spheres, 1e30)
            cap[: len(caps)] = caps
            set_uniform(prog, "u_light_spheres", sph)
            set_uniform(prog, "u_light_caps", cap)
        set_uniform(prog, "u_gamma", CLIP_GAMMA)
        set_uniform(prog, "u_cur_weight", CURRENT_WEIGHT_MOVING)
        fbo = bufs.framebuffer(f"fb_taa_{1 - src}", [OUTPUT, h_dst, g_dst])
        draw_fullscreen(ctx, prog, fbo, bufs.size)
        hist.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self._prev_view = frame.view
        self.count = 1 if reason else self.count + 1
        self._parity = 1 - src
        frame.put(SceneColor(OUTPUT))
