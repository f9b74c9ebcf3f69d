"""ColorCorrectionTask: scene-linear -> display through OCIO's GPU shader."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ...color.ocio import ColorCorrectionPass, ColorPipeline
from ..frame import FrameContext
from ..graph import Imported, Rec, Tex
from ..records import SceneColor
from .base import Pass
from .taa import ACCUM
from .taa_filter import OUTPUT as FILTER_OUTPUT
from .temporal import OUTPUT as TAA_OUTPUT

if TYPE_CHECKING:
    from ..gl_delegate import GLRenderDelegate

#: Buffers that may hold the frame's scene-linear colour (``SceneColor.buffer``).
COLOR_SOURCES = (
    Tex("lighting"),
    *(Tex(n, optional=True) for n in ACCUM),
    Tex(TAA_OUTPUT, optional=True),
    Tex(FILTER_OUTPUT, optional=True),
)


class ColorCorrectionTask(Pass):
    name = "color_correction"
    only_final = True
    #: The display image is what a window shows: kept even when no AOV asks for it.
    side_effect = True
    reads = (Rec(SceneColor), *COLOR_SOURCES, Imported("color_pipeline"))
    writes = (Tex("display", "rgba8"),)

    def __init__(self, delegate: GLRenderDelegate, pipeline: ColorPipeline) -> None:
        super().__init__(delegate)
        self.pipeline = pipeline
        self._pass: ColorCorrectionPass | None = None

    def execute(self, frame: FrameContext) -> None:
        if self._pass is None:
            self._pass = ColorCorrectionPass(frame.ctx, self.pipeline)
        src = frame.buffers.textures[frame.get(SceneColor).buffer]
        self._pass.run(src, frame.buffers.textures["display"])

    def release(self) -> None:
        if self._pass is not None:
            self._pass.release()
            self._pass = None
