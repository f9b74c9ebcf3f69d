"""Lighting task: runs the selected lighting method into the ``lighting`` buffer
(RGBA16F, scene-linear) and names it as the frame's ``SceneColor``; with
``taa_inputs`` the same pass writes the temporal pass's demodulated input
(``lighting.base.TAA_INPUTS``)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..frame import FrameContext
from ..graph import Rec, Resource, Tex
from ..lighting.base import TAA_INPUTS, LightingMethod
from ..records import SceneColor
from .base import Pass

if TYPE_CHECKING:
    from ..gl_delegate import GLRenderDelegate

LIGHTING = Tex("lighting", "rgba16f")


class LightingTask(Pass):
    name = "lighting"

    def __init__(
        self, delegate: GLRenderDelegate, method: LightingMethod, taa_inputs: bool = False
    ) -> None:
        super().__init__(delegate)
        self.method = method
        method.taa_inputs = taa_inputs

    def io(self) -> tuple[tuple[Resource, ...], tuple[Resource, ...]]:
        extra = TAA_INPUTS if self.method.taa_inputs else ()
        return self.method.reads(), (LIGHTING, Rec(SceneColor), *extra, *self.method.internal())

    def prepare(self, frame: FrameContext) -> None:
        self.method.prepare(frame)

    def execute(self, frame: FrameContext) -> None:
        self.method.execute(frame)
        frame.put(SceneColor("lighting"))

    def release(self) -> None:
        self.method.release()
        self.method.release_base()
