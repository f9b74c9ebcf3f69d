"""`stb`: Stochastic Tile-Based lighting (Lempiainen, SIGGRAPH 2025), pass by pass.

1. Big-tile sampling (``stb_bigtile.frag``): per 128 px big tile, K reservoir
   slots filled by stratified reservoir sampling over the FoV lights with the
   target Phi / d^2 to the tile's central depth segment; 32-bit samples in a
   block of texels per big tile (4x4 for K = 16).
2. Small-tile resampling (``stb_smalltile.frag``): per 16 px small tile
   (interleaved 4 per 32 px footprint with the shipped Gaussian-Poisson quad
   patterns, offset per frame), stochastic bilinear big-tile choice, SRS of N
   samples with the refined 4-quad target. One RGBA32UI texel per small tile.
3. Deferred shadow terms (``stb_shadow.frag``): one 8-bit term per (quad,
   sample) in a block per small tile: shadow x cone x normalised IES.
4. Lighting (``stb_lighting.frag``): per pixel its tile's N samples, fixed cost.

Options (``method_options`` / CLI): ``K`` (4..64), ``N`` (1..4), ``big_tile``
(px, power of two 16..256; 16: the reuse's still configuration), ``small_tile`` (16
with interleaving; any even power of two without), ``eps``, ``weight_cap`` (None/<=0 = unbiased),
``interleave``, ``stochastic_bilinear``, ``target`` ("segment" | "uniform"),
``pdf_floor`` (defensive mixture weight of the small-tile target, see below),
``shadow_res`` ("quad": one term per 2x2 quad, the talk's; "pixel": full
resolution, exact at shadow/cone edges at ~4x the shadow-pass cost), ``select``
("all": every pixel shades its tile's N samples, the talk's; "quad"/"pixel": one of N
independent picks per quad/pixel; "ris": each pixel resamples the N picks by a cheap
target x the quad's term and shades one -- see docs/STB_NOTES.md, fourth pass),
``reuse`` (issue 31: per-pixel reservoirs resampled from the small tile's N samples and
reused over frames and neighbours, ReSTIR-style, in place of the term and lighting
passes; ``reuse_*`` options, ``lighting/stb_reuse.py``; off by default).

Where we differ from the talk (see docs/STB_NOTES.md): the small-tile target is
a defensive mixture ``p_hat + pdf_floor x mean(p_hat over the K candidates)``,
so a light that lights some pixel of a tile but none of its 4 sampled points
stays selectable with a bounded weight (unbiased; the talk accepts this bias);
small tiles redraw sample points that fall off screen or on background; empty big tiles are filled
with the full view ray as segment (stochastic bilinear selection uses them);
the 8-bit terms use stochastic rounding; samples pack a 17-bit index and a
15-bit log2 weight instead of fp16.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, ClassVar, cast

import moderngl
import numpy as np

from ... import limits
from ..fullscreen import draw_fullscreen
from ..gl import set_uniform, shader_library
from ..graph import DERIVED, Rec, Resource, Tex
from ..light_buffer import pack_lights
from ..records import DistantLights, FrameBlock, InViewLights, LightBuffer
from ..shader_constants import (
    IMAGE_UNIT_BIGTILE,
    IMAGE_UNIT_PIXEL_TERMS,
    INTERLEAVE_FOOTPRINT_PX,
    INTERLEAVE_QUADS_PER_SIDE,
    QUAD_FWD_Y_SHIFT,
    QUAD_LUT_SLOT_SHIFT,
    SSBO_STB_CLUSTER_CDF,
    SSBO_STB_CLUSTER_LIGHTS,
    SSBO_STB_CLUSTER_RECORDS,
    SSBO_STB_CLUSTERS,
    TEX_UNIT_HIZ,
)
from ..tasks.base import Pass
from .base import LightingMethod, Warn, program
from .light_clusters import LightClusters, build_clusters
from .options import Auto, Opt, OptionError, Schema
from .quad_patterns import QuadPatterns, fixed_pattern, pattern_bank
from .stb_reuse import ReuseStage, reuse_textures
from .tiled import SSBOPool

if TYPE_CHECKING:
    from ..frame import FrameContext
    from ..gl_delegate import GLRenderDelegate

#: Big-tile target functions: the talk's central segment, uniform (comparison), shaped
#: (segment x emission, cone and IES, zero where the light cannot reach the tile).
TARGET_MODES = {"segment": 0, "uniform": 1, "shaped": 2}

#: Slot block (columns, rows) per big tile for each allowed K.
SLOT_BLOCKS = {4: (2, 2), 8: (4, 2), 16: (4, 4), 32: (8, 4), 64: (8, 8)}


def _share_fits(o: Mapping[str, Any]) -> bool:
    """``reuse_res=share`` is possible with these options: the default of ``reuse_res``
    (reuse_k and reuse_target may not be resolved yet: a given reuse_k > 0 asks for
    spatial reuse) and ``check_options``'s rule. Share has no spatial reuse, and its
    quad exchange needs every invocation's values, helper invocations' too: the full and
    cheap targets and the shadow gather read the light buffer, which Mesa's llvmpipe
    does not load in helper invocations (a quad on its seam of the full-screen triangle
    would lose picks: noise there)."""
    return (
        int(o["reuse_candidates"]) >= 4
        and o.get("reuse_k", 0) == 0
        and o.get("reuse_target", "tile") == "tile"
        and o["reuse_shadow_floor"] >= 1.0
    )


OPTIONS = Schema(
    Opt(
        "K",
        int,
        limits.BIG_TILE_SLOTS_DEFAULT,
        choices=tuple(SLOT_BLOCKS),
        doc="reservoir slots per big tile",
    ),
    Opt(
        "N",
        int,
        limits.SMALL_TILE_SAMPLES_DEFAULT,
        range=(1, limits.SMALL_TILE_SAMPLES_MAX),
        doc="samples per small tile",
    ),
    Opt(
        "big_tile",
        int,
        Auto(
            lambda o: 0 if o["reuse"] and int(o["reuse_candidates"]) else limits.BIG_TILE_PX,
            f"0 with reuse's big-tile candidates, else {limits.BIG_TILE_PX}",
        ),
        choices=(0, 16, 32, 64, 128, 256),
        doc="big tile, px; 0: per frame by the light count (fixed cost): 16 px streaming up "
        "to 512 lights, 32 px up to 2,048, 32 px from light clusters above "
        "(STB_REUSE_BIG_TILES_PX, STB_REUSE_STREAM_TARGETS_PER_PX)",
    ),
    Opt(
        "small_tile",
        int,
        limits.SMALL_TILE_PX,
        choices=(4, 8, 16, 32),
        doc="small tile, px (16 with interleaving)",
    ),
    Opt("eps", float, 0.1, doc="small-tile target distance floor, m"),
    Opt(
        "weight_cap",
        float,
        8.0,
        nullable=True,
        doc="sample weight cap relative to the tile mean (none or <= 0: unbiased)",
    ),
    Opt("interleave", bool, True, doc="interleaved 4-tile footprints (the talk's)"),
    Opt(
        "pattern",
        str,
        "random",
        choices=("random", "fixed"),
        doc="interleaving: a balanced random pattern per frame, or the talk's fixed one",
    ),
    Opt("stochastic_bilinear", bool, True, doc="stochastic bilinear big-tile choice"),
    Opt(
        "target",
        str,
        "shaped",
        choices=tuple(TARGET_MODES),
        doc="big-tile target: shaped (emission, cone, IES, range; default), segment (the "
        "talk's Phi/d^2) or uniform",
    ),
    Opt("pdf_floor", float, 0.25, doc="defensive mixture weight of the small-tile target"),
    Opt(
        "shadow_res",
        str,
        "quad",
        choices=("quad", "pixel"),
        doc="deferred shadow terms per 2x2 quad (the talk's) or per pixel",
    ),
    Opt(
        "select",
        str,
        "all",
        choices=("all", "quad", "pixel", "ris"),
        doc="samples a pixel evaluates: all N of its small tile (the talk's), or one of N "
        "drawn independently over all K, chosen per quad (terms for that one only: the "
        "cost of N = 1), per pixel (terms for all N): less tile-correlated noise, or "
        "resampled per pixel (ris: by a cheap target x term at the pixel, terms for all N)",
    ),
    Opt(
        "bigtile",
        str,
        "auto",
        choices=("auto", "stream", "clusters"),
        doc="big-tile candidates: every slot streams n/K lights (exact WRS), or draws from "
        "a two-level light hierarchy (cost ~ n/32 + 12K per tile); auto: clusters above "
        "K x BIG_TILE_CLUSTER_MIN_LIGHTS_PER_SLOT lights (with big_tile=0: above "
        "STB_REUSE_STREAM_TARGETS_PER_PX x 32^2)",
    ),
    Opt(
        "cluster_pick",
        str,
        Auto(
            lambda o: "flux" if int(o["big_tile"]) == 0 else "target",
            "flux with big_tile=0, else target",
        ),
        choices=("target", "flux"),
        doc="light clusters: a cluster's light drawn by the lights' own targets "
        "(BIG_TILE_CLUSTER_LIGHTS per slot) or by their flux (one target per slot)",
    ),
    Opt(
        "reuse",
        bool,
        True,
        doc="per-pixel reservoirs resampled from the big tile's reservoirs (or the small "
        "tile's samples), shared in each 2x2 quad or reused over frames and neighbours "
        "(ReSTIR-style, issue 31; replaces the small-tile, term and lighting passes, see "
        "lighting/stb_reuse.py); off: the talk's pipeline",
    ),
    Opt(
        "reuse_temporal",
        str,
        "auto",
        choices=("auto", "on", "off"),
        doc="reuse: combine last frame's reservoirs; auto: on unless frames are averaged "
        "(--temporal accumulate), whose frames it would correlate",
    ),
    Opt(
        "reuse_k",
        int,
        Auto(lambda o: 0 if o["reuse_res"] == "share" else 4, "0 with reuse_res=share, else 4"),
        range=(0, limits.STB_REUSE_K_MAX),
        doc="reuse: spatial neighbours per pixel",
    ),
    Opt("reuse_radius", float, limits.STB_REUSE_RADIUS_PX, doc="reuse: spatial radius, px"),
    Opt(
        "reuse_m_cap",
        float,
        limits.STB_REUSE_M_CAP,
        range=(0.0, 1e6),
        doc="reuse: history confidence cap (frames' worth of candidates)",
    ),
    Opt(
        "reuse_mis",
        str,
        "balance",
        choices=("count", "balance", "pairwise"),
        doc="reuse: spatial MIS weights, count (the 1/M rule: cheap, biased), balance "
        "(generalized balance heuristic: unbiased, (k+1)^2 targets) or pairwise (pairwise "
        "MIS with confidences: unbiased, 2k+1 targets)",
    ),
    Opt(
        "reuse_candidates",
        int,
        Auto(lambda o: o["K"], "K"),
        range=(0, max(limits.BIG_TILE_SLOTS_ALLOWED)),
        doc="reuse: initial candidates per pixel; 0: the small tile's N samples, C > 0: C "
        "of the big tile's K reservoirs (a random stratum, K / C apart) resampled with the "
        "pixel's own target, no small-tile pass",
    ),
    Opt(
        "reuse_target",
        str,
        Auto(
            lambda o: "full" if o["reuse_res"] == "quad" else "tile",
            "tile (full with reuse_res=quad)",
        ),
        choices=("full", "cheap", "tile"),
        doc="reuse: the initial resampling's per-pixel target with reuse_candidates > 0: "
        "full (area, cone, IES) or cheap (point light from two of its ten vec4s) or tile "
        "(the light's emission shaping evaluated once per big-tile slot towards the tile; "
        "distance, cone and IES table per pixel from four texels)",
    ),
    Opt(
        "reuse_res",
        str,
        Auto(
            lambda o: "share" if _share_fits(o) else "pixel",
            "share (pixel where share does not fit the other options)",
        ),
        choices=("pixel", "quad", "share"),
        doc="reuse: initial reservoirs per pixel or per 2x2 quad (resampled at one of its "
        "pixels with a defensive floor, shaded at all four; needs reuse_candidates > 0); "
        "share: per pixel from C / 4 candidates each, the quad's four combined at every "
        "pixel (needs reuse_candidates >= 4, reuse_k = 0, reuse_target = tile and "
        "reuse_shadow_floor = 1; no temporal reuse)",
    ),
    Opt(
        "reuse_shadow_floor",
        float,
        1.0,
        range=(0.0, 1.0),
        doc="reuse: the initial resampling's target times (floor + (1 - floor) x one hard "
        "shadow gather); 1: unshadowed (no gather); > 0 keeps it unbiased",
    ),
    Opt(
        "reuse_visibility",
        bool,
        False,
        doc="reuse: store a pick shadowed at the pixel as an empty reservoir (less noise "
        "in shadow, biased at shadow edges)",
    ),
)
#: Shader define of each one-sample ``select`` mode.
SELECT_DEFINES = {"quad": "STB_QUAD_SELECT", "pixel": "STB_PIXEL_SELECT", "ris": "STB_RIS_SELECT"}
#: Debug views (``shaders/debug_<name>.frag``).
DEBUG_AOVS = ("bigtile", "smalltile", "shadowterms")
#: Debug views of the reservoir reuse (``-o reuse=on`` only): the stored reservoir's
#: confidence M, its light, and what the temporal reuse did (taken / rejected / none).
REUSE_DEBUG_AOVS = ("reuse_m", "reuse_light", "reuse_reject")
#: Textures a debug view samples (uniform -> render buffer).
DEBUG_INPUTS = {"u_bigtile": "stb_bigtile", "u_smalltile": "stb_smalltile", "u_terms": "stb_terms"}
#: The one each view of DEBUG_AOVS samples.
DEBUG_VIEW_INPUT = {"bigtile": "u_bigtile", "smalltile": "u_smalltile", "shadowterms": "u_terms"}


class StbLighting(LightingMethod):
    name = "stb"
    options = OPTIONS
    debug_aovs: tuple[str, ...] = DEBUG_AOVS + REUSE_DEBUG_AOVS
    debug_aov_requires: ClassVar[dict[str, str]] = {
        **dict.fromkeys(REUSE_DEBUG_AOVS, "-o reuse=on"),
        # the talk's pipeline's buffers: the reuse draws no terms, nor small tiles with
        # the big tile's candidates (the default)
        "smalltile": "-o reuse=off or -o reuse_candidates=0",
        "shadowterms": "-o reuse=off",
    }

    @classmethod
    def check_options(cls, o: dict) -> None:
        if o["interleave"] and o["small_tile"] != 16:
            raise OptionError("stb option small_tile: interleaving needs 16 px small tiles")
        if o["small_tile"] > (o["big_tile"] or limits.STB_REUSE_BIG_TILES_PX[0]):
            raise OptionError("stb option small_tile: must be <= big_tile")
        c = int(o["reuse_candidates"])
        if c and (c > int(o["K"]) or int(o["K"]) % c):
            raise OptionError("stb option reuse_candidates: must divide K")
        if o["reuse_res"] == "quad" and not c:
            raise OptionError("stb option reuse_res=quad: needs reuse_candidates > 0")
        if o["reuse_target"] == "tile" and o["reuse_res"] == "quad":
            raise OptionError("stb option reuse_target=tile: not with reuse_res=quad")
        if o["reuse_res"] == "share" and not _share_fits(o):
            raise OptionError(
                "stb option reuse_res=share: needs reuse_candidates >= 4, reuse_k=0, "
                "reuse_target=tile and reuse_shadow_floor=1"
            )
        cap = o["weight_cap"]
        o["weight_cap"] = 0.0 if cap is None or cap <= 0 else float(cap)

    def __init__(
        self, delegate: GLRenderDelegate | None, warn: Warn | None = None, **options: Any
    ) -> None:
        super().__init__(delegate, warn, **options)
        #: This frame's big tile (px) and whether it draws from light clusters
        #: (``frame_tiling``; fixed by the options unless big_tile=0).
        self.big_px = int(self.o["big_tile"]) or limits.STB_REUSE_BIG_TILES_PX[0]
        self.hiz_level = int(math.log2(self.big_px))
        self._luts: tuple[moderngl.Texture, moderngl.Texture] | None = None
        self.pattern_offset = (0, 0)
        self.pattern_layer = 0
        # Light clusters (bigtile=clusters): built for (table version, FoV rows).
        self._clusters: LightClusters | None = None
        self._clusters_key: tuple[int, bytes] | None = None
        self._cluster_buffers: SSBOPool | None = None
        #: Reservoir reuse (``-o reuse=on``) and its history.
        self.reuse = ReuseStage()
        o = self.o
        if o["reuse"] and o["reuse_res"] == "share" and o["reuse_temporal"] == "on":
            self.warn(
                "stb option reuse_temporal=on: ignored, reuse_res=share has no temporal "
                "reuse (-o reuse_res=pixel has)"
            )
        #: The views this instance draws: the reuse views need its reservoirs; under
        #: reuse no term pass runs, nor the small-tile pass with per-pixel candidates.
        self.debug_aovs = DEBUG_AOVS
        if self.o["reuse"]:
            small = () if self.o["reuse_candidates"] else ("smalltile",)
            self.debug_aovs = ("bigtile", *small, *REUSE_DEBUG_AOVS)

    def internal(self) -> tuple[Tex, ...]:
        reuse = reuse_textures() if self.o["reuse"] else ()
        return (
            Tex("stb_bigtile", "r32ui", DERIVED),
            Tex("stb_smalltile", "rgba32ui", DERIVED),
            Tex("stb_terms", "rgba8", DERIVED),
            Tex("stb_term_split", "r8ui", DERIVED),
            Tex("stb_pixel_terms", "rgba8"),
            *reuse,
        )

    def reads(self) -> tuple[Resource, ...]:
        extra: tuple[Resource, ...] = (Tex("g_motion", "rg16f"),) if self.o["reuse"] else ()
        if not int(self.o["big_tile"]):  # every depth level a frame's big tile may take
            sizes = limits.STB_REUSE_BIG_TILES_PX[1:]
            extra += tuple(Tex(f"hiz{int(math.log2(px))}", "rg32f") for px in sizes)
        return (*super().reads(), *extra)

    def debug_passes(self) -> list[Pass]:
        return [StbDebugPass(self, aov) for aov in self.debug_aovs]

    # -- resources --
    def patterns(self) -> QuadPatterns:
        """The interleaving patterns of ``-o pattern`` (one layer per pattern)."""
        return pattern_bank() if self.o["pattern"] == "random" else fixed_pattern()

    def _lut_textures(self, ctx: moderngl.Context) -> tuple[moderngl.Texture, moderngl.Texture]:
        """Inverse LUT (16 x 16 per layer: tile | slot << shift, row = qy) and forward
        table (64 x 4 per layer: qx | qy << shift, row = tile), layers stacked in y."""
        if self._luts is None:
            pat = self.patterns()
            inv = (pat.tile_of_quad | (pat.slot_of_quad << QUAD_LUT_SLOT_SHIFT)).astype(np.int32)
            fwd = pat.quad_of_slot  # (P, 4, 64, 2)
            fwd_packed = (fwd[..., 0] | (fwd[..., 1] << QUAD_FWD_Y_SHIFT)).astype(np.int32)
            n = pat.count
            t_inv = ctx.texture((16, 16 * n), 1, inv.tobytes(), dtype="i4")
            t_fwd = ctx.texture((64, 4 * n), 1, fwd_packed.tobytes(), dtype="i4")
            for t in (t_inv, t_fwd):
                t.filter = (moderngl.NEAREST, moderngl.NEAREST)
            self._luts = (t_inv, t_fwd)
        return self._luts

    def grid(self, width: int, height: int) -> dict[str, tuple[int, int]]:
        """Texture sizes of this frame's STB buffers."""
        o = self.o
        bt = self.big_px
        bw, bh = SLOT_BLOCKS[int(o["K"])]
        big = (math.ceil(width / bt), math.ceil(height / bt))
        if o["interleave"]:
            fp = INTERLEAVE_FOOTPRINT_PX
            fx, fy = math.ceil((width + fp) / fp), math.ceil((height + fp) / fp)
            small = (2 * fx, 2 * fy)
            qs = INTERLEAVE_QUADS_PER_SIDE
        else:
            s = int(o["small_tile"])
            small = (math.ceil((width + s) / s), math.ceil((height + s) / s))
            qs = s // 2
        return {
            "big_tiles": big,
            "bigtile": (big[0] * bw, big[1] * bh),
            "smalltile": small,
            "terms": (small[0] * qs, small[1] * qs),
        }

    def prepare(self, frame: FrameContext) -> None:
        o = self.o
        rng = np.random.default_rng(frame.seed)
        # Any pixel offset, odd ones included: the 2x2 quad grid moves with it, so the
        # quad-correlated noise of one frame does not stay in place when frames are
        # averaged (an even-only offset left a fixed 2x2 checkerboard).
        period = INTERLEAVE_FOOTPRINT_PX if o["interleave"] else int(o["small_tile"])
        self.pattern_offset = (int(rng.integers(0, period)), int(rng.integers(0, period)))
        # One interleaving pattern of the bank per frame (layer 0 of the fixed one).
        self.pattern_layer = int(rng.integers(0, self.patterns().count))

    def _common_uniforms(self, frame: FrameContext, prog: moderngl.Program) -> None:
        o = self.o
        set_uniform(prog, "u_block", SLOT_BLOCKS[int(o["K"])])
        set_uniform(prog, "u_big_px", self.big_px)
        set_uniform(prog, "u_pattern_offset", self.pattern_offset)
        set_uniform(prog, "u_pattern_layer", self.pattern_layer)
        set_uniform(prog, "u_interleave", 1 if o["interleave"] else 0)
        set_uniform(prog, "u_small_px", int(o["small_tile"]))
        set_uniform(prog, "u_weight_cap", float(o["weight_cap"]))

    def _bind(
        self,
        frame: FrameContext,
        prog: moderngl.Program,
        unit: int,
        name: str,
        tex: moderngl.Texture,
    ) -> int:
        if name in prog:
            tex.use(unit)
            cast(moderngl.Uniform, prog[name]).value = unit
            return unit + 1
        return unit

    def defines(self, frame: FrameContext) -> dict[str, object]:
        d = self.scene_defines(frame)
        d["STB_N"] = int(self.o["N"])
        d["STB_K"] = int(self.o["K"])
        if self.o["shadow_res"] == "pixel":
            d["STB_PIXEL_TERMS"] = True
        if self.o["select"] != "all":
            d["STB_SELECT_ONE"] = True
            d[SELECT_DEFINES[self.o["select"]]] = True
        if not any(k in d for k in ("HAS_SHADOWS", "HAS_CONES", "HAS_IES")):
            d["STB_UNIT_TERMS"] = True  # every term is 1: no term pass
        return d

    def execute(self, frame: FrameContext) -> None:
        if frame.light_count == 0:
            # No local lights: the sun-only path (compiled without STB passes).
            prog = program(frame, "lighting_direct.frag", self.lighting_defines(frame))
            self.bind_common(frame, prog)
            self.fullscreen_pass(frame, prog, "lighting")
            self.reuse.reset()
            return
        ctx = frame.ctx
        bufs = frame.buffers
        w, h = bufs.size
        self.big_px, clusters = self.frame_tiling(frame.light_count)
        frame.stats["stb_big_tile_px"] = self.big_px
        g = self.grid(w, h)
        defines = self.defines(frame)
        lut_inv, lut_fwd = self._lut_textures(ctx)
        hiz = self.big_tile_hiz(frame)

        # 1. big tiles
        big = bufs.texture("stb_bigtile", 1, "u4", size=g["bigtile"])
        if clusters:
            self._bigtile_clusters(frame, defines, big, hiz, g["big_tiles"])
        else:
            prog = program(frame, "stb_bigtile.frag", defines)
            self._common_uniforms(frame, prog)
            set_uniform(prog, "u_target_mode", TARGET_MODES[self.o["target"]])
            self.bind_common(frame, prog)
            self._bind(frame, prog, TEX_UNIT_HIZ, "u_hiz", hiz)
            self._pass(frame, prog, ["stb_bigtile"], g["bigtile"])

        if self.o["reuse"] and int(self.o["reuse_candidates"]):
            # Per-pixel candidates straight from the big tiles: no small tiles, no terms.
            self.reuse.execute(self, frame, defines, big, (lut_inv, lut_fwd))
            frame.stats["stb_grid"] = {k: list(v) for k, v in g.items()}
            return

        # 2. small tiles
        small = bufs.texture("stb_smalltile", 4, "u4", size=g["smalltile"])
        prog = program(frame, "stb_smalltile.frag", defines)
        self._common_uniforms(frame, prog)
        set_uniform(prog, "u_big_tiles", g["big_tiles"])
        set_uniform(prog, "u_eps", float(self.o["eps"]))
        set_uniform(prog, "u_pdf_floor", float(self.o["pdf_floor"]))
        set_uniform(prog, "u_stochastic_bilinear", 1 if self.o["stochastic_bilinear"] else 0)
        unit = self.bind_common(frame, prog)
        unit = self._bind(frame, prog, unit, "u_bigtile", big)
        unit = self._bind(frame, prog, unit, "u_quad_lut", lut_inv)
        self._bind(frame, prog, unit, "u_quad_fwd", lut_fwd)
        self._pass(frame, prog, ["stb_smalltile"], g["smalltile"])

        # 3. shadow terms (skipped when every term is 1)
        pixel_terms = self.o["shadow_res"] == "pixel"
        tsize = (w, h) if pixel_terms else g["terms"]
        terms = bufs.texture("stb_terms", 4, "f1", size=tsize)
        split = bufs.texture("stb_term_split", 1, "u1", size=tsize)
        if self.o["reuse"]:
            # The reuse stage evaluates the chosen light's term per pixel itself.
            with frame.timings_scope("stb_terms"):
                bufs.framebuffer("fb_stb_terms_unit", ["stb_terms"]).clear(1.0, 1.0, 1.0, 1.0)
            self.reuse.execute(self, frame, defines, small, (lut_inv, lut_fwd))
            frame.stats["stb_grid"] = {k: list(v) for k, v in g.items()}
            return
        if "STB_UNIT_TERMS" in defines:
            with frame.timings_scope("stb_terms"):
                bufs.framebuffer("fb_stb_terms_unit", ["stb_terms"]).clear(1.0, 1.0, 1.0, 1.0)
        else:
            prog = program(frame, "stb_shadow.frag", defines)
            self._common_uniforms(frame, prog)
            unit = self.bind_common(frame, prog)
            unit = self._bind(frame, prog, unit, "u_smalltile", small)
            unit = self._bind(frame, prog, unit, "u_quad_lut", lut_inv)
            self._bind(frame, prog, unit, "u_quad_fwd", lut_fwd)
            targets = ["stb_terms"] if pixel_terms else ["stb_terms", "stb_term_split"]
            if "u_pixel_terms" in prog:
                bufs.textures["stb_pixel_terms"].bind_to_image(
                    IMAGE_UNIT_PIXEL_TERMS, read=False, write=True
                )
            self._pass(frame, prog, targets, tsize)
            frame.ctx.memory_barrier()

        # 4. lighting
        prog = program(frame, "stb_lighting.frag", self.lighting_defines(frame, defines))
        self._common_uniforms(frame, prog)
        unit = self.bind_common(frame, prog)
        unit = self._bind(frame, prog, unit, "u_smalltile", small)
        unit = self._bind(frame, prog, unit, "u_terms", terms)
        unit = self._bind(frame, prog, unit, "u_term_split", split)
        unit = self._bind(frame, prog, unit, "u_pixel_terms", bufs.textures["stb_pixel_terms"])
        unit = self._bind(frame, prog, unit, "u_quad_lut", lut_inv)
        self._bind(frame, prog, unit, "u_quad_fwd", lut_fwd)
        set_uniform(prog, "u_eps", float(self.o["eps"]))
        with frame.timings_scope("stb_lighting"):
            self.fullscreen_pass(frame, prog, "lighting")
        frame.stats["stb_grid"] = {k: list(v) for k, v in g.items()}

    def big_tile_hiz(self, frame: FrameContext) -> moderngl.Texture:
        """The min/max depth level with one texel per big tile of this frame."""
        return frame.buffers.textures[f"hiz{int(math.log2(self.big_px))}"]

    def frame_tiling(self, n_lights: int) -> tuple[int, bool]:
        """This frame's big tile (px) and whether its big-tile pass draws from light
        clusters. A given ``big_tile`` is kept; ``big_tile=0`` takes the smallest of
        STB_REUSE_BIG_TILES_PX whose streaming pass evaluates at most
        STB_REUSE_STREAM_TARGETS_PER_PX light targets per pixel (n / px^2), else the
        largest with clusters: the pass's cost stays bounded whatever the light count."""
        mode = self.o["bigtile"]
        px = int(self.o["big_tile"])
        if not px:
            sizes = limits.STB_REUSE_BIG_TILES_PX
            fits = [s for s in sizes if n_lights <= limits.STB_REUSE_STREAM_TARGETS_PER_PX * s * s]
            if mode == "clusters" or (mode == "auto" and not fits):
                return sizes[-1], True
            return (fits[0] if fits else sizes[-1]), False
        if mode != "auto":
            return px, mode == "clusters"
        return px, n_lights > int(self.o["K"]) * limits.BIG_TILE_CLUSTER_MIN_LIGHTS_PER_SLOT

    def light_clusters(self, frame: FrameContext) -> LightClusters:
        """The FoV lights' clusters, rebuilt only when the light table or the FoV set
        changed since the last frame."""
        assert self.delegate is not None, "light clusters need the delegate's light table"
        t, rows = self.delegate.light_table, frame.get(InViewLights).rows
        key = (int(t.version), np.ascontiguousarray(rows).tobytes())
        if self._clusters is None or key != self._clusters_key:
            frame.stats["stb_clusters_rebuilt"] = 1
            self._clusters = build_clusters(t.position[rows], t.range[rows], t.flux[rows])
            self._clusters_key = key
            if self._cluster_buffers is None:
                self._cluster_buffers = SSBOPool(frame.ctx)
            pool = self._cluster_buffers
            pool.upload("records", self._clusters.records(), SSBO_STB_CLUSTERS)
            pool.upload("order", self._clusters.order, SSBO_STB_CLUSTER_LIGHTS)
            pool.upload("cdf", self._clusters.cdf, SSBO_STB_CLUSTER_CDF)
            # The lights' own records in Morton order: a cluster reads one contiguous run.
            pool.upload(
                "lights", pack_lights(t, rows[self._clusters.order]), SSBO_STB_CLUSTER_RECORDS
            )
        return self._clusters

    def _bigtile_clusters(
        self,
        frame: FrameContext,
        defines: dict[str, object],
        big: moderngl.Texture,
        hiz: moderngl.Texture,
        tiles: tuple[int, int],
    ) -> None:
        """Big-tile reservoirs drawn from light clusters (stb_bigtile_clusters.comp)."""
        with frame.timings_scope("stb_clusters"):  # CPU: rebuilt only on change
            cl = self.light_clusters(frame)
        with frame.timings_scope("stb_bigtile"):
            o = self.o
            flux = o["cluster_pick"] == "flux"
            cdefs = {**defines, "STB_CLUSTER_PICK_FLUX": True} if flux else defines
            cs = shader_library(frame.ctx).compute("stb_bigtile_clusters.comp", cdefs)
            set_uniform(cs, "u_block", SLOT_BLOCKS[int(o["K"])])
            set_uniform(cs, "u_big_px", self.big_px)
            set_uniform(cs, "u_weight_cap", float(o["weight_cap"]))
            set_uniform(cs, "u_target_mode", TARGET_MODES[o["target"]])
            set_uniform(cs, "u_clusters", cl.count)
            set_uniform(cs, "u_supers", len(cl.supers))
            flat = flux and cl.count <= limits.BIG_TILE_CLUSTERS_FLAT_MAX
            set_uniform(cs, "u_flat", 1 if flat else 0)
            self.bind_common(frame, cs)  # type: ignore[arg-type]  # same uniforms and buffers
            hiz.use(TEX_UNIT_HIZ)
            bufs = cast(SSBOPool, self._cluster_buffers).buffers  # built by light_clusters
            bufs["records"].bind_to_storage_buffer(SSBO_STB_CLUSTERS)
            bufs["order"].bind_to_storage_buffer(SSBO_STB_CLUSTER_LIGHTS)
            bufs["lights"].bind_to_storage_buffer(SSBO_STB_CLUSTER_RECORDS)
            if flux:
                bufs["cdf"].bind_to_storage_buffer(SSBO_STB_CLUSTER_CDF)
            big.bind_to_image(IMAGE_UNIT_BIGTILE, read=False, write=True)
            cs.run(tiles[0], tiles[1], 1)
            frame.ctx.memory_barrier()
        frame.stats["stb_light_clusters"] = cl.count

    def _pass(
        self,
        frame: FrameContext,
        prog: moderngl.Program,
        targets: list[str],
        size: tuple[int, int],
    ) -> None:
        """A full-screen draw into ``targets`` (MRT), timed as ``lighting.<first>``."""
        with frame.timings_scope(targets[0]):
            fbo = frame.buffers.framebuffer("fb_" + "+".join(targets), targets)
            draw_fullscreen(frame.ctx, prog, fbo, size)

    def release(self) -> None:
        self.reuse.release()
        if self._cluster_buffers is not None:
            self._cluster_buffers.release()
        self._clusters = None
        if self._luts is not None:
            for t in self._luts:
                t.release()
            self._luts = None


class StbDebugPass(Pass):
    """Draws one STB debug view (``shaders/debug_<aov>.frag``) of this frame's STB
    buffers into ``debug_<aov>`` (RGBA8, frame size); black when the frame ran no
    STB passes (no local lights in view)."""

    only_final = True

    def __init__(self, method: StbLighting, aov: str) -> None:
        # The method's delegate (None only for a method made without an engine); this
        # pass draws from the frame's buffers and never uses it.
        super().__init__(cast("GLRenderDelegate", method.delegate))
        self.method = method
        self.aov = aov
        self.name = f"debug_{aov}"  # type: ignore[misc]

    def _inputs(self) -> tuple[str, ...]:
        """The render buffers this view samples."""
        if self.aov in REUSE_DEBUG_AOVS:
            return tuple(t.name for t in reuse_textures()[:3])
        return (DEBUG_INPUTS[DEBUG_VIEW_INPUT[self.aov]],)

    def io(self) -> tuple[tuple[Resource, ...], tuple[Resource, ...]]:
        reads: tuple[Resource, ...] = (
            *(Tex(n) for n in self._inputs()),
            Rec(InViewLights),
            Rec(DistantLights),
            Rec(LightBuffer),
            Rec(FrameBlock),
        )
        return reads, (Tex(self.name, "rgba8"),)

    def execute(self, frame: FrameContext) -> None:
        m = self.method
        target = self.name
        fbo = frame.buffers.framebuffer("fb_" + target, [target])
        if frame.light_count == 0:
            fbo.clear(0.0, 0.0, 0.0, 0.0)
            return
        tex = frame.buffers.textures
        prog = program(frame, f"debug_{self.aov}.frag", m.defines(frame))
        m._common_uniforms(frame, prog)
        unit = 0
        if self.aov in REUSE_DEBUG_AOVS:
            cur, newest = m.reuse.debug_inputs()
            unit = m._bind(frame, prog, unit, "u_reuse_cur", tex[cur])
            m._bind(frame, prog, unit, "u_reuse_res", tex[newest])
            set_uniform(prog, "u_history", 1 if m.reuse.last_history else 0)
            # this frame's reservoirs after temporal reuse: one per 2x2 quad (reuse_res=quad)
            set_uniform(prog, "u_cur_shift", 1 if m.o["reuse_res"] == "quad" else 0)
        else:
            uniform = DEBUG_VIEW_INPUT[self.aov]
            unit = m._bind(frame, prog, unit, uniform, tex[DEBUG_INPUTS[uniform]])
            lut_inv, lut_fwd = m._lut_textures(frame.ctx)  # the interleaved tile layout
            unit = m._bind(frame, prog, unit, "u_quad_lut", lut_inv)
            unit = m._bind(frame, prog, unit, "u_quad_fwd", lut_fwd)
        draw_fullscreen(frame.ctx, prog, fbo, frame.buffers.size)


def decode_samples(raw: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unpack 32-bit STB samples (``common/packing.glsl``) -> (light index, weight)."""
    raw = np.asarray(raw, dtype=np.uint32)
    wbits = 32 - limits.SAMPLE_INDEX_BITS
    idx = raw >> np.uint32(wbits)
    code = (raw & np.uint32((1 << wbits) - 1)).astype(np.float64)
    w = np.where(
        code > 0,
        np.exp2(code / limits.SAMPLE_WEIGHT_STEPS_PER_OCTAVE + limits.SAMPLE_WEIGHT_LOG2_MIN),
        0.0,
    )
    return idx.astype(np.int64), w


def encode_samples(index: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """CPU twin of ``pack_sample`` (tests and tools)."""
    wbits = 32 - limits.SAMPLE_INDEX_BITS
    w = np.asarray(weight, dtype=np.float64)
    with np.errstate(divide="ignore"):
        code = np.where(
            w > 0,
            np.clip(
                np.floor(
                    (np.log2(np.maximum(w, 1e-300)) - limits.SAMPLE_WEIGHT_LOG2_MIN)
                    * limits.SAMPLE_WEIGHT_STEPS_PER_OCTAVE
                    + 0.5
                ),
                1,
                (1 << wbits) - 1,
            ),
            0,
        )
    return (np.asarray(index, dtype=np.uint64) << wbits | code.astype(np.uint64)).astype(np.uint32)
