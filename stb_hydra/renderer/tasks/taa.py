"""Temporal accumulation: a running average (rgba32f) over the frames of one
accumulation sequence (``--accumulate M``: distinct frame seeds, same time)."""

from __future__ import annotations

import moderngl

from ..gl import shader_library
from .base import Task


class AccumulateTask(Task):
    name = "accumulate"

    def __init__(self, engine) -> None:
        super().__init__(engine)
        self.count = 0

    def reset(self) -> None:
        self.count = 0

    def execute(self, frame) -> None:
        ctx = frame.ctx
        bufs = frame.buffers
        cur = bufs.textures["lighting"]
        a = bufs.texture("accum_a", 4, "f4")
        b = bufs.texture("accum_b", 4, "f4")
        src, _dst, dst_name = (a, b, "accum_b") if self.count % 2 == 0 else (b, a, "accum_a")
        prog = shader_library(ctx).program("fullscreen.vert", "accumulate.frag")
        if self.count == 0:
            src_name = "accum_a" if dst_name == "accum_b" else "accum_b"
            bufs.framebuffer("fb_" + src_name, [src_name]).clear(0.0, 0.0, 0.0, 0.0)
        fbo = bufs.framebuffer("fb_" + dst_name, [dst_name])
        fbo.use()
        ctx.viewport = (0, 0, *bufs.size)
        ctx.disable(moderngl.BLEND | moderngl.DEPTH_TEST)
        cur.use(0)
        src.use(1)
        prog["u_current"].value = 0
        if "u_history" in prog:
            prog["u_history"].value = 1
        prog["u_weight"].value = 1.0 / (self.count + 1)
        self.engine.fullscreen(prog).render(moderngl.TRIANGLES, vertices=3)
        self.count += 1
        frame.color_buffer = dst_name
