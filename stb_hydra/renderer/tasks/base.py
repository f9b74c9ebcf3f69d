"""Pass base class (Hydra's HdTask with Falcor-style declared I/O).

A pass names the resources it reads and writes (``reads``/``writes``: ``Tex``,
``Rec``, ``Imported`` from ``graph.py``), and implements Hydra's phases:
``sync`` (scene changes, no GL), ``prepare`` (CPU work, in graph order, before the
frame's uniforms are written), ``execute`` (GPU work, in graph order). The engine
builds the graph from the declarations, so adding a pass is one file plus one
registration in ``passes.py``. While a pass runs, ``frame.get``/``frame.put`` and
``frame.buffers`` only allow what it declared.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, ClassVar

if TYPE_CHECKING:
    from ..frame import FrameContext
    from ..gl_delegate import GLRenderDelegate
    from ..graph import Resource


class Pass:
    name: ClassVar[str] = "pass"
    #: Resources read / written (class-level; override ``io()`` when they depend on
    #: the pass's configuration).
    reads: ClassVar[tuple[Resource, ...]] = ()
    writes: ClassVar[tuple[Resource, ...]] = ()
    #: Run only on the last frame of an accumulation sequence.
    only_final: ClassVar[bool] = False
    #: Never culled, even when no other pass reads its outputs.
    side_effect: ClassVar[bool] = False

    def __init__(self, delegate: GLRenderDelegate) -> None:
        self.delegate = delegate

    def io(self) -> tuple[tuple[Resource, ...], tuple[Resource, ...]]:
        """(reads, writes) of this pass as configured."""
        return self.reads, self.writes

    def sync(self, frame: FrameContext) -> None:
        """Pick up scene changes (cheap; no GL)."""

    def prepare(self, frame: FrameContext) -> None:
        """CPU work before the frame's uniforms are written (culling, scheduling)."""

    def execute(self, frame: FrameContext) -> None:
        """GPU work."""

    def release(self) -> None:
        """Free GL objects the pass owns."""


#: Hydra's name for a pass.
Task = Pass
