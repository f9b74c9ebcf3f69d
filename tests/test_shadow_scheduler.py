"""Shadow scheduler + resolution policy: static latency, dynamic fairness, the
starvation guard, the budget rule, hysteresis, captured transforms, atlas integration."""

from __future__ import annotations

import math

import numpy as np
import pytest

from stb_hydra.limits import (
    SHADOW_MAP_MAX_SIZE,
    SHADOW_MAP_MIN_SIZE,
    SHADOW_OUT_OF_VIEW_PRIORITY_SCALE,
    SHADOW_REFERENCE_FLUX_LM,
    SHADOW_RES_HYSTERESIS_OCTAVES,
)
from stb_hydra.shadows import policy
from stb_hydra.shadows.atlas import ShadowAtlas
from stb_hydra.shadows.scheduler import ShadowScheduler, same_transform

SIDE = 256
MAP = SIDE * SIDE  # texels of one spot map in these tests


def _sched(budget_maps: float, *, reserve: float = 0.25, atlas: int = 4096) -> ShadowScheduler:
    return ShadowScheduler(
        ShadowAtlas(atlas, 32, 1024), budget_texels=int(budget_maps * MAP), static_reserve=reserve
    )


def _add(s: ShadowScheduler, key, dynamic: bool, prio: float = 1.0, frame_t: int = 0) -> None:
    s.add_light(key, dynamic=dynamic, transform=("T", key, frame_t), size=SIDE, priority=prio)


def _run(s: ShadowScheduler, frames: range, served: dict | None = None) -> list[list]:
    plans = []
    for f in frames:
        plan = s.plan_frame(f)
        for u in plan:
            if served is not None:
                served.setdefault(u.key, []).append(f)
        s.commit(plan)
        plans.append(plan)
    return plans


# --- static latency, fairness, starvation guard ----------------------------------------


@pytest.mark.parametrize(("n_static", "m_dynamic", "budget"), [(50, 10, 8), (37, 0, 5), (9, 4, 3)])
def test_statics_served_within_bound_static_first(n_static, m_dynamic, budget) -> None:
    """reserve = 1: the whole budget goes to pending statics -> ceil(N/B) frames."""
    s = _sched(budget, reserve=1.0)
    for i in range(n_static):
        _add(s, ("s", i), dynamic=False)
    for i in range(m_dynamic):
        _add(s, ("d", i), dynamic=True)
    served: dict = {}
    _run(s, range(0, math.ceil(n_static / budget) + 1), served)
    for i in range(n_static):
        first = served[("s", i)][0]
        assert first < math.ceil(n_static / budget) + 1, f"static {i} served at frame {first}"
    assert all(len(served[("s", i)]) == 1 for i in range(n_static)), "a clean static re-served"
    assert s.stats().statics_pending == 0
    assert all(s.is_fresh(("s", i)) for i in range(n_static))


def test_statics_bound_with_default_reserve_under_dynamic_flood() -> None:
    """Default reserve 0.25: statics get >= ceil(0.25 B) maps per frame whatever the
    dynamic demand, and dynamics keep being served meanwhile."""
    n_static, budget = 50, 8
    s = _sched(budget)
    for i in range(40):  # 40 dynamics: 5x the budget
        _add(s, ("d", i), dynamic=True, prio=100.0)  # far more urgent than the statics
    _run(s, range(0, 20))
    for i in range(n_static):
        _add(s, ("s", i), dynamic=False)
    per_frame = math.ceil(0.25 * budget)
    bound = math.ceil(n_static / per_frame) + 1
    served: dict = {}
    plans = _run(s, range(20, 20 + bound), served)
    for i in range(n_static):
        assert served[("s", i)][0] - 20 < bound
    for plan in plans:
        if any(not u.dynamic for u in plan):
            assert not plan[0].dynamic, "guard: the first map of the frame is a static"
        assert sum(1 for u in plan if u.dynamic) >= budget - per_frame - 1 or not any(
            u.dynamic for u in plan
        )
    assert sum(len(v) for k, v in served.items() if k[0] == "d") > 0, "dynamics starved"


def test_starvation_guard_with_zero_reserve() -> None:
    """Budget < one frame of dynamic demand, reserve 0, dynamics far more urgent:
    still exactly >= 1 static per frame while statics pend."""
    s = _sched(4, reserve=0.0)
    for i in range(20):
        _add(s, ("d", i), dynamic=True, prio=1000.0)
    _run(s, range(0, 10))
    for i in range(30):
        _add(s, ("s", i), dynamic=False, prio=0.001)
    f = 10
    while s.stats().statics_pending:
        plan = s.plan_frame(f)
        assert not plan[0].dynamic and sum(not u.dynamic for u in plan) >= 1
        assert sum(u.cost for u in plan[:-1]) < s.budget_texels  # overspend < one map
        s.commit(plan)
        f += 1
        assert f < 10 + 30 + 1, "statics starved"
    assert f == 10 + 30  # exactly one static per frame: the guard, nothing more


def test_budget_overspend_is_less_than_one_map() -> None:
    rng = np.random.default_rng(3)
    s = ShadowScheduler(ShadowAtlas(4096, 32, 1024), budget_texels=1_500_000)
    for i in range(60):
        side = 32 << int(rng.integers(6))
        s.add_light(
            i,
            dynamic=bool(i % 3 == 0),
            transform=0,
            size=side,
            priority=float(rng.random()),
            cost_factor=1.5 if i % 2 else 1.0,
        )
    for f in range(200):
        for i in rng.choice(60, size=5, replace=False):
            if i % 3:
                s.set_transform(int(i), f)
        plan = s.plan_frame(f)
        assert plan, "pending work but an empty frame"
        total = sum(u.cost for u in plan)
        assert total - plan[-1].cost < s.budget_texels
        assert len({u.key for u in plan}) == len(plan), "a map twice in one frame"
        for u in plan:
            assert u.cost == round((1.5 if u.key % 2 else 1.0) * u.rect.size**2)
        s.commit(plan)
        st = s.stats()
        assert (st.maps_planned, st.texels_planned) == (len(plan), total)
        assert (st.maps_updated, st.texels_rendered) == (len(plan), total)


def test_pass_overhead_bounds_many_tiny_maps_per_frame() -> None:
    """Each render pass is charged a fixed overhead: a flood of tiny omni maps can no
    longer all fit one frame's texel budget (the hitch it would cause)."""
    budget, overhead, passes, side = 2 * 1024 * 1024, 4096, 7, 32
    per_map = round(1.5 * side * side) + passes * overhead
    plain = ShadowScheduler(ShadowAtlas(4096, 32, 1024), budget_texels=budget)
    charged = ShadowScheduler(
        ShadowAtlas(4096, 32, 1024), budget_texels=budget, pass_overhead_texels=overhead
    )
    for s in (plain, charged):
        for i in range(800):
            s.add_light(i, dynamic=False, transform=0, size=side, cost_factor=1.5, passes=passes)
    n_plain = len(plain.plan_frame(0))
    plan = charged.plan_frame(0)
    assert n_plain == 800  # 800 x 1536 texels < 2 Mi: all in one frame without the charge
    assert len(plan) == math.ceil(budget / per_map)  # taken while the charge is < budget
    st = charged.stats()
    assert st.texels_planned == sum(u.cost for u in plan) == len(plan) * round(1.5 * side**2)
    with pytest.raises(ValueError):
        ShadowScheduler(ShadowAtlas(4096, 32, 1024), pass_overhead_texels=-1)


def test_zero_budget_still_serves_one_map() -> None:
    s = _sched(0)
    _add(s, "d", dynamic=True)
    _add(s, "s", dynamic=False)
    plan = s.plan_frame(0)
    assert [u.key for u in plan] == ["s"]


def test_dynamic_round_robin_equal_priority() -> None:
    s = _sched(5)
    for i in range(12):
        _add(s, i, dynamic=True)
    served: dict = {}
    _run(s, range(1200), served)
    counts = [len(served[i]) for i in range(12)]
    assert max(counts) - min(counts) <= 1, counts
    assert sum(counts) == 1200 * 5
    age = s.stats().dynamic_age
    assert age.max <= math.ceil(12 / 5) + 1


def test_dynamic_service_proportional_to_priority() -> None:
    s = _sched(3)
    for i in range(12):
        _add(s, i, dynamic=True, prio=2.0 if i < 6 else 1.0)
    served: dict = {}
    _run(s, range(3000), served)
    hi = np.mean([len(served[i]) for i in range(6)])
    lo = np.mean([len(served[i]) for i in range(6, 12)])
    assert 1.6 < hi / lo < 2.4, (hi, lo)
    assert min(len(served[i]) for i in range(6, 12)) > 0.8 * lo  # fair within a class


def test_out_of_view_deprioritised_not_dropped() -> None:
    s = _sched(2)
    for i in range(6):
        _add(s, i, dynamic=True, prio=1.0 if i else SHADOW_OUT_OF_VIEW_PRIORITY_SCALE)
    served: dict = {}
    _run(s, range(600), served)
    assert 0 < len(served[0]) < min(len(served[i]) for i in range(1, 6))


# --- staleness statistics ---------------------------------------------------------------


def test_static_wait_statistics() -> None:
    s = _sched(2, reserve=1.0)
    for i in range(10):
        _add(s, i, dynamic=False)
    _run(s, range(5))
    w = s.stats().static_wait
    assert w.count == 10 and w.max == 4 and w.mean == pytest.approx(2.0)
    assert w.p95 == pytest.approx(np.percentile([0, 0, 1, 1, 2, 2, 3, 3, 4, 4], 95))
    _run(s, range(5, 5 + s.stats_window + 1))
    assert s.stats().static_wait.count == 0  # slid out of the window


# --- captured transform -----------------------------------------------------------------


def test_captured_transform_until_recaptured() -> None:
    s = _sched(1, reserve=0.0)
    t0, t1, t2 = np.eye(4), np.eye(4), np.eye(4)
    t1[3, 0] = 1.0
    t2[3, 0] = 2.0
    s.add_light("lamp", dynamic=False, transform=t0, size=SIDE, priority=1.0)
    assert s.captured_transform("lamp") is None and not s.is_valid("lamp")
    _run(s, range(1))
    assert same_transform(s.captured_transform("lamp"), t0) and s.is_fresh("lamp")
    # moved, but a more urgent static takes the single-map budget this frame
    s.set_transform("lamp", t1)
    s.add_light("hero", dynamic=False, transform=t0, size=SIDE, priority=50.0)
    assert s.is_dirty("lamp") and not s.is_fresh("lamp")
    plan = s.plan_frame(1)
    assert [u.key for u in plan] == ["hero"]
    s.commit(plan)
    assert same_transform(s.captured_transform("lamp"), t0), "evaluate with the old capture"
    assert s.is_valid("lamp")  # still safe to sample, just stale
    # planned with t1, light moves to t2 before the commit: captured = t1, still dirty
    plan = s.plan_frame(2)
    assert [u.key for u in plan] == ["lamp"] and same_transform(plan[0].transform, t1)
    s.set_transform("lamp", t2)
    s.commit(plan)
    assert same_transform(s.captured_transform("lamp"), t1) and s.is_dirty("lamp")
    plan = s.plan_frame(3)
    assert [u.key for u in plan] == ["lamp"]
    s.commit(plan)
    assert same_transform(s.captured_transform("lamp"), t2) and s.is_fresh("lamp")


def test_move_back_to_captured_transform_clears_move() -> None:
    s = _sched(1)
    s.add_light("a", dynamic=False, transform=(0, 0, 0), size=SIDE)
    _run(s, range(1))
    s.set_transform("a", (1, 0, 0))
    assert s.is_dirty("a")
    s.set_transform("a", (0, 0, 0))
    assert not s.is_dirty("a") and s.is_fresh("a") and s.plan_frame(1) == []
    s.mark_dirty("a", "geometry")  # other reasons are not undone by moving back
    s.set_transform("a", (1, 0, 0))
    s.set_transform("a", (0, 0, 0))
    assert s.is_dirty("a")


def test_commit_of_void_capture_is_ignored() -> None:
    s = _sched(4)
    _add(s, "a", dynamic=False)
    plan = s.plan_frame(0)
    s.set_size("a", 512)  # rect changes between plan and commit
    s.commit(plan)
    assert not s.is_valid("a") and s.is_dirty("a") and s.captured_transform("a") is None


# --- atlas integration ------------------------------------------------------------------


def test_resize_remove_and_displacement_mark_dirty() -> None:
    s = ShadowScheduler(ShadowAtlas(1024, 32, 512), budget_texels=10**9)
    for i in range(16):  # fill the atlas with 256s, low priority
        s.add_light(i, dynamic=False, transform=0, size=256, priority=1.0)
    _run(s, range(1))
    assert all(s.is_fresh(i) for i in range(16))
    s.add_light("hero", dynamic=True, transform=0, size=512, priority=9.0)
    assert s.rect("hero").size == 512
    victims = [i for i in range(16) if s.rect(i).size < 256]
    assert victims and all(s.is_dirty(i) and not s.is_valid(i) for i in victims)
    assert all(s.is_fresh(i) for i in range(16) if i not in victims)
    plan = s.plan_frame(1)
    assert {u.key for u in plan} == {*victims, "hero"}
    assert all("downgraded" in u.reason for u in plan if u.key != "hero")
    s.commit(plan)
    assert 0 < s.stats().undersized <= len(victims)  # one may already have grown back
    # the hero goes away: under-sized victims grow back, one per frame
    s.remove_light("hero")
    assert "hero" not in s.atlas and "hero" not in s
    for f in range(2, 2 + len(victims) + 1):
        _run(s, range(f, f + 1))
    assert s.stats().undersized == 0 and all(s.rect(i).size == 256 for i in range(16))
    assert s.stats().statics_pending == 0
    s.atlas.check_invariants()


def test_evicted_light_is_unplaced_then_retried() -> None:
    s = ShadowScheduler(ShadowAtlas(64, 32, 32), budget_texels=10**9)  # 4 cells
    for i in range(4):
        s.add_light(i, dynamic=False, transform=0, size=32, priority=1.0)
    s.add_light("hero", dynamic=False, transform=0, size=32, priority=5.0)
    evicted = [i for i in range(4) if s.rect(i) is None]
    assert len(evicted) == 1 and s.stats().unplaced == 1
    assert all(u.key not in evicted for u in s.plan_frame(0))
    s.remove_light(3 if evicted != [3] else 2)
    s.plan_frame(1)  # retry happens in the frame's maintenance
    assert s.rect(evicted[0]) is not None and s.stats().unplaced == 0


def test_update_lights_applies_policy() -> None:
    s = ShadowScheduler(ShadowAtlas(), budget_texels=10**9)
    keys = list(range(6))
    for k in keys:
        s.add_light(k, dynamic=False, transform=0, size=32, priority=1.0)
    _run(s, range(1))
    dist = np.array([2.0, 10.0, 40.0, 160.0, 640.0, 10.0])
    kw = dict(
        flux_lm=np.full(6, 1000.0),
        range_m=np.full(6, 20.0),
        viewport_height_px=1080,
        fov_y_rad=math.radians(60),
        in_view=np.array([True] * 5 + [False]),
    )
    s.update_lights(keys, distance_m=dist, **kw)
    sizes = [s.rect(k).size for k in keys]
    assert sizes[:5] == sorted(sizes[:5], reverse=True) and sizes[0] == SHADOW_MAP_MAX_SIZE
    assert sizes[5] == 32, "out of view keeps its current size"
    assert s.atlas.priority(5) < s.atlas.priority(1)
    assert all(s.is_dirty(k) for k in range(5) if sizes[k] != 32)
    before = [s.rect(k) for k in keys]
    s.update_lights(keys, distance_m=dist * 1.05, **kw)  # small motion: hysteresis holds
    assert [s.rect(k) for k in keys] == before


# --- policy / hysteresis ----------------------------------------------------------------


def test_hysteresis_holds_within_10_percent_of_boundary() -> None:
    boundary = 256 * math.sqrt(2)  # nearest-pow2 boundary between 256 and 512
    wobble = boundary * (1 + 0.1 * np.sin(np.arange(200) * 0.7))
    for start in (256, 512):
        cur = np.array([start])
        for t in wobble:
            cur = policy.apply_hysteresis(np.array([t]), cur)
            assert cur[0] == start, (start, t)
    # well past the boundary: changes
    assert policy.apply_hysteresis(np.array([boundary * 1.3]), np.array([256]))[0] == 512
    assert policy.apply_hysteresis(np.array([boundary / 1.3]), np.array([512]))[0] == 256
    # the band edge is exactly 0.5 + h octaves
    edge = 256 * 2 ** (0.5 + SHADOW_RES_HYSTERESIS_OCTAVES)
    assert policy.apply_hysteresis(np.array([edge * 0.999]), np.array([256]))[0] == 256
    assert policy.apply_hysteresis(np.array([edge * 1.001]), np.array([256]))[0] == 512


def test_policy_vectorised_and_clamped() -> None:
    n = 10_000
    rng = np.random.default_rng(0)
    dist = rng.uniform(0.1, 500.0, n)
    flux = rng.uniform(10.0, 1e5, n)
    rng_m = rng.uniform(1.0, 50.0, n)
    cur = np.zeros(n, dtype=np.int64)
    sizes = policy.choose_resolutions(dist, flux, rng_m, 1080, math.radians(60), cur)
    assert sizes.shape == (n,) and sizes.dtype == np.int64
    assert sizes.min() >= SHADOW_MAP_MIN_SIZE and sizes.max() <= SHADOW_MAP_MAX_SIZE
    assert np.all((sizes & (sizes - 1)) == 0)
    t = policy.target_texels(dist, flux, rng_m, 1080, math.radians(60))
    # scalar cross-check of a few entries
    for i in range(0, n, 1999):
        d_eff = max(dist[i], rng_m[i])
        px = 1080 * rng_m[i] / (d_eff * math.tan(math.radians(30)))
        scale = min(max(math.sqrt(flux[i] / SHADOW_REFERENCE_FLUX_LM), 0.25), 4.0)
        assert t[i] == pytest.approx(px * 0.5 * scale)
    # farther -> not larger; brighter -> not smaller
    t2 = policy.target_texels(dist * 2, flux, rng_m, 1080, math.radians(60))
    assert np.all(t2 <= t)
    t3 = policy.target_texels(dist, flux * 4, rng_m, 1080, math.radians(60))
    assert np.all(t3 >= t)


def test_policy_out_of_view() -> None:
    t = np.array([1000.0, 1000.0, 1000.0])
    cur = np.array([512, 0, 128])
    in_view = np.array([False, False, True])
    sizes = policy.choose_resolutions(
        np.array([1.0, 1.0, 1.0]), np.full(3, 1e4), np.full(3, 10.0), 1080, 1.0, cur, in_view
    )
    assert sizes.tolist() == [512, SHADOW_MAP_MIN_SIZE, SHADOW_MAP_MAX_SIZE]
    p = policy.light_priorities(t, in_view)
    base = 1.0 + math.log2(1001.0)
    assert p.tolist() == pytest.approx([base * SHADOW_OUT_OF_VIEW_PRIORITY_SCALE] * 2 + [base])
    order = policy.light_priorities(np.array([0.0, 10.0, 1e3, 1e6]))
    assert np.all(np.diff(order) > 0) and order[0] == 1.0  # monotone, >= 1
