"""Shadow-map atlas allocator: power-of-two quadtree (buddy) blocks in one square texture.

No GL here. Conventions the GL capture / sampling code relies on:

* **Origin.** ``AtlasRect(x, y, size)`` is the block whose first texel is (x, y),
  counted in texels from texel (0, 0) of the atlas texture: exactly the offsets of
  ``glViewport`` / ``glScissor`` / ``glTexSubImage2D``. With GL's bottom-left
  texture origin, (0, 0) is the bottom-left texel and the block starts at
  UV (x / S, y / S). Nothing here flips Y.
* **Border.** A rect *includes* its PCF border (``SHADOW_MAP_BORDER_PX``): the capture
  renders ``size - 2 * border`` texels square into ``interior()`` and fills the
  ``border`` texels around it (clamp-replicate for spot maps, octahedral fold for
  omni maps). ``uv_scale_offset()`` maps the map's [0, 1]^2 interior UV to atlas UV.
* **Alignment.** Blocks are squares of a power-of-two side in [min_map, max_map],
  aligned to their size (x % size == y % size == 0); two blocks never overlap.

Placement: best fit (smallest free block that holds the request), lowest Morton code
among equals, split toward the lowest-Morton child; a freed block coalesces with its
three buddies. Everything is deterministic: same calls -> same rects.

When the atlas is full, a request of priority p (``displace=True``):
  1. halves maps of priority < p one step at a time, lowest priority first (ties:
     largest, then oldest), each down to ``min_map``, until the request fits;
     a halved map moves into the best-fitting free block elsewhere when there is one
     (so its whole old block frees up), else it stays at its origin;
  2. only then halves the request itself, down to ``floor`` (default ``min_map``);
  3. at ``min_map``, evicts the lowest-priority map of priority < p;
  4. only then refuses. Maps of priority >= p are never touched.
A request that cannot reach its ``floor`` changes nothing: the maps it touched are put
back exactly (journal + rollback). A cheap area test skips hopeless attempts. Every
map whose rect changed must be re-rendered (its old texels may already belong to
another map): results list them.
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Hashable, Iterator
from dataclasses import dataclass

import numpy as np

from stb_hydra.limits import (
    SHADOW_ATLAS_SIZE_DEFAULT,
    SHADOW_ATLAS_SIZE_MAX,
    SHADOW_MAP_BORDER_PX,
    SHADOW_MAP_MAX_SIZE,
    SHADOW_MAP_MIN_SIZE,
)

__all__ = ["AllocResult", "AtlasRect", "AtlasStats", "ShadowAtlas", "is_pow2"]


def is_pow2(n: int) -> bool:
    """True for 1, 2, 4, ... (ints only)."""
    return isinstance(n, (int, np.integer)) and n > 0 and (int(n) & (int(n) - 1)) == 0


def _part1by1(v: int) -> int:
    v &= 0xFFFF
    v = (v | (v << 8)) & 0x00FF00FF
    v = (v | (v << 4)) & 0x0F0F0F0F
    v = (v | (v << 2)) & 0x33333333
    return (v | (v << 1)) & 0x55555555


def _morton(x: int, y: int) -> int:
    """Z-order code of a texel position (x, y < 65536)."""
    return _part1by1(x) | (_part1by1(y) << 1)


@dataclass(frozen=True)
class AtlasRect:
    """One map's block in the atlas, in texels, border included (see module doc)."""

    x: int
    y: int
    size: int

    def interior(self, border: int = SHADOW_MAP_BORDER_PX) -> tuple[int, int, int]:
        """(x, y, side) of the rendered area inside the border (texels)."""
        return self.x + border, self.y + border, self.size - 2 * border

    def uv_scale_offset(
        self, atlas_size: int, border: int = SHADOW_MAP_BORDER_PX
    ) -> tuple[float, float, float]:
        """(scale, offset_u, offset_v): atlas_uv = offset + map_uv * scale, where map UV
        [0, 1]^2 spans the interior's outer texel edges."""
        ix, iy, side = self.interior(border)
        return side / atlas_size, ix / atlas_size, iy / atlas_size

    def overlaps(self, other: AtlasRect) -> bool:
        return (
            self.x < other.x + other.size
            and other.x < self.x + self.size
            and self.y < other.y + other.size
            and other.y < self.y + self.size
        )


@dataclass(frozen=True)
class AllocResult:
    """Outcome of ``allocate`` / ``resize``.

    ``rect`` is the key's rect after the call (None: the key has no map). ``ok`` is
    False when the request was refused (nothing changed for the key). ``displaced``
    are *other* keys whose rect changed (halved, maybe moved): re-render them.
    ``evicted`` are other keys removed from the atlas to make room.
    """

    key: Hashable
    rect: AtlasRect | None
    requested: int
    ok: bool
    changed: bool
    displaced: tuple[Hashable, ...] = ()
    evicted: tuple[Hashable, ...] = ()

    @property
    def reduced(self) -> bool:
        """Granted, but smaller than asked."""
        return self.ok and self.rect is not None and self.rect.size < self.requested


@dataclass(frozen=True)
class AtlasStats:
    """Atlas occupancy and event counters (texels; counters since construction)."""

    size: int
    maps: int
    allocated_texels: int
    free_texels: int
    occupancy: float  # allocated / atlas texels
    largest_free_block: int  # side (texels) of the largest free aligned block, 0 if full
    largest_free_fraction: float  # largest free block area / total free area (1 if none free)
    fragmentation: float  # 1 - largest_free_fraction
    failed_allocations: int
    reduced_requests: int
    downgrades: int  # halvings of other maps to make room
    evictions: int


@dataclass(slots=True)
class _Map:
    x: int
    y: int
    size: int
    priority: float
    seq: int


class ShadowAtlas:
    """Quadtree allocator of square power-of-two shadow maps in one square atlas."""

    def __init__(
        self,
        size: int = SHADOW_ATLAS_SIZE_DEFAULT,
        min_map: int = SHADOW_MAP_MIN_SIZE,
        max_map: int = SHADOW_MAP_MAX_SIZE,
    ) -> None:
        if not (is_pow2(size) and is_pow2(min_map) and is_pow2(max_map)):
            raise ValueError(f"atlas/min/max must be powers of two: {size}/{min_map}/{max_map}")
        if size > SHADOW_ATLAS_SIZE_MAX:
            raise ValueError(f"atlas size {size} > SHADOW_ATLAS_SIZE_MAX {SHADOW_ATLAS_SIZE_MAX}")
        max_map = min(max_map, size)
        if not 2 * SHADOW_MAP_BORDER_PX < min_map <= max_map:
            raise ValueError(f"need 2*border < min_map <= max_map, got {min_map}, {max_map}")
        self.size = int(size)
        self.min_map = int(min_map)
        self.max_map = int(max_map)
        levels = int(math.log2(self.size // self.min_map)) + 1
        self._sizes = [self.min_map << i for i in range(levels)]
        self._free: dict[int, set[tuple[int, int]]] = {s: set() for s in self._sizes}
        self._heap: dict[int, list[tuple[int, int, int]]] = {s: [] for s in self._sizes}
        self._free_texels = 0
        self._maps: dict[Hashable, _Map] = {}
        self._seq = 0
        self._failed = 0
        self._reduced = 0
        self._downgrades = 0
        self._evictions = 0
        self._release(0, 0, self.size)

    # --- queries ------------------------------------------------------------------------

    def __contains__(self, key: Hashable) -> bool:
        return key in self._maps

    def __len__(self) -> int:
        return len(self._maps)

    def __iter__(self) -> Iterator[Hashable]:
        return iter(list(self._maps))

    def keys(self) -> list[Hashable]:
        return list(self._maps)

    def rect(self, key: Hashable) -> AtlasRect | None:
        m = self._maps.get(key)
        return None if m is None else AtlasRect(m.x, m.y, m.size)

    def priority(self, key: Hashable) -> float | None:
        m = self._maps.get(key)
        return None if m is None else m.priority

    def rects(self) -> dict[Hashable, AtlasRect]:
        return {k: AtlasRect(m.x, m.y, m.size) for k, m in self._maps.items()}

    def free_blocks(self) -> list[AtlasRect]:
        """Every free block, largest first then Morton order."""
        out = [AtlasRect(x, y, s) for s in self._sizes for (x, y) in self._free[s]]
        out.sort(key=lambda r: (-r.size, _morton(r.x, r.y)))
        return out

    def largest_free(self) -> int:
        """Side (texels) of the largest free block, 0 when full."""
        for s in reversed(self._sizes):
            if self._free[s]:
                return s
        return 0

    def stats(self) -> AtlasStats:
        total = self.size * self.size
        largest = self.largest_free()
        frac = 1.0 if self._free_texels == 0 else largest * largest / self._free_texels
        return AtlasStats(
            size=self.size,
            maps=len(self._maps),
            allocated_texels=total - self._free_texels,
            free_texels=self._free_texels,
            occupancy=(total - self._free_texels) / total,
            largest_free_block=largest,
            largest_free_fraction=frac,
            fragmentation=1.0 - frac,
            failed_allocations=self._failed,
            reduced_requests=self._reduced,
            downgrades=self._downgrades,
            evictions=self._evictions,
        )

    # --- mutations ----------------------------------------------------------------------

    def clamp_size(self, size: int) -> int:
        """Validate a requested side (power of two) and clamp it to [min_map, max_map]."""
        if not is_pow2(size):
            raise ValueError(f"shadow map size must be a power of two, got {size!r}")
        return int(min(max(int(size), self.min_map), self.max_map))

    def set_priority(self, key: Hashable, priority: float) -> None:
        self._maps[key].priority = _check_priority(priority)

    def allocate(
        self,
        key: Hashable,
        size: int,
        priority: float,
        *,
        displace: bool = True,
        floor: int | None = None,
    ) -> AllocResult:
        """Place a map of side ``size`` (texels, clamped) for ``key``.

        ``displace``: may halve / evict maps of lower priority (see module doc); else
        only free space is used. The request itself is halved down to ``floor``
        (default ``min_map``) if needed; if it cannot get >= ``floor`` nothing changes
        and ``ok`` is False. An existing key is resized instead.
        """
        if key in self._maps:
            return self.resize(key, size, priority, displace=displace, floor=floor)
        priority = _check_priority(priority)
        size = self.clamp_size(size)
        floor = self.min_map if floor is None else min(self.clamp_size(floor), size)
        blk = self._take(size)
        if blk is not None:
            self._insert(key, blk, size, priority)
            return AllocResult(key, AtlasRect(*blk, size), size, True, True)
        got = size
        displaced: dict[Hashable, None] = {}
        evicted: list[Hashable] = []
        journal: dict[Hashable, tuple[int, int, int, _Map]] = {}
        counters = (self._downgrades, self._evictions)
        if self._may_fit(floor, priority, displace):
            blk, got, displaced, evicted = self._acquire(size, priority, displace, floor, journal)
        if blk is None:
            self._rollback(journal, counters)
            self._failed += 1
            return AllocResult(key, None, size, False, False)
        self._insert(key, blk, got, priority)
        self._reduced += got < size
        return AllocResult(
            key, AtlasRect(*blk, got), size, True, True, tuple(displaced), tuple(evicted)
        )

    def resize(
        self,
        key: Hashable,
        size: int,
        priority: float | None = None,
        *,
        displace: bool = True,
        floor: int | None = None,
    ) -> AllocResult:
        """Change the side of ``key``'s map (free + allocate; the map may move).

        A shrink always succeeds at exactly ``size``. A grow either ends at least one
        step larger (default ``floor`` = 2 * current side; maybe less than asked) or
        changes nothing (``ok`` False, state rolled back). Same size: priority only.
        """
        m = self._maps[key]
        if priority is not None:
            m.priority = _check_priority(priority)
        size = self.clamp_size(size)
        if size == m.size:
            return AllocResult(key, AtlasRect(m.x, m.y, m.size), size, True, False)
        if floor is None:
            floor = size if size < m.size else 2 * m.size
        floor = min(self.clamp_size(floor), size)
        old = (m.x, m.y, m.size)
        blk = self._take(size)  # first try with the old block still held: no churn
        if blk is not None:
            self._release(*old)
            m.x, m.y, m.size = blk[0], blk[1], size
            return AllocResult(key, AtlasRect(m.x, m.y, size), size, True, True)
        del self._maps[key]
        self._release(*old)
        blk = self._take(size)  # the old block (maybe coalesced) may be enough
        got = size
        displaced: dict[Hashable, None] = {}
        evicted: list[Hashable] = []
        journal: dict[Hashable, tuple[int, int, int, _Map]] = {}
        counters = (self._downgrades, self._evictions)
        if blk is None and self._may_fit(floor, m.priority, displace):
            blk, got, displaced, evicted = self._acquire(size, m.priority, displace, floor, journal)
        if blk is None:
            self._rollback(journal, counters)
            self._take_exact(*old)
            self._maps[key] = m
            self._failed += 1
            return AllocResult(key, AtlasRect(*old), size, False, False)
        m.x, m.y, m.size = blk[0], blk[1], got
        self._maps[key] = m
        self._reduced += got < size
        return AllocResult(
            key,
            AtlasRect(m.x, m.y, got),
            size,
            True,
            (m.x, m.y, m.size) != old,
            tuple(displaced),
            tuple(evicted),
        )

    def free(self, key: Hashable) -> None:
        """Release ``key``'s block (KeyError if it has none)."""
        m = self._maps.pop(key)
        self._release(m.x, m.y, m.size)

    def clear(self) -> None:
        for key in list(self._maps):
            self.free(key)

    # --- invariants (tests) -------------------------------------------------------------

    def check_invariants(self) -> None:
        """Raise AssertionError on overlap, out-of-bounds, misalignment, a missed
        coalescing or an accounting mismatch. O(atlas cells at min_map resolution)."""
        cell = self.min_map
        n = self.size // cell
        cover = np.zeros((n, n), dtype=np.int32)
        alloc = 0
        for key, m in self._maps.items():
            assert is_pow2(m.size) and self.min_map <= m.size <= self.max_map, (key, m)
            assert m.x % m.size == 0 and m.y % m.size == 0, f"misaligned {key}: {m}"
            assert 0 <= m.x and m.x + m.size <= self.size, f"out of bounds {key}: {m}"
            assert 0 <= m.y and m.y + m.size <= self.size, f"out of bounds {key}: {m}"
            assert m.priority == m.priority, f"NaN priority {key}"
            cover[m.y // cell : (m.y + m.size) // cell, m.x // cell : (m.x + m.size) // cell] += 1
            alloc += m.size * m.size
        free = 0
        for s in self._sizes:
            heap_entries = {(x, y) for (_, x, y) in self._heap[s]}
            for x, y in self._free[s]:
                assert x % s == 0 and y % s == 0, f"misaligned free block {(x, y, s)}"
                assert x + s <= self.size and y + s <= self.size, f"free block out {(x, y, s)}"
                assert (x, y) in heap_entries, f"free block missing from heap {(x, y, s)}"
                cover[y // cell : (y + s) // cell, x // cell : (x + s) // cell] += 1
                free += s * s
                if s < self.size:
                    p = 2 * s
                    px, py = x & ~(p - 1), y & ~(p - 1)
                    kids = {(px, py), (px + s, py), (px, py + s), (px + s, py + s)}
                    assert not kids <= self._free[s], f"uncoalesced buddies at {(px, py, p)}"
        assert cover.min() == 1 and cover.max() == 1, "overlap or hole in the atlas"
        assert free == self._free_texels, f"free accounting {free} != {self._free_texels}"
        assert alloc + free == self.size * self.size, "allocated + free != atlas area"

    # --- internals ----------------------------------------------------------------------

    def _insert(self, key: Hashable, blk: tuple[int, int], size: int, priority: float) -> None:
        self._maps[key] = _Map(blk[0], blk[1], size, priority, self._seq)
        self._seq += 1

    def _push_free(self, x: int, y: int, s: int) -> None:
        self._free[s].add((x, y))
        heap = self._heap[s]
        heapq.heappush(heap, (_morton(x, y), x, y))
        if len(heap) > 4 * len(self._free[s]) + 64:  # drop stale (lazily deleted) entries
            self._heap[s] = [(_morton(a, b), a, b) for (a, b) in self._free[s]]
            heapq.heapify(self._heap[s])

    def _pop_free(self, s: int) -> tuple[int, int] | None:
        free, heap = self._free[s], self._heap[s]
        while heap:
            _, x, y = heapq.heappop(heap)
            if (x, y) in free:
                free.discard((x, y))
                return x, y
        return None

    def _take(self, size: int) -> tuple[int, int] | None:
        """Best-fit block of side ``size``: split the smallest free block that holds it."""
        for s in self._sizes:
            if s < size or not self._free[s]:
                continue
            x, y = self._pop_free(s)  # type: ignore[misc]
            while s > size:
                s //= 2
                self._push_free(x + s, y, s)
                self._push_free(x, y + s, s)
                self._push_free(x + s, y + s, s)
            self._free_texels -= size * size
            return x, y
        return None

    def _take_exact(self, x: int, y: int, size: int) -> None:
        """Take the block (x, y, size), which must lie in a free block."""
        for s in self._sizes:
            if s < size:
                continue
            bx, by = x & ~(s - 1), y & ~(s - 1)
            if (bx, by) in self._free[s]:
                self._free[s].discard((bx, by))
                while s > size:
                    s //= 2
                    for cx, cy in ((bx, by), (bx + s, by), (bx, by + s), (bx + s, by + s)):
                        if cx <= x < cx + s and cy <= y < cy + s:
                            nx, ny = cx, cy
                        else:
                            self._push_free(cx, cy, s)
                    bx, by = nx, ny
                self._free_texels -= size * size
                return
        raise AssertionError(f"block {(x, y, size)} is not free")

    def _release(self, x: int, y: int, s: int) -> None:
        """Return a block to the free lists, coalescing it with its three buddies."""
        self._free_texels += s * s
        while s < self.size:
            p = 2 * s
            px, py = x & ~(p - 1), y & ~(p - 1)
            kids = ((px, py), (px + s, py), (px, py + s), (px + s, py + s))
            buddies = [b for b in kids if b != (x, y)]
            free = self._free[s]
            if not all(b in free for b in buddies):
                break
            for b in buddies:
                free.discard(b)
            x, y, s = px, py, p
        self._push_free(x, y, s)

    def _halve(self, key: Hashable) -> None:
        """Downgrade ``key`` one step; prefer a free block elsewhere so its old block
        frees up whole, else stay at the old origin."""
        m = self._maps[key]
        half = m.size // 2
        blk = self._take(half)
        self._release(m.x, m.y, m.size)
        if blk is None:
            blk = self._take(half)
            assert blk is not None
        m.x, m.y, m.size = blk[0], blk[1], half
        self._downgrades += 1

    def _acquire(
        self,
        size: int,
        priority: float,
        displace: bool,
        floor: int,
        journal: dict[Hashable, tuple[int, int, int, _Map]],
    ) -> tuple[tuple[int, int] | None, int, dict[Hashable, None], list[Hashable]]:
        """Make room for a request (module doc, steps 1-4). Returns (block, side,
        displaced keys, evicted keys); block None = refused: the caller rolls back with
        ``journal`` (original placement of every map touched)."""
        displaced: dict[Hashable, None] = {}
        evicted: list[Hashable] = []
        victims: list[tuple[float, int, int, Hashable]] | None = None
        s = size
        while True:
            blk = self._take(s)
            if blk is not None:
                return blk, s, displaced, evicted
            if displace:
                if victims is None:
                    victims = [
                        (m.priority, -m.size, m.seq, k)
                        for k, m in self._maps.items()
                        if m.priority < priority and m.size > self.min_map
                    ]
                    heapq.heapify(victims)
                if victims:
                    _, _, seq, k = heapq.heappop(victims)
                    self._journal(journal, k)
                    self._halve(k)
                    displaced[k] = None
                    m = self._maps[k]
                    if m.size > self.min_map:
                        heapq.heappush(victims, (m.priority, -m.size, seq, k))
                    continue
            if s > floor:
                s //= 2
                continue
            if displace and s == self.min_map:
                low = self._lowest_below(priority)
                if low is not None:
                    (k,) = low
                    self._journal(journal, k)
                    self.free(k)
                    self._evictions += 1
                    displaced.pop(k, None)
                    evicted.append(k)
                    continue
            return None, s, displaced, evicted

    def _may_fit(self, floor: int, priority: float, displace: bool) -> bool:
        """Necessary area condition for a request to get >= ``floor``: free texels plus
        what halving (and, at the min size, evicting) lower priorities could free.
        Failing it skips the make-room attempt entirely."""
        need = floor * floor
        avail = self._free_texels
        if avail >= need or not displace:
            return avail >= need
        keep = self.min_map * self.min_map if floor > self.min_map else 0
        for m in self._maps.values():
            if m.priority < priority:
                avail += m.size * m.size - keep
                if avail >= need:
                    return True
        return False

    def _lowest_below(self, priority: float) -> tuple[Hashable] | None:
        """(key,) of the lowest-priority map (ties: oldest) with priority < ``priority``."""
        best: tuple[float, int] | None = None
        out = None
        for k, m in self._maps.items():
            if m.priority < priority and (best is None or (m.priority, m.seq) < best):
                best, out = (m.priority, m.seq), (k,)
        return out

    def _journal(self, journal: dict, key: Hashable) -> None:
        if key not in journal:
            m = self._maps[key]
            journal[key] = (m.x, m.y, m.size, m)

    def _rollback(
        self, journal: dict[Hashable, tuple[int, int, int, _Map]], counters: tuple[int, int]
    ) -> None:
        """Undo a failed make-room attempt: put every touched map back where it was.
        Eager coalescing makes the free lists a function of the allocated set, so the
        atlas ends exactly as before (O(maps touched), no snapshot)."""
        for key in journal:
            m = self._maps.get(key)
            if m is not None:
                self._release(m.x, m.y, m.size)
        for key, (x, y, s, m) in journal.items():
            self._take_exact(x, y, s)
            m.x, m.y, m.size = x, y, s
            self._maps[key] = m
        self._downgrades, self._evictions = counters


def _check_priority(priority: float) -> float:
    p = float(priority)
    if p != p:
        raise ValueError("shadow map priority is NaN")
    return p
