"""Edge-aware spatial filter of taa's output (``RenderSettings.taa_filter`` levels,
0 = off): SVGF-style a-trous levels over the albedo-demodulated history the taa pass
wrote, with depth, normal and variance-scaled luminance stops
(``shaders/taa_filter.frag`` says how). Display only: the history stays unfiltered
(feeding the first level back, as SVGF does, darkened the courtyard orbit by 8 % and
raised its HDR-FLIP; docs/STB_NOTES.md, issue 14)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ... import limits
from ..frame import FrameContext
from ..fullscreen import draw_fullscreen
from ..gl import set_uniform, shader_library
from ..graph import Rec, Tex
from ..records import SceneColor
from .base import Pass
from .temporal import ALBEDO, GEOMETRY, HISTORY

if TYPE_CHECKING:
    from ..gl_delegate import GLRenderDelegate
    from .temporal import TemporalTask

#: The filtered display colour (``SceneColor.buffer``).
OUTPUT = "taa_filtered"
#: Ping-pong levels: demodulated lighting without emission (rgb), luma variance (a).
LEVELS = ("taa_filter_a", "taa_filter_b")


class TaaFilterTask(Pass):
    name = "taa_filter"
    reads = (
        Rec(SceneColor),
        Tex("g_emission", "rgba16f"),
        Tex(ALBEDO, "rgba32f"),
        *(Tex(n, "rgba32f") for n in HISTORY),
        *(Tex(n, "rgba32f") for n in GEOMETRY),
    )
    writes = (
        Rec(SceneColor),
        Tex(OUTPUT, "rgba16f"),
        *(Tex(n, "rgba32f") for n in LEVELS),
    )

    def __init__(self, delegate: GLRenderDelegate, temporal: TemporalTask, levels: int) -> None:
        """``levels``: 1..limits.TAA_FILTER_LEVELS_MAX (``RenderSettings`` checks the
        setting; ``build_passes`` adds this pass only when it is not 0)."""
        super().__init__(delegate)
        self.temporal = temporal
        self.levels = levels

    def execute(self, frame: FrameContext) -> None:
        bufs = frame.buffers
        tex = bufs.textures
        hist, geo = self.temporal.latest
        prog = shader_library(frame.ctx).program("fullscreen.vert", "taa_filter.frag")
        tex[geo].use(1)
        tex[ALBEDO].use(2)
        tex[hist].use(3)
        tex["g_emission"].use(4)
        for uniform, unit in (("u_geo", 1), ("u_albedo", 2), ("u_history", 3), ("u_emission", 4)):
            set_uniform(prog, uniform, unit)
        set_uniform(prog, "u_src", 0)
        set_uniform(prog, "u_sigma_l", float(limits.TAA_FILTER_SIGMA_L))
        set_uniform(prog, "u_mode", 0)
        tex[hist].use(0)
        draw_fullscreen(
            frame.ctx, prog, bufs.framebuffer("fb_taa_filter_0", [LEVELS[0]]), bufs.size
        )
        for level in range(self.levels):
            last = level == self.levels - 1
            src = LEVELS[level % 2]
            dst = OUTPUT if last else LEVELS[1 - level % 2]
            tex[src].use(0)
            set_uniform(prog, "u_mode", 2 if last else 1)
            set_uniform(prog, "u_step", 1 << level)
            draw_fullscreen(frame.ctx, prog, bufs.framebuffer(f"fb_{dst}", [dst]), bufs.size)
        frame.put(SceneColor(OUTPUT))
