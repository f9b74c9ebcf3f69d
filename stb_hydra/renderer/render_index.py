"""``RenderIndex``: one render prim per scene prim, synced by dirty bits.

It observes a scene index: ``PrimsAdded`` creates render prims through the
delegate (the prim factory) fully dirty, ``PrimsDirtied`` turns locators into
dirty bits (``scene.locators.dirty_bits_for``), ``PrimsRemoved`` destroys them.
``sync_all()`` syncs each dirty prim once with its accumulated bits and keeps
counters tests can assert on.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

from ..scene.lights_bulk import MIN_BULK_LIGHTS
from ..scene.locators import DirtyBits, dirty_bits_for
from ..scene.scene_index import AddedPrimEntry, DirtiedPrimEntry, SceneIndex
from .delegate import RenderDelegate
from .render_prims import LightSprim, RenderPrim, sync_lights


@dataclass
class SyncCounters:
    """What ``sync_all`` did. ``last`` holds the most recent call's syncs."""

    total: int = 0
    calls: int = 0
    by_type: Counter = field(default_factory=Counter)
    by_bits: Counter = field(default_factory=Counter)  # (prim_type, bits) -> count
    last: dict[str, DirtyBits] = field(default_factory=dict)

    def reset(self) -> None:
        self.total = self.calls = 0
        self.by_type.clear()
        self.by_bits.clear()
        self.last.clear()


class RenderIndex:
    def __init__(self, scene_index: SceneIndex, delegate: RenderDelegate) -> None:
        self.scene_index = scene_index
        self.delegate = delegate
        self.prims: dict[str, RenderPrim] = {}
        self._dirty: dict[str, DirtyBits] = {}
        self.counters = SyncCounters()
        scene_index.add_observer(self)
        self._insert(
            AddedPrimEntry(p, sp.prim_type)
            for p in scene_index.prim_paths()
            if (sp := scene_index.get_prim(p)) is not None
        )

    # -- observer --
    def prims_added(self, sender: SceneIndex, entries: list[AddedPrimEntry]) -> None:
        self._insert(entries)

    def prims_removed(self, sender: SceneIndex, paths: list[str]) -> None:
        for p in paths:
            rp = self.prims.pop(p, None)
            self._dirty.pop(p, None)
            if rp is not None:
                self.delegate.destroy_prim(rp)

    def prims_dirtied(self, sender: SceneIndex, entries: list[DirtiedPrimEntry]) -> None:
        prims = self.prims
        dirty = self._dirty
        for e in entries:
            rp = prims.get(e.path)
            if rp is None:
                continue
            bits = dirty_bits_for(rp.prim_type, e.locators)
            if bits:
                dirty[e.path] = dirty.get(e.path, DirtyBits.Clean) | bits

    def mark_dirty(self, path: str, bits: DirtyBits = DirtyBits.AllDirty) -> bool:
        """Sync prim ``path`` again on the next :meth:`sync_all` (something it reads
        outside the stage changed, e.g. a texture file on disk). False: no such prim."""
        if path not in self.prims:
            return False
        self._dirty[path] = self._dirty.get(path, DirtyBits.Clean) | bits
        return True

    def _insert(self, entries: Iterable[AddedPrimEntry]) -> None:
        for e in entries:
            old = self.prims.pop(e.path, None)
            if old is not None:
                self.delegate.destroy_prim(old)
            rp = self.delegate.create_prim(e.prim_type, e.path)
            if rp is not None:
                self.prims[e.path] = rp
                self._dirty[e.path] = DirtyBits.AllDirty

    # -- sync --
    def sync_all(self) -> int:
        """Sync every dirty prim (materials and cameras first, then geometry and
        lights). Returns the number of prims synced."""
        if not self._dirty:
            self.counters.last = {}
            self.counters.calls += 1
            return 0
        dirty, self._dirty = self._dirty, {}
        si = self.scene_index
        c = self.counters
        c.calls += 1
        c.last = dirty
        order = sorted(dirty, key=lambda p: _SYNC_ORDER.get(self.prims[p].prim_type, 3))
        batch: dict[type, tuple[list[LightSprim], list[Any], list[DirtyBits]]] = {}
        for path in order:
            rp = self.prims.get(path)
            sp = si.get_prim(path)
            if rp is None or sp is None:
                continue
            bits = dirty[path]
            ds = sp.data_source
            if isinstance(rp, LightSprim) and rp.needs_full_read(bits) and hasattr(ds, "lights"):
                b = batch.setdefault(type(ds), ([], [], []))
                b[0].append(rp)
                b[1].append(ds)
                b[2].append(bits)
            else:
                rp.sync(ds, bits)
            c.by_type[rp.prim_type] += 1
            c.by_bits[(rp.prim_type, int(bits))] += 1
        for sprims, sources, bits_list in batch.values():
            if len(sprims) >= MIN_BULK_LIGHTS:
                sync_lights(sprims, sources, bits_list)
            else:
                for rp, ds, bits in zip(sprims, sources, bits_list, strict=True):
                    rp.sync(ds, bits)
        c.total += len(dirty)
        return len(dirty)


_SYNC_ORDER = {"material": 0, "camera": 1, "mesh": 2}
