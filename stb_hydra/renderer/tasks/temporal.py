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
from ..frame import FrameContext, RenderSettings
from ..fullscreen import draw_fullscreen
from ..gl import set_uniform, shader_library
from ..graph import Imported, Rec, Tex
from ..light_changes import Rule, change_uniforms, light_changes, light_snapshot
from ..lighting import validate_options
from ..lighting.base import TAA_INPUTS
from ..records import FrameBlock, SceneColor
from .base import Pass

if TYPE_CHECKING:
    from ..gl_delegate import GLRenderDelegate

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
#: Under STB's reservoir reuse (``-o reuse=on``, issue 31), whose input is much less
#: noisy than STB's: a moving pixel's history cap (frames; MAX_HISTORY[0] otherwise) and
#: its own sample's weight (CURRENT_WEIGHT_MOVING otherwise). The long history and the
#: neighbourhood mean that keep STB's tile noise from flickering blur and drag the
#: reuse's sharper lighting (docs/STB_NOTES.md "(taa13)"). Opt-in reuse orbits at
#: 320x180, HDR-FLIP / instability (frames 8+): (32, 0) -> (8, 0.25): courtyard 0.1131 /
#: 1.14x -> 0.1088 / 1.20x, 256-light chess 0.1972 / 0.81x -> 0.1830 / 0.84x; (8, 0):
#: courtyard 0.1098 / 1.15x; (8, 0.5): 0.1085 / 1.32x, chess 0.1804.
REUSE_MOVING = (8.0, 0.25)
#: Under the reuse: each pixel's history cap from its specular lobe, (k, least frames):
#: k x the lobe's width (GGX alpha = roughness^2, radians) over the angle (radians) the
#: view direction at the surface turned since the previous frame. A highlight slides
#: over the surface by about that angle a frame, so history older than that holds it
#: where it was: the lag that reprojection by the surface's motion cannot follow (the
#: chess orbit's error grew along the orbit; NRD's specular history is capped by
#: roughness and parallax alike). A still camera turns nothing: no cap. Orbits as above
#: with (8, 0.25), (0.5, 4): chess 0.1830 -> 0.1698 / 0.91x, courtyard 0.1088 -> 0.1089
#: (its surfaces are rough); (1, 4) 0.1714, (0.25, 4) 0.1701, (0.5, 3) 0.1685 / 0.95x.
REUSE_LOBE = (0.5, 4.0)
#: An old texel that is not this pixel's surface is still kept as "an edge the jitter
#: crosses" (a 3x3 neighbour shows its surface now) only if that neighbour's motion
#: brings the texel within this many px of the pixel (per axis; equal motion gives
#: < 1). Without it the floor a sliding box uncovered took the box's history from the
#: box's trailing side (tests/test_temporal.py's box with the opt-in reuse configuration
#: of issue 31, seed 0: the uncovered floor's error 8 frames on 0.103 -> 0.054, with
#: PLANE_TOLERANCE 0.049, a whole-history restart 0.037; the still courtyard unchanged:
#: docs/STB_NOTES.md "(reuse6)").
EDGE_MOTION_SLACK = 2.0
#: Same-surface test: the old texel's point within this many pixel footprints of the
#: pixel's tangent plane (as well as 3 % of its depth); 0: no plane test. Catches a
#: face that met this surface at a crease (a box's side standing on the floor: within
#: 3 % of the floor's depth near it). Sliding box, opt-in configuration, three seeds:
#: late error 1.49x -> 1.34x a restart's; still courtyard relMSE taa / accumulate 1.19x
#: -> 1.22x (docs/STB_NOTES.md "(reuse6)").
PLANE_TOLERANCE = 0.25
#: Young history (issue 31, docs/STB_NOTES.md "(taa8)"): a pixel whose history is
#: shorter than YOUNG_LEN frames (a disocclusion; not a light change's cap) shows its
#: history mixed with a Savitzky-Golay estimate of it from its neighbours (a quadratic
#: least-squares fit over the YOUNG_GRID taps, :func:`young_weights`; each tap is
#: the neighbour's reprojected history blended with its current sample), with weight
#: YOUNG_WEIGHT tapering linearly to 0 at YOUNG_LEN frames; only where the whole
#: neighbourhood is the pixel's tangent plane (within YOUNG_PLANE pixel footprints per px of
#: offset, now and in the previous view). Display only: the history keeps its own
#: samples, so a still image converges as before. A plain (Gaussian) mean instead
#: blurred the sliding box's floor, lit by a near light's hot spot, more than its noise
#: (uncovered-floor error 0.074 -> 0.133 at the uncovering). Sliding box with the opt-in
#: reuse configuration (tests/test_stb_reuse.py, three seeds): YOUNG_LEN 16 / 20 / 24
#: / 32 settle in 7 / 9 / 7 / 9 frames (a longer length lowers the still level too).
#: YOUNG_LEN 0: off.
YOUNG_LEN = 24.0
YOUNG_WEIGHT = 0.85
YOUNG_PLANE = 0.5
#: Edge-left cap (frames; 0: off): a history taken with an edge beside the pixel for at
#: least EDGE_RUN frames in a row (a 3x3 neighbour off its tangent plane, by YOUNG_PLANE,
#: and more than 5 % deeper or nearer or moving against it by more than
#: sqrt(EDGE_MOTION_SQ) px) is capped at EDGE_LEFT_CAP where the whole 13-tap
#: neighbourhood is now that plane: the edge left by more than the jitter moves it, and
#: the history mixes the two surfaces (the sliding box's far top edge: docs/STB_NOTES.md
#: "(reuse6)" and "(taa8)"; late error 1.34x -> 1.08x a restart's). Still courtyard
#: (96x54, 64 frames) relMSE taa / accumulate 1.216x -> 1.207x; without the run and with
#: texels of the footprint the bilinear weights ignore it was 1.58x (jitter edges).
EDGE_LEFT_CAP = 1.0
EDGE_MOTION_SQ = 0.25
EDGE_RUN = 8.0
#: May a nearer surface's history be lent to a moving pixel as "an edge the jitter
#: crosses" (1: yes, before taa11; 0: no)? A foreground silhouette moving over the
#: surface behind it (parallax) left its light as a trail on the background it uncovered:
#: the uncovered pixels were lent the occluder's history and the clip box, widened by
#: that history's own temporal spread, kept it (issue 31, docs/STB_NOTES.md "(taa10)",
#: "(taa11)"). With 0 such a pixel borrows its own surface's history from beside it or
#: starts again; a still pixel keeps the jitter's edges (its antialiasing). Orbits at
#: 320x180, HDR-FLIP / instability, 1 -> 0: 256-light chess, exact lighting + taa 0.2118
#: / 0.85x -> 0.1837 / 0.81x, opt-in reuse 0.2287 -> 0.2003; courtyard, STB defaults
#: 0.1721 / 1.28x -> 0.1665 / 1.26x (relMSE 0.379 -> 0.465: early frames).
LENT_FROM_NEARER = 0.0
#: A moving pixel's history lent by a neighbour's surface (an edge the jitter crosses, a
#: ``borrow_history`` history): weight of its temporal spread in the clip box and in the
#: second moment kept (1: as its own history's; a still pixel always 1), (under other
#: lighting, under STB's reservoir reuse ``-o reuse=on``). That spread is partly the
#: neighbour's and that between the two surfaces. 0 measured under STB defaults made the
#: courtyard orbit flicker more (1.28x -> 1.46x: the widening is what keeps STB's
#: tile-shared noise from being clipped back each frame), so it applies to the reuse's
#: input only (issue 31, docs/STB_NOTES.md "(taa10)", "(taa12)"). Opt-in reuse orbits at
#: 320x180, HDR-FLIP / instability, 1 -> 0: 256-light chess 0.2003 / 0.83x -> 0.1972 / 0.81x,
#: courtyard 0.1177 / 1.12x -> 0.1131 / 1.14x (0.5: 0.1997, 0.1169).
LENT_SPREAD_MOVING = (1.0, 0.0)


#: The 13-tap neighbourhood of temporal.frag (``TAPS``: the pixel, its 3x3, 4 taps at
#: distance 2 on the axes), in the shader's order (px offsets x, y).
NEIGHBOURHOOD = (
    (0, 0), (-1, -1), (0, -1), (1, -1), (-1, 0), (1, 0), (-1, 1), (0, 1), (1, 1),
    (-2, 0), (2, 0), (0, -2), (0, 2),
)  # fmt: skip


#: The young-history estimate's taps (temporal.frag ``young_estimate``): a 5x5 grid,
#: row-major (y, then x). 1 / sum(w^2) = 175/27 = 6.5 independent taps against the 13
#: taps' 11/3, which settled the sliding box in 9 frames instead of 7 (docs/STB_NOTES.md
#: "(taa8)").
_YR = limits.TAA_YOUNG_GRID // 2
YOUNG_GRID = tuple((x, y) for y in range(-_YR, _YR + 1) for x in range(-_YR, _YR + 1))


def young_weights(taps: tuple[tuple[int, int], ...] = NEIGHBOURHOOD) -> np.ndarray:
    """(len(taps),) weights of the centre value (offset (0, 0)) of a least-squares
    quadratic (1, x, y, x^2, xy, y^2) through samples at ``taps`` (px offsets): a 2D
    Savitzky-Golay filter. Sums to 1 and is exact for quadratics; for the 13 taps
    1 / sum(w^2) = 11/3 independent taps (a 5x5 grid: 175/27 = 6.5, at twice the
    fetches)."""
    x, y = (np.array(v, dtype=np.float64) for v in zip(*taps))
    basis = np.stack([np.ones_like(x), x, y, x * x, x * y, y * y], axis=1)
    return np.linalg.pinv(basis)[0]


#: Camera cut: the view direction turned by more than this (degrees) or the
#: camera moved by more than this fraction of the scene's diagonal in one frame.
CUT_ANGLE_DEG = 30.0
CUT_MOVE_FRACTION = 0.25
#: Light changes that shorten the history where the light reaches (its influence
#: sphere, grown by how far it moved): (history cap, relative intensity change,
#: move as a fraction of its range, cos of the turn). The first row that applies
#: wins; smaller changes (a flicker of a few %) are left to the clip box
#: (``renderer/light_changes.py``).
LIGHT_CHANGE_RULES: tuple[Rule, ...] = ((1, 0.5, 0.25, 0.9), (8, 0.2, 0.05, 0.99))
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


def lit_by_reuse(settings: RenderSettings) -> bool:
    """The frame's lighting is STB with reservoir reuse (``-o reuse=on``)."""
    if settings.lighting != "stb":
        return False
    return bool(validate_options("stb", settings.method_options)["reuse"])


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


_YOUNG_C = young_weights(YOUNG_GRID).astype(np.float32)


class TemporalTask(Pass):
    name = "temporal"
    reads = (
        *TAA_INPUTS,
        Tex("g_normal", "rg16f"),
        Tex("g_motion", "rg16f"),
        Tex("g_base_rough", "rgba16f"),
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
            now = light_snapshot(table)
            before = self._lights
            if before is None or len(before["enabled"]) != len(now["enabled"]):
                reason = "lights"  # nothing to compare with (rows added or removed)
            else:
                self._changes = light_changes(before, now, LIGHT_CHANGE_RULES, _LIGHT_EXACT)
            self._lights = now
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
        reuse = lit_by_reuse(frame.settings)
        lobe_cap = reuse and REUSE_LOBE[0] > 0
        # the reuse's variant compiles the specular-lobe cap in (REUSE_LOBE)
        defines: dict[str, object] | None = {"TAA_LOBE_CAP": 1} if lobe_cap else None
        prog = shader_library(ctx).program("fullscreen.vert", "temporal.frag", defines)
        units = (
            ("u_demod", DEMOD),
            ("u_albedo", ALBEDO),
            ("u_normal", "g_normal"),
            ("u_motion", "g_motion"),
            ("u_history", h_src),
            ("u_prev_geo", g_src),
            ("u_base_rough", "g_base_rough"),
        )
        for unit, (uniform, name) in enumerate(units):
            tex[name].use(unit)
            set_uniform(prog, uniform, unit)
        prev = self._prev_view if self._prev_view is not None else frame.view
        set_uniform(prog, "u_prev_view", np.ascontiguousarray(prev.view, dtype=np.float64))
        set_uniform(prog, "u_prev_tan", tuple(float(v) for v in (*prev.tan_half, *prev.offset)))
        set_uniform(prog, "u_jitter", tuple(float(j) for j in frame.view.jitter))
        set_uniform(prog, "u_reset", 1.0 if reason else 0.0)
        spheres, caps = self._changes
        sph, cap, everywhere = change_uniforms(spheres, caps, MAX_LIGHT_CHANGES)
        max_len = tuple(float(m) for m in self.max_history)
        cur_weight = CURRENT_WEIGHT_MOVING
        if reuse:  # the reuse's cleaner input: a shorter moving history, its own samples
            max_len = (min(max_len[0], REUSE_MOVING[0]), max_len[1])
            cur_weight = REUSE_MOVING[1]
        if lobe_cap:
            eye = -prev.forward if prev.orthographic else prev.position
            set_uniform(prog, "u_prev_eye", (*(float(v) for v in eye), float(prev.orthographic)))
            set_uniform(prog, "u_lobe", REUSE_LOBE)
        n = len(caps)
        if everywhere is not None:  # too many to test per pixel: cap everywhere
            max_len = tuple(min(m, everywhere) for m in max_len)
            n = 0
        frame.stats["temporal_light_changes"] = n
        set_uniform(prog, "u_max_len", max_len)
        set_uniform(prog, "u_light_changes", n)
        if n:
            set_uniform(prog, "u_light_spheres", sph)
            set_uniform(prog, "u_light_caps", cap)
        set_uniform(prog, "u_gamma", CLIP_GAMMA)
        set_uniform(prog, "u_cur_weight", cur_weight)
        set_uniform(prog, "u_edge_slack", EDGE_MOTION_SLACK)
        set_uniform(prog, "u_lent_near", LENT_FROM_NEARER)
        set_uniform(prog, "u_lent_spread", LENT_SPREAD_MOVING[reuse])
        set_uniform(prog, "u_plane_tol", PLANE_TOLERANCE)
        set_uniform(prog, "u_young", (YOUNG_LEN, YOUNG_WEIGHT, YOUNG_PLANE, EDGE_LEFT_CAP or 1e9))
        set_uniform(prog, "u_young_c", _YOUNG_C)
        set_uniform(prog, "u_edge_motion", EDGE_MOTION_SQ)
        set_uniform(prog, "u_edge_run", (EDGE_RUN, float(limits.TAA_EDGE_RUN_MAX)))
        fbo = bufs.framebuffer(f"fb_taa_{1 - src}", [OUTPUT, h_dst, g_dst])
        draw_fullscreen(ctx, prog, fbo, bufs.size)
        hist.filter = (moderngl.NEAREST, moderngl.NEAREST)
        self._prev_view = frame.view
        self.count = 1 if reason else self.count + 1
        self._parity = 1 - src
        frame.put(SceneColor(OUTPUT))
