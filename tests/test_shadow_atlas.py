"""Shadow-atlas allocator: property test (>= 10,000 random ops), downgrade-before-refuse,
resize semantics, determinism, rect conventions."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

from stb_hydra.limits import (
    SHADOW_ATLAS_SIZE_DEFAULT,
    SHADOW_MAP_BORDER_PX,
    SHADOW_MAP_MAX_SIZE,
    SHADOW_MAP_MIN_SIZE,
)
from stb_hydra.shadows.atlas import AllocResult, AtlasRect, ShadowAtlas

# --- property test ----------------------------------------------------------------------

MIN = 32
#: (atlas side, max map, keys): a roomy one (downgrades, reductions) and a tiny one
#: with more keys than min-size cells (evictions, refusals).
CONFIGS = [(1024, 512, 48), (256, 128, 80)]
OPS_PER_EXAMPLE = 250
EXAMPLES = 22  # 2 configs * 22 examples * 250 ops = 11,000 operations

_keys = st.integers(0, max(c[2] for c in CONFIGS) - 1)
_exps = st.integers(0, 4)  # side = 32 << exp, 32..512
_prios = st.integers(0, 4)  # small range: plenty of ties
_floor = st.one_of(st.none(), _exps)
_op = st.one_of(
    st.tuples(st.just("alloc"), _keys, _exps, _prios, st.booleans(), _floor),
    st.tuples(st.just("alloc"), _keys, _exps, _prios, st.just(True), st.none()),
    st.tuples(st.just("resize"), _keys, _exps, _prios, st.booleans(), _floor),
    st.tuples(st.just("free"), _keys),
    st.tuples(st.just("prio"), _keys, _prios),
)


def _check_result(
    atlas: ShadowAtlas,
    res: AllocResult,
    before: dict,
    prios_before: dict,
    priority: float,
    displace: bool,
    floor: int,
) -> None:
    """Everything an allocate/resize result promises, against the state before the call."""
    after = atlas.rects()
    key = res.key
    assert res.rect == after.get(key)
    if not res.ok:
        assert after == before, "a refused request changed the atlas"
        assert not res.displaced and not res.evicted and not res.changed
        return
    assert res.rect is not None
    assert floor <= res.rect.size <= res.requested
    assert res.changed == (before.get(key) != res.rect)
    if not displace:
        assert not res.displaced and not res.evicted
    touched = set(res.displaced) | set(res.evicted) | {key}
    for k in res.displaced:
        assert prios_before[k] < priority, "displaced a map of >= priority"
        assert after[k].size < before[k].size, "a displaced map was not downgraded"
    for k in res.evicted:
        assert prios_before[k] < priority, "evicted a map of >= priority"
        assert k not in after
    for k, r in before.items():
        if k not in touched:
            assert after[k] == r, f"untouched map {k} moved"
    if displace and res.rect.size < res.requested:
        # downgrade-before-reduce: every lower-priority map left is at the min size
        for k, r in after.items():
            if k != key and atlas.priority(k) < priority:
                assert r.size == atlas.min_map, f"request reduced while {k} is {r.size}"


def _run_op(atlas: ShadowAtlas, op: tuple, n_keys: int) -> None:
    kind, key = op[0], op[1] % n_keys
    before = atlas.rects()
    prios_before = {k: atlas.priority(k) for k in before}
    if kind == "free":
        if key in atlas:
            atlas.free(key)
        else:
            with pytest.raises(KeyError):
                atlas.free(key)
        return
    if kind == "prio":
        if key in atlas:
            atlas.set_priority(key, float(op[2]))
        return
    _, _, exp, prio, displace, fexp = op
    size = atlas.clamp_size(MIN << exp)
    floor = None if fexp is None else min(MIN << fexp, size)
    if kind == "resize" and key not in atlas:
        with pytest.raises(KeyError):
            atlas.resize(key, size, float(prio))
        return
    old = before.get(key)
    res = (atlas.allocate if kind == "alloc" else atlas.resize)(
        key, size, float(prio), displace=displace, floor=floor
    )
    if old is None:
        eff_floor = MIN if floor is None else floor
        if displace and floor is None and not res.ok:  # refused only when nothing is lower
            assert all(p >= prio for p in prios_before.values())
    elif size < old.size:
        eff_floor = size if floor is None else floor
        if floor is None:
            assert res.ok and res.rect.size == size, "a shrink must always succeed exactly"
    elif size > old.size:
        eff_floor = 2 * old.size if floor is None else floor
    else:
        eff_floor = size
        assert res.ok and res.rect == old
    _check_result(atlas, res, before, prios_before, float(prio), displace, min(eff_floor, size))


@settings(
    max_examples=EXAMPLES,
    deadline=None,
    derandomize=True,
    # no shrink phase: lists are >= 250 ops by construction, and shrinking them runs into
    # Hypothesis' 5-minute shrink limit on every failure; the first failing op list and
    # the assertion message are what a debugger needs
    phases=[Phase.explicit, Phase.reuse, Phase.generate],
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
@given(ops=st.lists(_op, min_size=OPS_PER_EXAMPLE, max_size=OPS_PER_EXAMPLE))
@pytest.mark.parametrize(("atlas_size", "max_map", "n_keys"), CONFIGS)
def test_random_ops_keep_invariants(
    atlas_size: int, max_map: int, n_keys: int, ops: list[tuple]
) -> None:
    atlas = ShadowAtlas(atlas_size, MIN, max_map)
    for op in ops:
        _run_op(atlas, op, n_keys)
        atlas.check_invariants()
    for key in atlas.keys():
        atlas.free(key)
    atlas.check_invariants()
    assert atlas.free_blocks() == [AtlasRect(0, 0, atlas_size)], "free-all did not coalesce"
    assert atlas.stats().occupancy == 0.0


@pytest.mark.parametrize(
    ("atlas_size", "max_map", "n_keys"),
    [(SHADOW_ATLAS_SIZE_DEFAULT, SHADOW_MAP_MAX_SIZE, 300), (512, 256, 400)],
)
def test_seeded_stress(atlas_size: int, max_map: int, n_keys: int) -> None:
    """6,000 random ops; the default atlas (downgrades) and a tiny one (evictions)."""
    rng = np.random.default_rng(1234)
    atlas = ShadowAtlas(atlas_size, SHADOW_MAP_MIN_SIZE, max_map)
    for i in range(6_000):
        key = int(rng.integers(n_keys))
        r = rng.random()
        if r < 0.2:
            if key in atlas:
                atlas.free(key)
            continue
        size = atlas.clamp_size(SHADOW_MAP_MIN_SIZE << int(rng.integers(6)))
        prio = float(rng.integers(8))
        before = atlas.rects()
        prios = {k: atlas.priority(k) for k in before}
        res = atlas.allocate(key, size, prio, displace=bool(r < 0.9))
        floor = SHADOW_MAP_MIN_SIZE
        if key in before:
            old = before[key].size
            floor = size if size < old else (2 * old if size > old else size)
        _check_result(atlas, res, before, prios, prio, bool(r < 0.9), min(floor, size))
        if i % 100 == 0:
            atlas.check_invariants()
    atlas.check_invariants()
    stats = atlas.stats()
    assert stats.downgrades > 0 and stats.failed_allocations > 0  # the test bites
    assert stats.evictions > 0 or atlas_size == SHADOW_ATLAS_SIZE_DEFAULT
    atlas.clear()
    assert atlas.free_blocks() == [AtlasRect(0, 0, atlas_size)]


# --- downgrade before refuse ------------------------------------------------------------


def _fill_low(atlas: ShadowAtlas, size: int, prio: float = 1.0) -> list:
    keys = []
    n = (atlas.size // size) ** 2
    for i in range(n):
        res = atlas.allocate(("low", i), size, prio)
        assert res.ok and res.rect.size == size and not res.displaced
        keys.append(("low", i))
    assert atlas.stats().occupancy == 1.0
    return keys


def test_full_atlas_high_priority_downgrades_victims() -> None:
    atlas = ShadowAtlas(4096, 32, 1024)
    low = _fill_low(atlas, 256)
    res = atlas.allocate("hero", 1024, 10.0)
    assert res.ok and res.rect.size == 1024 and not res.evicted
    assert res.displaced and set(res.displaced) <= set(low)
    for k in res.displaced:
        assert atlas.rect(k).size == 128, "victims are halved once, not dropped"
    untouched = set(low) - set(res.displaced)
    assert all(atlas.rect(k).size == 256 for k in untouched)
    assert atlas.stats().downgrades == len(res.displaced)
    atlas.check_invariants()


def test_nothing_refused_until_victims_at_min() -> None:
    atlas = ShadowAtlas(2048, 32, 1024)
    low = _fill_low(atlas, 128)
    reduced_seen = evicted_seen = False
    i = 0
    while True:
        res = atlas.allocate(("hero", i), 1024, 10.0)
        lows = [atlas.rect(k) for k in low if k in atlas]
        if not res.ok:
            assert not lows, "refused while a lower-priority map still exists"
            break
        if res.reduced:
            reduced_seen = True
            assert all(r.size == 32 for r in lows), "request reduced before victims at min"
        if res.evicted:
            evicted_seen = True
            assert res.rect.size == 32 and all(r.size == 32 for r in lows)
        for j in range(i):  # equal priority: heroes never displace each other
            assert ("hero", j) not in res.displaced and ("hero", j) not in res.evicted
        atlas.check_invariants()
        i += 1
    assert reduced_seen and evicted_seen
    st_ = atlas.stats()
    assert st_.failed_allocations == 1 and st_.evictions == len(low)


def test_victims_are_lowest_priority_first() -> None:
    atlas = ShadowAtlas(1024, 32, 256)
    for i in range(16):  # 16 maps of 256 fill it; priority = i
        assert atlas.allocate(i, 256, float(i)).ok
    res = atlas.allocate("hero", 256, 100.0)
    assert res.ok and res.rect.size == 256
    assert sorted(res.displaced) == list(range(len(res.displaced)))  # 0, 1, ... in order
    assert max(res.displaced) < min(k for k in range(16) if k not in res.displaced)


def test_equal_priority_never_displaced() -> None:
    atlas = ShadowAtlas(1024, 32, 512)
    for i in range(4):
        assert atlas.allocate(i, 512, 5.0).ok
    res = atlas.allocate("x", 512, 5.0)
    assert not res.ok and res.rect is None
    assert atlas.stats().failed_allocations == 1 and atlas.stats().downgrades == 0
    assert all(atlas.rect(i).size == 512 for i in range(4))


def test_displace_false_uses_free_space_only() -> None:
    atlas = ShadowAtlas(1024, 32, 512)
    for i in range(3):
        assert atlas.allocate(i, 512, 1.0).ok
    res = atlas.allocate("x", 512, 9.0, displace=False)
    assert res.ok and res.rect.size == 512  # the last free quadrant
    res = atlas.allocate("y", 256, 9.0, displace=False)
    assert not res.ok and not res.displaced


# --- resize semantics -------------------------------------------------------------------


def test_resize_shrink_then_grow() -> None:
    atlas = ShadowAtlas(1024, 32, 512)
    assert atlas.allocate("a", 512, 1.0).ok
    res = atlas.resize("a", 128)
    assert res.ok and res.changed and res.rect.size == 128
    res = atlas.resize("a", 512)
    assert res.ok and res.rect.size == 512
    res = atlas.resize("a", 512, 3.0)  # same size: priority only
    assert res.ok and not res.changed and atlas.priority("a") == 3.0
    atlas.check_invariants()


def _quadrant_scene(low_prio: float, extra_quadrant_lows: bool) -> ShadowAtlas:
    """Hero 256 + three 256 lows in quadrant (0, 0); pinned 512s elsewhere."""
    atlas = ShadowAtlas(1024, 32, 512)
    assert atlas.allocate("hero", 256, 5.0).rect == AtlasRect(0, 0, 256)
    for i in range(3):
        assert atlas.allocate(("low", i), 256, low_prio).ok
    pins = ((512, 0), (0, 512)) if extra_quadrant_lows else ((512, 0), (0, 512), (512, 512))
    for q, (x, y) in enumerate(pins):
        assert atlas.allocate(("pin", q), 512, 5.0).rect == AtlasRect(x, y, 512)
    if extra_quadrant_lows:
        for i in range(3, 7):
            assert atlas.allocate(("low", i), 256, low_prio).rect.x >= 512
    assert atlas.stats().occupancy == 1.0
    return atlas


def test_grow_impossible_is_rolled_back() -> None:
    # lows lower than the hero but sharing its only candidate quadrant: halving them all
    # cannot free 512x512 -> the grow fails and every victim is restored
    atlas = _quadrant_scene(low_prio=1.0, extra_quadrant_lows=False)
    before, stats = atlas.rects(), atlas.stats()
    res = atlas.resize("hero", 512)
    assert not res.ok and not res.changed and not res.displaced
    assert atlas.rects() == before
    assert atlas.stats().downgrades == stats.downgrades
    assert atlas.stats().failed_allocations == stats.failed_allocations + 1
    atlas.check_invariants()


def test_grow_with_displacement() -> None:
    atlas = _quadrant_scene(low_prio=1.0, extra_quadrant_lows=True)
    res = atlas.resize("hero", 512)
    assert res.ok and res.changed and res.rect.size == 512 and not res.evicted
    assert all(k[0] == "low" for k in res.displaced)
    assert all(atlas.rect(("pin", q)).size == 512 for q in range(2))
    atlas.check_invariants()
    # same scene with equal priorities: nothing may be displaced -> refused, unchanged
    atlas = _quadrant_scene(low_prio=5.0, extra_quadrant_lows=True)
    before = atlas.rects()
    res = atlas.resize("hero", 512)
    assert not res.ok and atlas.rects() == before


# --- determinism, conventions, validation -----------------------------------------------


def test_deterministic() -> None:
    def run() -> dict:
        rng = np.random.default_rng(7)
        atlas = ShadowAtlas(2048, 32, 512)
        for _ in range(2000):
            k = int(rng.integers(80))
            if rng.random() < 0.25 and k in atlas:
                atlas.free(k)
            else:
                atlas.allocate(k, 32 << int(rng.integers(5)), float(rng.integers(4)))
        return atlas.rects()

    assert run() == run()


def test_rect_conventions() -> None:
    r = AtlasRect(256, 512, 128)
    b = SHADOW_MAP_BORDER_PX
    assert r.interior() == (256 + b, 512 + b, 128 - 2 * b)
    scale, ou, ov = r.uv_scale_offset(4096)
    assert scale == pytest.approx((128 - 2 * b) / 4096)
    assert (ou, ov) == pytest.approx(((256 + b) / 4096, (512 + b) / 4096))
    # map UV (1, 1) lands on the interior's far edge, inside the block
    assert ou + scale == pytest.approx((256 + 128 - b) / 4096)
    atlas = ShadowAtlas()
    first = atlas.allocate("a", 64, 1.0).rect
    assert first == AtlasRect(0, 0, 64)  # texel origin of the texture
    assert atlas.allocate("b", 64, 1.0).rect == AtlasRect(64, 0, 64)  # Morton order
    assert atlas.allocate("c", 64, 1.0).rect == AtlasRect(0, 64, 64)


def test_validation_and_clamping() -> None:
    with pytest.raises(ValueError):
        ShadowAtlas(3000)
    with pytest.raises(ValueError):
        ShadowAtlas(1024, 4, 512)  # min map must exceed 2 * border
    atlas = ShadowAtlas()
    with pytest.raises(ValueError):
        atlas.allocate("a", 100, 1.0)
    with pytest.raises(ValueError):
        atlas.allocate("a", 64, float("nan"))
    assert atlas.allocate("big", 8192, 1.0).rect.size == SHADOW_MAP_MAX_SIZE
    assert atlas.allocate("tiny", 2, 1.0).rect.size == SHADOW_MAP_MIN_SIZE


def test_stats_fragmentation() -> None:
    atlas = ShadowAtlas(1024, 32, 512)
    s = atlas.stats()
    assert (s.occupancy, s.largest_free_fraction, s.fragmentation) == (0.0, 1.0, 0.0)
    for i in range(4):
        atlas.allocate(i, 256, 1.0)  # fills quadrant (0, 0)
    atlas.free(0)
    atlas.free(3)
    s = atlas.stats()
    free = 3 * 512 * 512 + 2 * 256 * 256
    assert s.free_texels == free and s.largest_free_block == 512
    assert s.largest_free_fraction == pytest.approx(512 * 512 / free)
    assert s.fragmentation == pytest.approx(1 - 512 * 512 / free)
    assert s.occupancy == pytest.approx(2 * 256 * 256 / 1024**2)


def test_a_released_atlas_is_reused_cleared_and_the_pool_is_bounded(gl_ctx):
    """An engine's released atlas texture goes to the next capturer of the context
    (no new 32 MiB allocation and first touch), cleared to "unoccluded" whatever the
    last engine left in it; the pool never holds more than SHADOW_ATLAS_POOL_BYTES."""
    from stb_hydra import limits
    from stb_hydra.renderer import shadow_capture as sc

    sc.release_atlas_pool()
    a = sc.ShadowCapturer(gl_ctx, 256)
    a.atlas_fbo.clear(0.25, 0.25, 0.25, 0.25)  # a previous engine's maps
    glo = a.atlas.glo
    a.release()
    b = sc.ShadowCapturer(gl_ctx, 256)
    try:
        assert b.atlas.glo == glo
        assert (np.frombuffer(b.atlas.read(), np.uint16) == 65535).all()
    finally:
        b.release()
    side = limits.SHADOW_ATLAS_SIZE_DEFAULT
    caps = [sc.ShadowCapturer(gl_ctx, side) for _ in range(4)]
    for c in caps:
        c.release()
    held = sum(k[1] * k[1] * 2 * len(v) for k, v in sc._atlas_pool.items())
    assert 0 < held <= limits.SHADOW_ATLAS_POOL_BYTES
    sc.release_atlas_pool()
    assert not sc._atlas_pool
