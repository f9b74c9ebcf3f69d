"""Min/max depth pyramid: level k (rg32f) covers 2^k x 2^k pixels; level 7 is one
texel per 128 px big tile."""

from __future__ import annotations

import math

from ..gl import shader_library
from .base import Task

HIZ_LEVELS = 7


class HiZTask(Task):
    name = "hiz"

    def __init__(self, engine, levels: int = HIZ_LEVELS) -> None:
        super().__init__(engine)
        self.levels = levels

    def execute(self, frame) -> None:
        ctx = frame.ctx
        bufs = frame.buffers
        cs = shader_library(ctx).compute("hiz_minmax.comp")
        w, h = bufs.size
        src = bufs.textures["g_depth"]
        for k in range(1, self.levels + 1):
            size = (max(1, math.ceil(w / 2**k)), max(1, math.ceil(h / 2**k)))
            dst = bufs.texture(f"hiz{k}", 2, "f4", size=size)
            src.use(0)
            cs["u_src"].value = 0
            cs["u_from_depth"].value = 1 if k == 1 else 0
            dst.bind_to_image(0, read=False, write=True)
            cs.run(math.ceil(size[0] / 8), math.ceil(size[1] / 8), 1)
            ctx.memory_barrier()
            src = dst
