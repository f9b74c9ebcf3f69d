"""Shadow-map update scheduler and atlas manager (no GL).

``ShadowScheduler`` owns the ``ShadowAtlas``: it places, resizes (via the resolution
policy) and frees maps, and each frame picks which maps to re-render within a budget
of texels rendered. The GL capture task calls, per frame::

    scheduler.update_lights(keys, distance_m=..., flux_lm=..., range_m=..., ...)  # sizes
    scheduler.set_transform(key, m)      # per light that moved (opaque object, e.g. 4x4)
    scheduler.mark_dirty(key, "geometry")  # static geometry in the light's range changed
    plan = scheduler.plan_frame(frame_index)   # -> [ShadowUpdate]
    ... render each update.transform into update.rect ...
    scheduler.commit(plan)               # records the captured transforms

Rules (STB_SPEC "Shadow atlas"):

* Static maps (static geometry only) are queued only when dirty: added, moved,
  resized/relocated/downgraded by the atlas, or ``mark_dirty`` by the caller.
  Dynamic maps are always due; they age from their last capture.
* Urgency = priority * frames waited (static: since it became dirty, +1; dynamic:
  since its last capture). Ties: statics first, then the map served (or added)
  longest ago -- so equal-priority dynamic maps are served in strict round robin.
* Starvation guard: while statics are pending, the first map of every frame is the
  most urgent static, even if it alone exceeds the budget. Then more statics are
  taken while the frame's spend is < ``static_reserve * budget``; then statics and
  dynamics compete by urgency while the spend is < budget.
* Budget: maps are taken while the cost already planned is < budget, so a frame
  overspends by *less than one map* (the last one taken), never more; a frame with
  pending work always renders at least one map. A map's cost is its texels plus a
  fixed charge per render pass (``pass_overhead_texels``): without it, hundreds of
  tiny maps fit a texel budget and their per-pass overhead makes a hitch.
* Time budget (``budget_ms``, optional, with a ``ShadowCostModel``): each map's cost
  is also predicted in milliseconds from its texels, passes and the triangles it
  submits (``set_work``). In strict urgency order, a map is taken only while the
  predicted milliseconds *after* it stay <= ``budget_ms`` (the static reserve:
  ``static_reserve * budget_ms``), so a frame never plans past its time budget --
  except the first map of a frame, which is always taken (starvation guard; a
  splittable map, below, only its first face(s)). When both budgets are given, a
  frame closes at whichever limit it reaches first. A split map closes the frame.
* Face-granular captures (time budget only): a map registered with ``faces`` > 1 (an
  omni cube: 6) whose remaining faces do not fit the milliseconds left is split: the
  longest run of its remaining faces (in face order) that fits is planned this frame
  (at least one face when it is the first map of the frame: nothing starves), the rest
  in later frames. A face's cost is its share of the texels and passes plus its own
  triangles (``set_work`` with per-face counts); the copy pass is charged to the chunk
  that completes the map. The map counts as captured (valid, clean, ``captured``
  transform, dynamic age) only when its last face is committed; progress is kept only
  while the light's generation, rect and transform stay those of its first face (a
  move, a new dirt or a new rect restarts it). Without a time budget, or when the
  map fits, it is planned whole (``ShadowUpdate.faces`` None), as before.
* Lights out of view are not dropped: their priority is scaled down (policy), so they
  are downgraded first and refreshed last.
* A map remembers the transform it was captured with (``captured_transform``);
  shadows are evaluated with it, not with the light's current transform. A map is
  *valid* once captured at its current rect (a rect change invalidates it: the GL
  code must not sample an invalid map) and *fresh* when valid, captured with the
  current transform and not dirty.
* Under-sized maps (granted less than the policy asked) and evicted ones (no rect)
  are retried, ``SHADOW_UPGRADES_PER_FRAME`` per frame, highest priority first; a
  retry never shrinks anything of equal or higher priority.
"""

from __future__ import annotations

import heapq
from collections import deque
from collections.abc import Hashable, Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np

from stb_hydra.limits import (
    SHADOW_MAP_MIN_SIZE,
    SHADOW_STATIC_RESERVE_FRACTION,
    SHADOW_STATS_WINDOW_FRAMES,
    SHADOW_TEXELS_PER_PIXEL,
    SHADOW_UPDATE_BUDGET_TEXELS_DEFAULT,
    SHADOW_UPGRADE_RETRY_FRAMES,
    SHADOW_UPGRADES_PER_FRAME,
)
from stb_hydra.shadows import policy
from stb_hydra.shadows.atlas import AllocResult, AtlasRect, AtlasStats, ShadowAtlas
from stb_hydra.shadows.cost import ShadowCostModel

__all__ = ["SchedulerStats", "ShadowScheduler", "ShadowUpdate", "WaitStats", "same_transform"]

#: Urgency floor for priority 0 lights so they still age (and get served eventually).
_PRIORITY_FLOOR = 1.0e-12


def _mask(faces: Iterable[int]) -> int:
    return sum(1 << f for f in set(faces))


def same_transform(a: object, b: object) -> bool:
    """Exact equality of two opaque transforms (numpy arrays compared elementwise)."""
    if a is b:
        return True
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a_arr, b_arr = np.asarray(a), np.asarray(b)
        return a_arr.shape == b_arr.shape and bool(np.array_equal(a_arr, b_arr))
    try:
        return bool(a == b)
    except (TypeError, ValueError):
        return False


@dataclass(frozen=True)
class ShadowUpdate:
    """One capture to render this frame: ``transform`` into ``rect`` (border included)."""

    key: Hashable
    rect: AtlasRect
    reason: str  # "+"-joined dirty reasons (sorted), or "refresh" for a clean dynamic map
    cost: int  # texels rendered (cost_factor * side^2)
    transform: object  # light transform to capture with (current at plan time)
    dynamic: bool
    frame: int
    gen: int = field(default=0, repr=False, compare=False)
    #: Predicted milliseconds (the cost model's; 0 without one).
    cost_ms: float = field(default=0.0, compare=False)
    #: Texels, passes and triangles the capture renders (cost-model features).
    passes: int = field(default=1, repr=False, compare=False)
    triangles: float = field(default=0.0, repr=False, compare=False)
    #: Faces rendered this frame (face order of ``shadows.capture.face_rotations``);
    #: None: the whole map (every face, then the copy) -- the only case without a
    #: time budget.
    faces: tuple[int, ...] | None = None
    #: First chunk of a split map (start a fresh depth target) ...
    first: bool = True
    #: ... and the chunk that completes it (copy into the atlas; the map is captured).
    complete: bool = True


@dataclass(frozen=True)
class WaitStats:
    """Frames over the stats window (0 = served in the frame it became due)."""

    count: int
    mean: float
    p95: float
    max: float


@dataclass(frozen=True)
class SchedulerStats:
    frame: int  # last planned frame
    lights: int
    unplaced: int  # lights with no rect (evicted / refused): unshadowed
    undersized: int  # lights granted less than the policy asked
    statics_pending: int
    dynamic_maps: int
    maps_planned: int  # last plan_frame
    texels_planned: int
    budget_texels: int
    ms_planned: float  # predicted by the cost model (0 without one)
    budget_ms: float | None
    maps_updated: int  # last commit
    texels_rendered: int
    static_wait: WaitStats  # frames a dirty static map waited before its capture
    dynamic_age: WaitStats  # frames between two captures of a dynamic map
    oldest_pending: int  # frames the longest-waiting pending static has waited so far
    stale_maps: int  # lights whose map is not fresh (invalid, dirty, moved or unplaced)
    atlas: AtlasStats
    partial_maps: int = 0  # split maps with some (not all) faces rendered


@dataclass(slots=True)
class _Light:
    key: Hashable
    seq: int
    dynamic: bool
    cost_factor: float
    passes: int
    priority: float
    desired: int
    transform: object
    rect: AtlasRect | None = None
    captured: object = None
    has_capture: bool = False
    valid: bool = False
    dirty_since: int | None = None
    last_mark: int = 0
    reasons: set[str] = field(default_factory=set)
    gen: int = 0
    last_served: int = -1
    ticket: int = 0  # service order: lower = served (or added) longer ago
    retry_after: int = 0
    triangles: float = 0.0  # submitted per capture (after culling): cost-model feature
    faces: int = 1  # capture faces the scheduler may split the map into (1: whole)
    face_tris: np.ndarray | None = None  # (faces,) triangles per face (None: even)
    part_mask: int = 0  # faces rendered of a split capture in progress (bit per face)
    part_gen: int = -1  # gen, rect and transform that capture started with
    part_rect: AtlasRect | None = None
    part_transform: object = None


class ShadowScheduler:
    """Per-frame shadow-map update planner that owns the atlas (see module doc)."""

    def __init__(
        self,
        atlas: ShadowAtlas | None = None,
        *,
        budget_texels: int = SHADOW_UPDATE_BUDGET_TEXELS_DEFAULT,
        static_reserve: float = SHADOW_STATIC_RESERVE_FRACTION,
        stats_window: int = SHADOW_STATS_WINDOW_FRAMES,
        upgrades_per_frame: int = SHADOW_UPGRADES_PER_FRAME,
        pass_overhead_texels: int = 0,
        budget_ms: float | None = None,
        cost_model: ShadowCostModel | None = None,
    ) -> None:
        if budget_texels < 0 or not 0.0 <= static_reserve <= 1.0:
            raise ValueError("budget_texels must be >= 0 and static_reserve in [0, 1]")
        if pass_overhead_texels < 0:
            raise ValueError("pass_overhead_texels must be >= 0")
        #: Fixed cost of one capture render pass, in texel equivalents, charged on
        #: top of the texels (limits.SHADOW_PASS_OVERHEAD_TEXELS in the engine).
        self.pass_overhead_texels = int(pass_overhead_texels)
        if budget_ms is not None and not (budget_ms > 0 and np.isfinite(budget_ms)):
            raise ValueError(
                f"budget_ms must be a positive number of milliseconds, got {budget_ms}"
            )
        #: Milliseconds of captures per frame (None: no time budget), priced by
        #: ``cost_model`` (a default ``ShadowCostModel`` when none is given).
        self.budget_ms = None if budget_ms is None else float(budget_ms)
        self.cost_model = cost_model if cost_model is not None else ShadowCostModel()
        self.atlas = atlas if atlas is not None else ShadowAtlas()
        self.budget_texels = int(budget_texels)
        self.static_reserve = float(static_reserve)
        self.stats_window = int(stats_window)
        self.upgrades_per_frame = int(upgrades_per_frame)
        self._lights: dict[Hashable, _Light] = {}
        self._pending: dict[Hashable, None] = {}  # dirty static lights (ordered set)
        self._dynamic: dict[Hashable, None] = {}
        self._undersized: dict[Hashable, None] = {}
        self._seq = 0
        self._ticket = 0
        self._now = 0  # frame that dirt marked now belongs to
        self._last_planned = -1
        self._planned = (0, 0)
        self._planned_ms = 0.0
        self._committed = (0, 0)
        self._static_wait: deque[tuple[int, int]] = deque()
        self._dynamic_age: deque[tuple[int, int]] = deque()

    # --- lights -------------------------------------------------------------------------

    def __contains__(self, key: Hashable) -> bool:
        return key in self._lights

    def __len__(self) -> int:
        return len(self._lights)

    def add_light(
        self,
        key: Hashable,
        *,
        dynamic: bool,
        transform: object,
        size: int = SHADOW_MAP_MIN_SIZE,
        priority: float = 1.0,
        cost_factor: float = 1.0,
        passes: int = 1,
        faces: int = 1,
    ) -> AtlasRect | None:
        """Register a shadowed light and place its map (dirty "added").

        ``cost_factor``: texels rendered per atlas texel (1 spot,
        ``SHADOW_OMNI_COST_FACTOR`` omni); ``passes``: render passes per capture
        (the copy included: 2 spot, 7 omni), each charged ``pass_overhead_texels``;
        ``faces``: faces a capture may be split into under a time budget (6: an omni
        cube rendered face by face, one pass each, then the copy; 1: never split).
        Returns the rect (None: no room yet).
        """
        if faces < 1 or (faces > 1 and passes != faces + 1):
            raise ValueError(f"a map split into {faces} faces renders faces + 1 passes")
        if key in self._lights:
            raise KeyError(f"shadow light {key!r} already added")
        light = _Light(
            key=key,
            seq=self._seq,
            dynamic=bool(dynamic),
            cost_factor=float(cost_factor),
            passes=max(int(passes), 1),
            priority=float(priority),
            desired=self.atlas.clamp_size(size),
            transform=transform,
            last_served=self._now - 1,
            ticket=self._next_ticket(),
            faces=int(faces),
        )
        self._seq += 1
        self._lights[key] = light
        if light.dynamic:
            self._dynamic[key] = None
        self._dirty(light, "added")
        self._place(light, "added")
        return light.rect

    def remove_light(self, key: Hashable) -> None:
        """Forget a light and free its map."""
        self._lights.pop(key)
        if key in self.atlas:
            self.atlas.free(key)
        self._pending.pop(key, None)
        self._dynamic.pop(key, None)
        self._undersized.pop(key, None)
        for k in self._undersized:  # space freed: retry under-sized maps right away
            self._lights[k].retry_after = 0

    def set_transform(self, key: Hashable, transform: object) -> None:
        """Current light transform; a change marks the map dirty ("moved"). Moving back
        to the captured transform before a re-capture clears a move-only dirt."""
        light = self._lights[key]
        if same_transform(transform, light.transform):
            return
        light.transform = transform
        back = light.valid and light.has_capture and same_transform(transform, light.captured)
        if back and light.reasons <= {"moved"}:
            self._clean(light)
        else:
            self._dirty(light, "moved")

    def set_priority(self, key: Hashable, priority: float) -> None:
        light = self._lights[key]
        light.priority = float(priority)
        if key in self.atlas:
            self.atlas.set_priority(key, light.priority)

    def set_size(self, key: Hashable, size: int) -> None:
        """Desired map side (texels, power of two); resizes now (may displace lower
        priorities; a grow that cannot happen is retried later)."""
        self._set_size(self._lights[key], size)

    def set_dynamic(self, key: Hashable, dynamic: bool) -> None:
        """Switch between static and dynamic updates (``stb:shadow:update``)."""
        light = self._lights[key]
        if light.dynamic == bool(dynamic):
            return
        light.dynamic = bool(dynamic)
        if light.dynamic:
            self._dynamic[key] = None
            self._pending.pop(key, None)
            light.last_served = self._now - 1
        else:
            self._dynamic.pop(key, None)
            self._dirty(light, "geometry")  # its map held dynamic geometry

    def set_work(self, key: Hashable, triangles: float | Sequence[float] | np.ndarray) -> None:
        """Triangles one capture of ``key`` submits (after culling; cost-model feature):
        a total, or one number per face (``faces`` of ``add_light``) -- what a split
        capture's chunks are priced with (a total is shared evenly by the faces)."""
        light = self._lights[key]
        t = np.maximum(np.asarray(triangles, dtype=np.float64), 0.0)
        if t.ndim == 0:
            light.triangles, light.face_tris = float(t), None
            return
        if t.shape != (light.faces,):
            raise ValueError(f"{key!r}: {t.shape[0]} per-face triangle counts, {light.faces} faces")
        light.triangles, light.face_tris = float(t.sum()), t

    def mark_dirty(self, key: Hashable, reason: str) -> None:
        """Queue a re-capture (e.g. "geometry": static geometry in range changed)."""
        self._dirty(self._lights[key], reason)

    def update_lights(
        self,
        keys: Sequence[Hashable],
        *,
        distance_m: np.ndarray,
        flux_lm: np.ndarray,
        range_m: np.ndarray,
        viewport_height_px: float,
        fov_y_rad: float,
        in_view: np.ndarray | None = None,
        texels_per_pixel: float = SHADOW_TEXELS_PER_PIXEL,
        footprint_need: np.ndarray | None = None,
        resolution: str = policy.DEFAULT_RESOLUTION,
    ) -> None:
        """Apply the resolution policy to ``keys`` (arrays aligned with them): set
        priorities, then shrink, then grow (highest priority first). Units: metres,
        lumens, pixels, radians; see ``policy``. ``footprint_need``: the footprint
        pass's measure per light (NaN: not measured), used as ``resolution`` says
        (``policy.combine_targets``)."""
        lights = [self._lights[k] for k in keys]
        cur = np.fromiter((lt.desired for lt in lights), dtype=np.int64, count=len(lights))
        target = policy.target_texels(
            distance_m, flux_lm, range_m, viewport_height_px, fov_y_rad, texels_per_pixel
        )
        if footprint_need is not None and resolution != "flux":
            fp = policy.footprint_texels(footprint_need)
            target = policy.combine_targets(
                target,
                fp,
                resolution,
                budget_texels=float(self.atlas.size) ** 2,
                min_size=self.atlas.min_map,
                max_size=self.atlas.max_map,
                current_sizes=cur,
            )
        sizes = policy.sizes_from_target(
            target, cur, in_view, self.atlas.min_map, self.atlas.max_map
        )
        prios = policy.light_priorities(target, in_view)
        for light, p in zip(lights, prios.tolist()):
            if p != light.priority:
                light.priority = p
                if light.rect is not None:
                    self.atlas.set_priority(light.key, p)
        changed = [(lt, int(s)) for lt, s in zip(lights, sizes.tolist()) if s != lt.desired]
        changed.sort(key=lambda ls: (ls[1] > ls[0].desired, -ls[0].priority, ls[0].seq))
        for light, size in changed:
            self._set_size(light, size)

    # --- queries ------------------------------------------------------------------------

    def rect(self, key: Hashable) -> AtlasRect | None:
        return self._lights[key].rect

    def captured_transform(self, key: Hashable) -> object | None:
        """Transform the map was last captured with (None: never captured). Evaluate
        shadows with this one, not the light's current transform."""
        light = self._lights[key]
        return light.captured if light.has_capture else None

    def is_valid(self, key: Hashable) -> bool:
        """The map holds a capture at its current rect (safe to sample)."""
        return self._lights[key].valid

    def is_fresh(self, key: Hashable) -> bool:
        """Valid, captured with the current transform, and not dirty."""
        light = self._lights[key]
        return (
            light.valid
            and light.dirty_since is None
            and same_transform(light.captured, light.transform)
        )

    def faces(self, key: Hashable) -> int:
        """Faces ``key``'s capture may be split into (``add_light``)."""
        return self._lights[key].faces

    def priority(self, key: Hashable) -> float:
        """Current allocation / update priority of ``key`` (``policy.light_priorities``)."""
        return self._lights[key].priority

    def is_dynamic(self, key: Hashable) -> bool:
        return self._lights[key].dynamic

    def is_dirty(self, key: Hashable) -> bool:
        return self._lights[key].dirty_since is not None

    # --- per frame ----------------------------------------------------------------------

    def plan_frame(self, frame_index: int) -> list[ShadowUpdate]:
        """Choose this frame's captures (module doc). ``frame_index`` must increase."""
        frame = int(frame_index)
        if frame <= self._last_planned:
            raise ValueError(f"frame {frame} <= last planned frame {self._last_planned}")
        self._now = frame
        self._maintain(frame)
        lights = self._lights
        statics = [lights[k] for k in self._pending if lights[k].rect is not None]
        statics.sort(key=lambda lt: (-self._urgency(lt, frame), lt.ticket))
        plan: list[ShadowUpdate] = []
        spent = 0
        spent_ms = 0.0
        budget_ms = self.budget_ms
        i = 0
        split = False  # a map was split: the frame is full
        if statics:  # starvation guard + static reserve
            reserve = self.static_reserve * self.budget_texels
            reserve_ms = None if budget_ms is None else self.static_reserve * budget_ms
            faces = self._faces_within(statics[0], 0.0, budget_ms, force=True)
            while faces is not None:
                charge, ms, split = self._take(plan, statics[i], frame, faces)
                spent += charge
                spent_ms += ms
                i += 1
                if split or i == len(statics) or spent >= reserve:
                    break
                faces = self._faces_within(statics[i], spent_ms, reserve_ms, whole=True)
        rest = statics[i:] + [lights[k] for k in self._dynamic if lights[k].rect is not None]
        rest.sort(key=lambda lt: (-self._urgency(lt, frame), lt.dynamic, lt.ticket))
        for light in [] if split else rest:
            if plan and spent >= self.budget_texels:
                break
            faces = self._faces_within(light, spent_ms, budget_ms, force=not plan)
            if faces is None:
                break
            charge, ms, split = self._take(plan, light, frame, faces)
            spent += charge
            spent_ms += ms
            if split:
                break
        self._planned = (len(plan), sum(u.cost for u in plan))  # texels, not charge
        self._planned_ms = spent_ms
        self._last_planned = frame
        self._now = frame + 1
        return plan

    def commit(self, updates: Iterable[ShadowUpdate]) -> None:
        """Record rendered captures: captured transform, validity, dirt cleared unless
        the light changed after planning (then it stays dirty)."""
        n = texels = 0
        for u in updates:
            light = self._lights.get(u.key)
            if light is None or light.rect != u.rect:
                continue  # removed or moved since planning: that capture is void
            texels += u.cost
            if not u.complete:  # faces of a split capture: progress, nothing captured
                assert u.faces is not None
                same = light.gen == u.gen and same_transform(light.transform, u.transform)
                if same and (u.first or light.part_gen == u.gen):
                    light.part_mask = (0 if u.first else light.part_mask) | _mask(u.faces)
                    light.part_gen, light.part_rect = u.gen, u.rect
                    light.part_transform = u.transform
                else:
                    light.part_mask = 0  # the light changed since planning: restart
                continue
            light.part_mask = 0
            if light.dynamic:
                self._dynamic_age.append((u.frame, u.frame - light.last_served))
            light.captured = u.transform
            light.has_capture = True
            light.valid = True
            light.last_served = u.frame
            light.ticket = self._next_ticket()
            n += 1
            if light.dirty_since is None:
                continue
            if not light.dynamic:
                self._static_wait.append((u.frame, u.frame - light.dirty_since))
            if light.gen == u.gen:
                self._clean(light)
            else:
                light.dirty_since = light.last_mark
        self._committed = (n, texels)

    def stats(self) -> SchedulerStats:
        frame = self._last_planned
        lights = self._lights
        # Every pending (dirty static) light has dirty_since set (``_dirty``/``_clean``).
        oldest = max(
            (frame - lights[k].dirty_since for k in self._pending),  # type: ignore[operator]
            default=0,
        )
        return SchedulerStats(
            frame=frame,
            lights=len(lights),
            unplaced=sum(1 for lt in lights.values() if lt.rect is None),
            undersized=len(self._undersized),
            statics_pending=len(self._pending),
            dynamic_maps=len(self._dynamic),
            maps_planned=self._planned[0],
            texels_planned=self._planned[1],
            budget_texels=self.budget_texels,
            ms_planned=self._planned_ms,
            budget_ms=self.budget_ms,
            maps_updated=self._committed[0],
            texels_rendered=self._committed[1],
            static_wait=self._window(self._static_wait, frame),
            dynamic_age=self._window(self._dynamic_age, frame),
            oldest_pending=max(oldest, 0),
            stale_maps=sum(
                1 for lt in lights.values() if not lt.valid or lt.dirty_since is not None
            ),
            atlas=self.atlas.stats(),
            partial_maps=sum(1 for lt in lights.values() if lt.part_mask),
        )

    # --- internals ----------------------------------------------------------------------

    def _next_ticket(self) -> int:
        self._ticket += 1
        return self._ticket

    def _urgency(self, light: _Light, frame: int) -> float:
        p = max(light.priority, _PRIORITY_FLOOR)
        if not light.dynamic:
            return p * (frame - light.dirty_since + 1)  # type: ignore[operator]
        return p * (frame - light.last_served)

    def _texels(self, light: _Light) -> int:
        rect = light.rect
        assert rect is not None
        return round(light.cost_factor * rect.size * rect.size)

    def _remaining(self, light: _Light) -> tuple[int, ...]:
        """Faces still to render: those a split capture in progress lacks, or all of
        them (progress is dropped once the light's gen, rect or transform changed)."""
        if light.part_mask and not (
            light.part_gen == light.gen
            and light.part_rect == light.rect
            and same_transform(light.part_transform, light.transform)
        ):
            light.part_mask = 0
        return tuple(f for f in range(light.faces) if not light.part_mask >> f & 1)

    def _work(self, light: _Light, faces: tuple[int, ...]) -> tuple[int, int, float, float]:
        """Texels, passes, triangles and predicted ms of rendering ``faces`` of the map
        (the copy pass included when they complete it)."""
        if len(faces) == light.faces:  # the whole map
            texels, passes, tris = self._texels(light), light.passes, light.triangles
        else:
            k, n = len(faces), light.faces
            texels = round(self._texels(light) * k / n)
            done = bin(light.part_mask).count("1")
            passes = k + (1 if done + k == n else 0)  # one pass per face, then the copy
            ft = light.face_tris
            tris = light.triangles * k / n if ft is None else float(ft[list(faces)].sum())
        return texels, passes, tris, self.cost_model.predict(texels, passes, tris)

    def _faces_within(
        self,
        light: _Light,
        spent_ms: float,
        limit: float | None,
        *,
        force: bool = False,
        whole: bool = False,
    ) -> tuple[int, ...] | None:
        """Faces of ``light`` to plan with ``spent_ms`` already planned: all remaining
        ones if they fit ``limit`` (or there is no limit); else (unless ``whole``) the
        longest run of them that fits; with ``force`` at least one face (the first map
        of a frame). None: nothing fits."""
        rem = self._remaining(light)
        if limit is None or spent_ms + self._work(light, rem)[3] <= limit:
            return rem
        if light.faces == 1 or whole:
            return rem if force else None
        k = 0
        while k + 1 < len(rem) and spent_ms + self._work(light, rem[: k + 1])[3] <= limit:
            k += 1
        if k == 0:
            return rem[:1] if force else None
        return rem[:k]

    def _take(
        self, plan: list[ShadowUpdate], light: _Light, frame: int, faces: tuple[int, ...]
    ) -> tuple[int, float, bool]:
        """Plan ``faces`` of one capture; returns what it charges against the budgets
        (texels plus the fixed per-pass overhead, predicted milliseconds) and whether the
        map stays incomplete (split)."""
        rect = light.rect
        assert rect is not None
        texels, passes, tris, ms = self._work(light, faces)
        first = light.part_mask == 0
        complete = bin(light.part_mask).count("1") + len(faces) == light.faces
        reason = "+".join(sorted(light.reasons)) if light.reasons else "refresh"
        plan.append(
            ShadowUpdate(
                light.key,
                rect,
                reason,
                texels,
                light.transform,
                light.dynamic,
                frame,
                light.gen,
                ms,
                passes,
                tris,
                None if first and complete else faces,
                first,
                complete,
            )
        )
        return texels + passes * self.pass_overhead_texels, ms, not complete

    def _dirty(self, light: _Light, reason: str) -> None:  # (gen bump: split restarts)
        if light.dirty_since is None:
            light.dirty_since = self._now
        light.last_mark = self._now
        light.reasons.add(reason)
        light.gen += 1
        if not light.dynamic:
            self._pending[light.key] = None

    def _clean(self, light: _Light) -> None:
        light.dirty_since = None
        light.reasons.clear()
        self._pending.pop(light.key, None)

    def _set_size(self, light: _Light, size: int) -> None:
        light.desired = self.atlas.clamp_size(size)
        if light.rect is None or light.rect.size != light.desired:
            light.retry_after = 0
            self._place(light, "resized")
        else:
            self._track_size(light)

    def _place(self, light: _Light, reason: str) -> None:
        """(Re)allocate ``light`` at its desired size and apply the outcome."""
        key = light.key
        if key in self.atlas:
            res = self.atlas.resize(key, light.desired, light.priority)
        else:
            res = self.atlas.allocate(key, light.desired, light.priority)
        self._apply(res, reason)
        if not res.ok or light.rect is None or light.rect.size < light.desired:
            light.retry_after = self._now + SHADOW_UPGRADE_RETRY_FRAMES

    def _apply(self, res: AllocResult, reason: str) -> None:
        light = self._lights[res.key]
        if res.changed:
            self._rect_changed(light, res.rect, reason)
        else:
            self._track_size(light)
        for k in res.displaced:
            other = self._lights.get(k)
            if other is not None:
                self._rect_changed(other, self.atlas.rect(k), "downgraded")
        for k in res.evicted:
            other = self._lights.get(k)
            if other is not None:
                self._rect_changed(other, None, "evicted")

    def _rect_changed(self, light: _Light, rect: AtlasRect | None, reason: str) -> None:
        light.rect = rect
        light.valid = False
        self._dirty(light, reason)
        self._track_size(light)

    def _track_size(self, light: _Light) -> None:
        if light.rect is None or light.rect.size < light.desired:
            self._undersized[light.key] = None
        else:
            self._undersized.pop(light.key, None)

    def _maintain(self, frame: int) -> None:
        """Retry the most important under-sized / evicted maps (rate-limited)."""
        if not self._undersized or self.upgrades_per_frame <= 0:
            return
        due = (self._lights[k] for k in self._undersized)
        due = (lt for lt in due if lt.retry_after <= frame)
        best = heapq.nsmallest(self.upgrades_per_frame, due, key=lambda lt: (-lt.priority, lt.seq))
        for light in best:
            self._place(light, "resized" if light.rect is not None else "placed")

    def _window(self, samples: deque[tuple[int, int]], frame: int) -> WaitStats:
        while samples and samples[0][0] <= frame - self.stats_window:
            samples.popleft()
        if not samples:
            return WaitStats(0, 0.0, 0.0, 0.0)
        v = np.fromiter((s[1] for s in samples), dtype=np.float64, count=len(samples))
        return WaitStats(len(v), float(v.mean()), float(np.percentile(v, 95)), float(v.max()))
