"""Scene index base (Hydra 2.0 vocabulary): prims, observers and change notices.

A scene index is a flat map ``path -> SceneIndexPrim(prim_type, data_source)``.
Observers receive ``PrimsAdded``, ``PrimsRemoved`` and ``PrimsDirtied`` batches
(with the data-source locators that changed). Paths are plain strings: USD
prim paths, or synthesised children for expanded PointInstancer instances.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from typing import Any, Protocol


@dataclass(frozen=True, slots=True)
class AddedPrimEntry:
    path: str
    prim_type: str


@dataclass(frozen=True, slots=True)
class DirtiedPrimEntry:
    path: str
    locators: frozenset[str]


@dataclass(slots=True)
class SceneIndexPrim:
    prim_type: str
    #: Object with the prim kind's ``read_*`` methods (see ``stage_scene_index``).
    data_source: Any = None


class SceneIndexObserver(Protocol):
    def prims_added(self, sender: SceneIndex, entries: list[AddedPrimEntry]) -> None: ...

    def prims_removed(self, sender: SceneIndex, paths: list[str]) -> None: ...

    def prims_dirtied(self, sender: SceneIndex, entries: list[DirtiedPrimEntry]) -> None: ...


@dataclass
class NoticeCounters:
    """How many notices of each kind were sent (tests assert on these)."""

    added: int = 0
    removed: int = 0
    dirtied: int = 0
    batches: int = 0
    locators: dict[str, int] = field(default_factory=dict)

    def reset(self) -> None:
        self.added = self.removed = self.dirtied = self.batches = 0
        self.locators.clear()


class SceneIndex:
    """Base class: prim storage is the subclass's; this holds observers."""

    def __init__(self) -> None:
        self._observers: list[SceneIndexObserver] = []
        self.counters = NoticeCounters()

    # -- queries (override) --
    def get_prim(self, path: str) -> SceneIndexPrim | None:
        raise NotImplementedError

    def prim_paths(self) -> Iterator[str]:
        raise NotImplementedError

    # -- observers --
    def add_observer(self, observer: SceneIndexObserver) -> None:
        if observer not in self._observers:
            self._observers.append(observer)

    def _send_added(self, entries: list[AddedPrimEntry]) -> None:
        if not entries:
            return
        self.counters.added += len(entries)
        self.counters.batches += 1
        for o in list(self._observers):
            o.prims_added(self, entries)

    def _send_removed(self, paths: list[str]) -> None:
        if not paths:
            return
        self.counters.removed += len(paths)
        self.counters.batches += 1
        for o in list(self._observers):
            o.prims_removed(self, paths)

    def _send_dirtied(self, entries: Iterable[DirtiedPrimEntry]) -> None:
        entries = list(entries)
        if not entries:
            return
        self.counters.dirtied += len(entries)
        self.counters.batches += 1
        locs = self.counters.locators
        for e in entries:
            for loc in e.locators:
                locs[loc] = locs.get(loc, 0) + 1
        for o in list(self._observers):
            o.prims_dirtied(self, entries)
