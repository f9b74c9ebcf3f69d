"""Min/max depth pyramid: level k (rg32f) covers 2^k x 2^k pixels; level 7 is one
texel per 128 px big tile."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from ..frame import FrameContext
from ..gl import shader_library
from ..graph import Resource, Size, Tex
from ..shader_constants import IMAGE_UNIT_HIZ_DST
from .base import Pass

if TYPE_CHECKING:
    from ..gl_delegate import GLRenderDelegate

HIZ_LEVELS = 7


class HiZTask(Pass):
    name = "hiz"
    reads = (Tex("g_depth", "r32f"),)

    def __init__(self, delegate: GLRenderDelegate, levels: int = HIZ_LEVELS) -> None:
        super().__init__(delegate)
        self.levels = levels

    def io(self) -> tuple[tuple[Resource, ...], tuple[Resource, ...]]:
        levels = range(1, self.levels + 1)
        writes = tuple(Tex(f"hiz{k}", "rg32f", Size(divisor=2**k)) for k in levels)
        return self.reads, writes

    def execute(self, frame: FrameContext) -> None:
        ctx = frame.ctx
        bufs = frame.buffers
        cs = shader_library(ctx).compute("hiz_minmax.comp")
        src = bufs.textures["g_depth"]
        for k in range(1, self.levels + 1):
            dst = bufs.textures[f"hiz{k}"]
            src.use(0)
            cs["u_src"].value = 0
            cs["u_from_depth"].value = 1 if k == 1 else 0
            dst.bind_to_image(IMAGE_UNIT_HIZ_DST, read=False, write=True)
            cs.run(math.ceil(dst.size[0] / 8), math.ceil(dst.size[1] / 8), 1)
            ctx.memory_barrier()
            src = dst
