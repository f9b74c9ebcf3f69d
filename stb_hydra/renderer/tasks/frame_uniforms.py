"""The per-frame uniform block (``shaders/common/frame.glsl``, binding 0): view,
previous view-projection, sun, ambient, light count, seed, big-tile grid."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import moderngl
import numpy as np

from ... import limits
from ..frame import FrameContext
from ..frame_data import FrameUniforms, pack_frame_block
from ..graph import Rec
from ..records import DistantLights, FrameBlock, InViewLights
from .base import Pass

if TYPE_CHECKING:
    from ..gl_delegate import GLRenderDelegate


class FrameUniformsTask(Pass):
    name = "frame_uniforms"
    reads = (Rec(DistantLights), Rec(InViewLights))
    writes = (Rec(FrameBlock),)

    def __init__(self, delegate: GLRenderDelegate, ctx: moderngl.Context) -> None:
        super().__init__(delegate)
        self.uniforms = FrameUniforms(ctx)
        self._prev_view_proj: np.ndarray | None = None

    def reset_history(self) -> None:
        """Forget the previous view (motion vectors restart from zero)."""
        self._prev_view_proj = None

    def prepare(self, frame: FrameContext) -> None:
        view = frame.view
        prev = self._prev_view_proj if self._prev_view_proj is not None else view.view_proj
        w, h = frame.buffers.size
        big = (math.ceil(w / limits.BIG_TILE_PX), math.ceil(h / limits.BIG_TILE_PX))
        lights = frame.get(DistantLights)
        self.uniforms.update(
            pack_frame_block(
                view,
                prev,
                lights.sun,
                lights.ambient,
                frame.get(InViewLights).count,
                frame.frame_index,
                frame.seed,
                big,
                lights.extra,
            )
        )
        # Unjittered: the G-buffer's motion vectors are then (this frame's jitter +
        # the motion), and the temporal pass subtracts the jitter it knows.
        unjittered = view.unjittered_view_proj
        self._prev_view_proj = view.view_proj if unjittered is None else unjittered
        frame.put(FrameBlock(big_tiles=big))

    def release(self) -> None:
        self.uniforms.release()
