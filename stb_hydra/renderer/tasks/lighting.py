"""Lighting task: runs the selected lighting method into the 'lighting' buffer."""

from __future__ import annotations

from .base import Task


class LightingTask(Task):
    name = "lighting"

    def __init__(self, engine, method) -> None:
        super().__init__(engine)
        self.method = method

    def prepare(self, frame) -> None:
        self.method.prepare(frame)

    def execute(self, frame) -> None:
        frame.buffers.texture("lighting", 4, "f2")
        self.method.execute(frame)

    def release(self) -> None:
        self.method.release()
