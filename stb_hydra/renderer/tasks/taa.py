"""Temporal accumulation: a running average (rgba32f) over the frames of one
accumulation sequence (``--accumulate M``: distinct frame seeds, same time)."""

from __future__ import annotations

from typing import TYPE_CHECKING, cast

import moderngl

from ..frame import FrameContext
from ..fullscreen import draw_fullscreen
from ..gl import shader_library
from ..graph import Rec, Tex
from ..records import SceneColor
from .base import Pass

if TYPE_CHECKING:
    from ..gl_delegate import GLRenderDelegate

ACCUM = ("accum_a", "accum_b")


class AccumulateTask(Pass):
    name = "accumulate"
    reads = (Tex("lighting", "rgba16f"), Rec(SceneColor))
    writes = (Rec(SceneColor), *(Tex(n, "rgba32f") for n in ACCUM))

    def __init__(self, delegate: GLRenderDelegate) -> None:
        super().__init__(delegate)
        self.count = 0

    def reset(self) -> None:
        self.count = 0

    def execute(self, frame: FrameContext) -> None:
        ctx = frame.ctx
        bufs = frame.buffers
        cur = bufs.textures["lighting"]
        src_name, dst_name = ACCUM if self.count % 2 == 0 else ACCUM[::-1]
        prog = shader_library(ctx).program("fullscreen.vert", "accumulate.frag")
        if self.count == 0:
            bufs.framebuffer("fb_" + src_name, [src_name]).clear(0.0, 0.0, 0.0, 0.0)
        cur.use(0)
        bufs.textures[src_name].use(1)
        cast(moderngl.Uniform, prog["u_current"]).value = 0
        if "u_history" in prog:
            cast(moderngl.Uniform, prog["u_history"]).value = 1
        cast(moderngl.Uniform, prog["u_weight"]).value = 1.0 / (self.count + 1)
        draw_fullscreen(ctx, prog, bufs.framebuffer("fb_" + dst_name, [dst_name]), bufs.size)
        self.count += 1
        frame.put(SceneColor(dst_name))
