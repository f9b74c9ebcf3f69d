"""ColorCorrectionTask: scene-linear -> display through OCIO's GPU shader."""

from __future__ import annotations

from ...color.ocio import ColorCorrectionPass, ColorPipeline
from .base import Task


class ColorCorrectionTask(Task):
    only_final = True
    name = "color_correction"

    def __init__(self, engine, pipeline: ColorPipeline) -> None:
        super().__init__(engine)
        self.pipeline = pipeline
        self._pass: ColorCorrectionPass | None = None

    def execute(self, frame) -> None:
        if self._pass is None:
            self._pass = ColorCorrectionPass(frame.ctx, self.pipeline)
        src = frame.buffers.textures[frame.color_buffer]
        dst = frame.buffers.texture("display", 4, "f1")
        self._pass.run(src, dst)

    def release(self) -> None:
        if self._pass is not None:
            self._pass.release()
            self._pass = None
