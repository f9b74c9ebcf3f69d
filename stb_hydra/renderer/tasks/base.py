"""Task base class (Hydra's HdTask): sync -> prepare -> execute."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from ..engine import Engine
    from ..frame import FrameContext


class Task:
    name = "task"
    #: Run only on the last frame of an accumulation sequence.
    only_final = False

    def __init__(self, engine: Engine) -> None:
        self.engine = engine

    def sync(self, frame: FrameContext) -> None:
        """Pick up scene changes (cheap; no GL)."""

    def prepare(self, frame: FrameContext) -> None:
        """CPU work before resources are committed (culling, scheduling)."""

    def execute(self, frame: FrameContext) -> None:
        """GPU work."""

    def release(self) -> None:
        pass
