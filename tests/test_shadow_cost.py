"""Shadow captures priced in time (issue 16): the cost model, the millisecond budget
in deterministic mode, per-face culling (closed forms) and the one-submission omni
capture against the per-face reference path."""

from __future__ import annotations

import numpy as np
import pytest
from stagegen import USDA_HEADER, camera_usda, ground_usda, usda_stage

from stb_hydra.renderer.engine import Engine
from stb_hydra.renderer.frame import RenderSettings
from stb_hydra.shadows.atlas import ShadowAtlas
from stb_hydra.shadows.capture import (
    capture_for,
    omni_face_view_projs,
    omni_face_view_projs_many,
    spot_view_proj,
)
from stb_hydra.shadows.cost import ShadowCostModel
from stb_hydra.shadows.culling import (
    boxes_in_sphere,
    frustum_planes,
    triangles_submitted,
    visible_faces,
)
from stb_hydra.shadows.scheduler import ShadowScheduler

# --- cost model (no GL) -----------------------------------------------------------------


def test_fixed_model_is_the_closed_form_and_never_moves():
    m = ShadowCostModel((10.0, 0.5, 40.0), fixed=True)
    # 2 Mtexel * 10 + 7 passes * 0.5 + 0.25 Mtri * 40
    assert m.predict(2_000_000, 7, 250_000) == pytest.approx(20.0 + 3.5 + 10.0)
    m.observe(2_000_000, 7, 250_000, 999.0)
    assert m.predict(2_000_000, 7, 250_000) == pytest.approx(33.5)


def test_refit_recovers_independent_coefficients():
    """Samples made from known coefficients (not the prior) pull the fit to them."""
    true = np.array([25.0, 0.3, 60.0])
    m = ShadowCostModel((6.0, 0.07, 15.0))
    rng = np.random.default_rng(1)
    for _ in range(64):
        tex, passes, tris = rng.uniform(0, 3e6), rng.integers(2, 300), rng.uniform(0, 5e6)
        ms = tex * 1e-6 * true[0] + passes * true[1] + tris * 1e-6 * true[2]
        m.observe(tex, int(passes), tris, ms)
    # held-out workloads: the re-fitted model predicts them, the prior did not
    prior = ShadowCostModel((6.0, 0.07, 15.0), fixed=True)
    for _ in range(20):
        tex, passes, tris = rng.uniform(0, 3e6), rng.integers(2, 300), rng.uniform(0, 5e6)
        ms = tex * 1e-6 * true[0] + passes * true[1] + tris * 1e-6 * true[2]
        assert m.predict(tex, int(passes), tris) == pytest.approx(ms, rel=0.05)
        assert prior.predict(tex, int(passes), tris) < 0.3 * ms
    np.testing.assert_allclose(m.coeffs, true, rtol=0.25)


@pytest.mark.parametrize("bad", [(1.0, 2.0), (1.0, -1.0, 0.0), (np.nan, 1.0, 1.0)])
def test_bad_coefficients_are_refused(bad):
    with pytest.raises(ValueError, match="coefficients"):
        ShadowCostModel(bad)


# --- scheduler with a millisecond budget (no GL, deterministic) -------------------------

SIDE = 256
COEFFS = (10.0, 1.0, 100.0)  # ms per Mtexel, per pass, per Mtriangle


def _ms(side: int, passes: int, tris: float) -> float:
    return side * side * 1e-6 * COEFFS[0] + passes * COEFFS[1] + tris * 1e-6 * COEFFS[2]


def _sched(budget_ms: float, budget_texels: int = 10**12) -> ShadowScheduler:
    return ShadowScheduler(
        ShadowAtlas(4096, 32, 1024),
        budget_texels=budget_texels,
        budget_ms=budget_ms,
        cost_model=ShadowCostModel(COEFFS, fixed=True),
    )


def test_ms_budget_plans_what_fits_in_priority_order():
    s = _sched(budget_ms=10.0)
    tris = [0.0, 20_000.0, 50_000.0]  # 2.66, 4.66, 7.66 ms per spot map (2 passes)
    for i in range(12):
        s.add_light(("L", i), dynamic=True, transform=i, size=SIDE, priority=1.0, passes=2)
        s.set_work(("L", i), tris[i % 3])
    cost = {("L", i): _ms(SIDE, 2, tris[i % 3]) for i in range(12)}
    served = dict.fromkeys(cost, 0)
    for f in range(30):
        plan = s.plan_frame(f)
        total = sum(cost[u.key] for u in plan)
        assert sum(u.cost_ms for u in plan) == pytest.approx(total)
        assert total <= 10.0 or len(plan) == 1  # never past the budget but the first map
        assert total > 10.0 - max(cost.values())  # and not stopped early
        assert s.stats().ms_planned == pytest.approx(total)
        for u in plan:
            served[u.key] += 1
        s.commit(plan)
    assert max(served.values()) - min(served.values()) <= 1  # round robin kept


def test_first_map_always_taken_and_statics_never_starve():
    s = _sched(budget_ms=1.0)  # below one map's cost
    s.add_light("heavy", dynamic=False, transform=0, size=SIDE, priority=0.1, passes=2)
    s.set_work("heavy", 1_000_000)  # 102.6 ms
    for i in range(4):
        s.add_light(("dyn", i), dynamic=True, transform=0, size=SIDE, priority=100.0)
    plan = s.plan_frame(0)
    assert [u.key for u in plan] == ["heavy"]  # the starvation guard: most urgent static
    assert plan[0].cost_ms == pytest.approx(_ms(SIDE, 2, 1_000_000))
    s.commit(plan)
    for f in range(1, 5):  # then one dynamic map per frame (each alone exceeds 1 ms)
        plan = s.plan_frame(f)
        assert len(plan) == 1 and plan[0].dynamic
        s.commit(plan)


def test_texel_and_ms_budgets_combine_whichever_is_reached_first():
    per_map = _ms(SIDE, 2, 0.0)  # 2.655 ms, 65536 texels
    for budget_ms, budget_texels, expect in (
        (100.0, 3 * SIDE * SIDE, 3),  # texels close the frame (rule: spent < budget)
        (2.5 * per_map, 10**12, 2),  # milliseconds close it (rule: after <= budget)
    ):
        s = _sched(budget_ms, budget_texels)
        for i in range(10):
            s.add_light(i, dynamic=True, transform=0, size=SIDE, passes=2)
        assert len(s.plan_frame(0)) == expect


# --- culling (no GL, closed forms) ------------------------------------------------------


def test_face_culling_closed_form():
    c = capture_for((0, 0, 0), (0, -1, 0), 10.0, 0.01, np.pi, 0)
    planes = frustum_planes(omni_face_view_projs(c))
    # face order +X -X +Y -Y +Z -Z; boxes: on +X, on -Y, straddling the +X/+Z edge,
    # around the light (every face), beyond the range along +X
    lo = np.array([[2, -0.5, -0.5], [-0.5, -3, -0.5], [2, -0.1, 1.9], [-0.2] * 3, [20, 0, 0]])
    hi = np.array([[3, 0.5, 0.5], [0.5, -2, 0.5], [3, 0.1, 3.1], [0.2] * 3, [21, 1, 1]])
    vis = visible_faces(planes, lo, hi)
    np.testing.assert_array_equal(vis[:, 0], [1, 0, 0, 0, 0, 0])
    np.testing.assert_array_equal(vis[:, 1], [0, 0, 0, 1, 0, 0])
    np.testing.assert_array_equal(vis[:, 2], [1, 0, 0, 0, 1, 0])
    assert vis[:, 3].all()
    assert not vis[:, 4].any()  # past the far plane (= range)
    np.testing.assert_array_equal(
        boxes_in_sphere(np.zeros(3), 10.0, lo, hi), [True, True, True, True, False]
    )


def test_vectorised_face_matrices_and_triangle_counts():
    rng = np.random.default_rng(3)
    pos = rng.uniform(-5, 5, (7, 3))
    caps = [capture_for(p, (0, -1, 0), 4.0, 0.05, np.pi, 0) for p in pos]
    many = omni_face_view_projs_many(
        pos, np.array([c.near for c in caps]), np.array([c.range for c in caps])
    )
    for c, m in zip(caps, many):
        np.testing.assert_allclose(m, omni_face_view_projs(c), atol=1e-12)
    lo = rng.uniform(-6, 5, (9, 3))
    hi = lo + rng.uniform(0.1, 2, (9, 3))
    tris = rng.integers(1, 1000, 9).astype(float)
    got = triangles_submitted(many, np.ones((7, 6), bool), pos, np.full(7, 4.0), lo, hi, tris)
    for i, c in enumerate(caps):  # one light at a time, face by face
        vis = visible_faces(frustum_planes(omni_face_view_projs(c)), lo, hi)
        vis &= boxes_in_sphere(pos[i], 4.0, lo, hi)
        assert got[i] == (vis * tris).sum()
    spot = capture_for((0, 2, 0), (0, -1, 0), 5.0, 0.05, np.radians(30), 0)
    planes = frustum_planes(spot_view_proj(spot)[None])
    box = visible_faces(
        planes,
        np.array([[-0.1, -0.1, -0.1], [3, -0.1, 0]]),
        np.array([[0.1, 0.1, 0.1], [3.2, 0.1, 0.2]]),
    )
    np.testing.assert_array_equal(box[0], [True, False])  # below the spot; outside its cone


# --- real GL ----------------------------------------------------------------------------

W, H = 96, 54
HEADER = USDA_HEADER + camera_usda((0, 7, 5), -55, clipping=(0.1, 100)) + ground_usda(30)


def _cube(name: str, pos, size: float = 0.6) -> str:
    return (
        f'def Cube "{name}"\n{{\n    double size = {size}\n'
        f"    double3 xformOp:translate = ({pos[0]}, {pos[1]}, {pos[2]})\n"
        '    uniform token[] xformOpOrder = ["xformOp:translate"]\n}\n'
    )


def _light(name: str, pos, cone: float | None = None) -> str:
    shaping = ""
    api = '["StbLightAPI"]'
    rot = ""
    order = '"xformOp:translate"'
    if cone:
        api = '["ShapingAPI", "StbLightAPI"]'
        shaping = f"    float inputs:shaping:cone:angle = {cone}\n"
        rot = "    float xformOp:rotateX = -90\n"
        order = '"xformOp:translate", "xformOp:rotateX"'
    return (
        f'def SphereLight "{name}" (\n    prepend apiSchemas = {api}\n)\n{{\n'
        "    float inputs:intensity = 40000\n    float inputs:radius = 0.05\n"
        f"{shaping}    double3 xformOp:translate = ({pos[0]}, {pos[1]}, {pos[2]})\n"
        f"{rot}    uniform token[] xformOpOrder = [{order}]\n}}\n"
    )


def _scene(n_lights: int = 6):
    """Casters all around: a ring of cubes around each of a row of lights, some spots."""
    rng = np.random.default_rng(7)
    text = HEADER
    for i in range(12):
        a = 2 * np.pi * i / 12
        text += _cube(f"C{i}", (2.0 * np.cos(a), 0.3 + 0.4 * (i % 3), 2.0 * np.sin(a)))
    text += _cube("Above", (0.2, 3.2, -0.1), 0.8)
    for i in range(n_lights):
        p = rng.uniform(-1.2, 1.2, 3) * (1, 0, 1) + (0, 1.0 + 0.3 * i, 0)
        text += _light(f"L{i}", p, cone=60.0 if i % 3 == 2 else None)
    return usda_stage(text)


def _atlas_after(stage, **settings) -> tuple[np.ndarray, Engine]:
    eng = Engine(stage, RenderSettings(width=W, height=H, lighting="reference", **settings))
    eng.render_frame()
    task = eng.task("shadow_atlas")
    assert task.capturer is not None
    atlas = np.frombuffer(task.capturer.atlas.read(), dtype=np.uint16)
    return atlas.reshape(task.capturer.size, task.capturer.size).copy(), eng


@pytest.mark.gl
def test_one_pass_capture_matches_the_per_face_path(gl_ctx):
    stage = _scene()
    ref, e1 = _atlas_after(stage, shadow_capture_mode="per_face")
    one, e2 = _atlas_after(stage, shadow_capture_mode="one_pass")
    try:
        keys = e1.task("shadow_atlas").registered_keys()
        assert len(keys) == 6
        for k in keys:  # same rects
            assert e1.task("shadow_atlas").scheduler.rect(k) == e2.task(
                "shadow_atlas"
            ).scheduler.rect(k)
    finally:
        e1.release()
        e2.release()
    written = ref != 65535
    assert written.sum() > 1000  # the maps hold casters
    diff = np.abs(ref.astype(np.int64) - one.astype(np.int64))
    # Same depths (the face transform is done in the shader instead of the viewport:
    # float rounding may move a sample by 1 LSB); a texel that changes coverage at a
    # triangle edge may differ more: a handful at most.
    assert (diff > 1).sum() <= max(4, written.sum() // 2000), int((diff > 1).sum())
    assert np.median(diff[written]) == 0


@pytest.mark.gl
def test_culling_keeps_every_caster_in_range(gl_ctx):
    """Culled capture == range-only capture (the reference), and a caster on each
    side of an omni light shows up in the face looking at it (closed form)."""
    stage = _scene()
    ref, e1 = _atlas_after(stage)
    e1.task("shadow_atlas").capturer.cull = False  # re-capture without face culling
    for k in e1.task("shadow_atlas").registered_keys():
        e1.task("shadow_atlas").scheduler.mark_dirty(k, "geometry")
    e1.render_frame()
    cap = e1.task("shadow_atlas").capturer
    unculled = np.frombuffer(cap.atlas.read(), dtype=np.uint16).reshape(cap.size, cap.size)
    try:
        assert (ref != 65535).sum() > 1000
        np.testing.assert_array_equal(ref, unculled)
        # closed form: light at the origin-ish, cubes at +-2 m on x and z
        c = capture_for((0, 0.7, 0), (0, -1, 0), 50.0, 0.05, np.pi, 0)
        vis = cap.visible(e1.delegate, c, dynamic=False)
        arr = e1.delegate.batch_arrays()
        assert vis.shape == (6, len(arr.batches))
        cen = 0.5 * (arr.lo + arr.hi)
        for b in range(len(arr.batches)):
            if arr.hi[b][0] - arr.lo[b][0] > 5:  # the ground: below, seen by -Y and sides
                assert vis[3, b]
                continue
            d = cen[b] - np.array(c.position)
            axis = int(np.argmax(np.abs(d)))
            face = 2 * axis + (0 if d[axis] > 0 else 1)
            assert vis[face, b], (b, cen[b], face)
    finally:
        e1.release()


@pytest.mark.gl
def test_deterministic_ms_budget_on_real_captures(gl_ctx):
    """Fixed cost model: each frame's planned milliseconds (from the real culled
    triangle counts) stay within the budget, or the frame took one map; the scheduler's
    per-capture triangles equal what the capturer submitted; priorities unchanged."""
    stage = _scene()
    coeffs = (20.0, 0.5, 200.0)
    eng = Engine(
        stage,
        RenderSettings(
            width=W, height=H, lighting="reference", shadow_budget_ms=6.0, shadow_cost_coeffs=coeffs
        ),
    )
    try:
        task = eng.task("shadow_atlas")
        assert not task.measure
        frames = 0
        while True:
            f = eng.render_frame()
            frames += 1
            plan = task._plan
            ms = sum(
                u.cost * 1e-6 * coeffs[0] + u.passes * coeffs[1] + u.triangles * 1e-6 * coeffs[2]
                for u in plan
            )
            assert f.stats["shadow_ms_planned"] == pytest.approx(ms)
            assert ms <= 6.0 or len(plan) == 1
            assert f.stats["shadow_triangles"] == pytest.approx(sum(u.triangles for u in plan))
            if f.stats["shadow_stale_maps"] == 0 or frames > 30:
                break
        assert f.stats["shadow_stale_maps"] == 0
        assert frames > 1  # the budget spread the six maps over frames
    finally:
        eng.release()
