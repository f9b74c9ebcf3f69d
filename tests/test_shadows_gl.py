"""Shadow atlas on real GL: edge positions against exact geometry, octahedral
mapping, no leaks across octahedral seams, static/dynamic maps, capture rule."""

from __future__ import annotations

import numpy as np
import pytest
from masks import dilate
from pxr import UsdGeom
from stagegen import USDA_HEADER, camera_usda, ground_usda, plane_points, usda_stage

from stb_hydra.renderer.engine import Engine
from stb_hydra.renderer.frame import RenderSettings
from stb_hydra.renderer.gl import preprocess

W, H = 192, 108

HEADER = USDA_HEADER + camera_usda((0, 7, 5), -55, clipping=(0.1, 100)) + ground_usda(30)


def ground_points(stage) -> np.ndarray:
    return plane_points(stage, W, H)


def segment_hits_box(p: np.ndarray, light: np.ndarray, lo, hi) -> np.ndarray:
    """Does the segment from each point p to the light cross the AABB (slab test)?"""
    d = light - p
    with np.errstate(divide="ignore", invalid="ignore"):
        t0 = (np.asarray(lo) - p) / d
        t1 = (np.asarray(hi) - p) / d
    tmin = np.nanmax(np.minimum(t0, t1), axis=-1)
    tmax = np.nanmin(np.maximum(t0, t1), axis=-1)
    return (tmax >= np.maximum(tmin, 1e-6)) & (tmin <= 1.0)


def sees_box(pts: np.ndarray) -> np.ndarray:
    """Pixels where the camera (0, 7, 5) sees the unit box, not the ground."""
    cam = np.broadcast_to(np.array([0.0, 7.0, 5.0]), pts.shape)
    return segment_hits_box(cam, pts, (0.0, 0.0, -0.5), (1.0, 1.0, 0.5))


def render(stage, frames: int = 1, **settings) -> tuple[np.ndarray, Engine]:
    eng = Engine(stage, RenderSettings(width=W, height=H, **settings))
    for _ in range(frames):
        eng.render_frame()
    return eng.aovs["color"][..., :3], eng


BOX = """def Cube "Box"
{
    double size = 1
    double3 xformOp:translate = (0.5, 0.5, 0)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}
"""


def light(name: str, pos, *, cone: float | None = None, extra: str = "", color=(1, 1, 1)):
    api = (
        '(\n    prepend apiSchemas = ["ShapingAPI", "StbLightAPI"]\n)'
        if cone
        else ('(\n    prepend apiSchemas = ["StbLightAPI"]\n)')
    )
    rot = "    float xformOp:rotateX = -90\n" if cone else ""
    order = '"xformOp:translate", "xformOp:rotateX"' if cone else '"xformOp:translate"'
    c = f"    float inputs:shaping:cone:angle = {cone}\n" if cone else ""
    return (
        f'def SphereLight "{name}" {api}\n{{\n'
        f"    float inputs:intensity = 40000\n    float inputs:radius = 0.05\n"
        f"    color3f inputs:color = ({color[0]}, {color[1]}, {color[2]})\n"
        f"{c}{extra}    double3 xformOp:translate = ({pos[0]}, {pos[1]}, {pos[2]})\n"
        f"{rot}    uniform token[] xformOpOrder = [{order}]\n}}\n"
    )


@pytest.mark.parametrize("cone", [None, 60.0], ids=["omni-octahedral", "spot"])
def test_box_shadow_edge_within_two_pixels(gl_ctx, cone):
    lpos = np.array([-1.0, 2.5, 0.3])
    stage = usda_stage(HEADER + BOX + light("L", lpos, cone=cone))
    lit, e1 = render(stage, shadows=False)
    shad, e2 = render(stage, shadows=True)
    e1.release()
    e2.release()
    pts = ground_points(stage)
    occluded = segment_hits_box(pts, lpos, (0.0, 0.0, -0.5), (1.0, 1.0, 0.5))
    box_px = segment_hits_box(
        np.broadcast_to(np.array([0.0, 7.0, 5.0]), pts.shape),
        pts,
        (0.0, 0.0, -0.5),
        (1.0, 1.0, 0.5),
    )  # pixels where the camera sees the box, not the ground
    valid = (lit[..., 0] > 1e-3) & ~box_px
    dark = shad[..., 0] < 0.5 * lit[..., 0]
    wrong = (dark != occluded) & valid
    band = dilate(occluded, 2) & dilate(~occluded, 2)
    assert occluded[valid].sum() > 50  # the shadow is on screen
    assert not np.any(wrong & ~band), f"{int((wrong & ~band).sum())} pixels beyond 2 px"
    # away from edges the shadowed ground is fully dark and the rest is untouched
    core = occluded & ~dilate(~occluded, 3) & valid
    assert shad[..., 0][core].max() < 0.05 * lit[..., 0][core].min()
    free = ~dilate(occluded, 3) & valid
    np.testing.assert_allclose(shad[free], lit[free], rtol=2e-3, atol=1e-4)


def test_octahedral_round_trip_and_border_wrap(gl_ctx):
    ctx = gl_ctx
    src = preprocess("common/octahedral.glsl")
    cs = ctx.compute_shader(
        src
        + """
layout(local_size_x = 64) in;
layout(std430, binding = 1) readonly buffer In { vec4 dirs[]; };
layout(std430, binding = 2) writeonly buffer Out { vec4 res[]; };
uniform uint n;
void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= n) return;
    vec3 d = normalize(dirs[i].xyz);
    vec2 uv = oct_dir_to_uv(d);
    vec3 back = oct_uv_to_dir(uv);
    // a point just past the right/top edge must map to the neighbour on the sphere
    vec2 e = vec2(1.0 + dirs[i].w, uv.y);
    vec3 wrapped = oct_uv_to_dir(oct_wrap_uv(e));
    vec3 inside = oct_uv_to_dir(vec2(1.0 - dirs[i].w, uv.y));
    res[2u * i] = vec4(back, uv.x);
    res[2u * i + 1u] = vec4(wrapped - inside, uv.y);
}
"""
    )
    rng = np.random.default_rng(3)
    d = rng.normal(size=(4096, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    data = np.c_[d, np.full(len(d), 1e-3)].astype(np.float32)
    bi = ctx.buffer(data.tobytes())
    bo = ctx.buffer(reserve=len(d) * 32)
    bi.bind_to_storage_buffer(1)
    bo.bind_to_storage_buffer(2)
    cs["n"].value = len(d)
    cs.run((len(d) + 63) // 64)
    out = np.frombuffer(bo.read(), dtype=np.float32).reshape(-1, 2, 4)
    back, uv = out[:, 0, :3], np.c_[out[:, 0, 3], out[:, 1, 3]]
    assert np.abs(back - d).max() < 1e-5  # encode/decode round trip
    assert uv.min() >= 0 and uv.max() <= 1
    # across the u = 1 edge the wrapped texel is the sphere neighbour of the inner one
    jump = np.linalg.norm(out[:, 1, :3], axis=1)
    assert np.median(jump) < 1e-2 and np.percentile(jump, 99) < 2e-2


CLOSED_BOX = """def Cube "Shell"
{
    double size = 2
    double3 xformOp:translate = (0, 1.001, 0)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}
"""


def test_omni_light_inside_a_closed_box_does_not_leak(gl_ctx):
    """Light inside a closed box standing on the ground: the ground outside must
    get no light through the octahedral map's seams (exact visibility: none)."""
    lpos = np.array([0.2, 1.0, -0.15])
    text = HEADER + CLOSED_BOX + light("L", lpos)
    stage = usda_stage(text)
    img, eng = render(stage, shadows=True)
    eng.release()
    nos, eng = render(stage, shadows=False)
    eng.release()
    pts = ground_points(stage)
    outside = (np.abs(pts[..., 0]) > 1.0) | (np.abs(pts[..., 2]) > 1.0)
    cam = np.array([0.0, 7.0, 5.0])
    seen = ~segment_hits_box(np.broadcast_to(cam, pts.shape), pts, (-1, 0, -1), (1, 2.002, 1))
    footprint = dilate(~outside | ~seen, 2)
    mask = outside & seen & ~footprint
    assert mask.sum() > 1000
    assert nos[..., 0][mask].max() > 1.0  # without shadows the ground would be lit
    leak = img[..., 0][mask]
    assert leak.max() < 1e-3 * nos[..., 0][mask].max(), leak.max()


def test_dynamic_object_in_dynamic_map_next_frame_never_in_static(gl_ctx):
    # Red light: static shadows; green light: dynamic shadows. The ball is dynamic.
    ball = """def Sphere "Ball" (
    prepend apiSchemas = ["StbGeometryAPI"]
)
{
    double radius = 0.4
    uniform bool stb:dynamic = 1
    double3 xformOp:translate = (-3, 0.6, 0)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}
"""
    red = light("Red", (-1.0, 3.0, 0.0), color=(1, 0, 0))
    green = light(
        "Green",
        (1.0, 3.0, 0.0),
        color=(0, 1, 0),
        extra='    uniform token stb:shadow:update = "dynamic"\n',
    )
    stage = usda_stage(HEADER + ball + red + green)
    eng = Engine(stage, RenderSettings(width=W, height=H))
    try:
        for _ in range(2):
            eng.render_frame()
        UsdGeom.XformCommonAPI(stage.GetPrimAtPath("/Ball")).SetTranslate((0.0, 0.6, 0.0))
        eng.render_frame()
        img = eng.aovs["color"][..., :3]
        pts = ground_points(stage)
        centre = np.array([0.0, 0.6, 0.0])

        def shadow_of(lp):
            # ground points whose segment to the light passes within the ball
            d = lp - pts
            t = np.clip(np.sum((centre - pts) * d, -1) / np.sum(d * d, -1), 0, 1)
            closest = pts + t[..., None] * d
            return np.linalg.norm(closest - centre, axis=-1) < 0.4 * 0.6

        g_sh = shadow_of(np.array([1.0, 3.0, 0.0]))
        r_sh = shadow_of(np.array([-1.0, 3.0, 0.0]))
        cam = np.array([0.0, 7.0, 5.0])
        d = pts - cam
        t = np.clip(np.sum((centre - cam) * d, -1) / np.sum(d * d, -1), 0, 1)
        on_ball = np.linalg.norm(cam + t[..., None] * d - centre, axis=-1) < 0.45
        g_core = g_sh & ~on_ball & ~r_sh
        r_core = r_sh & ~on_ball & ~g_sh
        assert g_core.sum() > 8 and r_core.sum() > 8
        # the dynamic (green) map already holds the ball at its new place
        assert np.mean(img[..., 1][g_core] < 0.05 * img[..., 1][r_core].mean()) > 0.95
        # the static (red) map never holds the dynamic ball
        assert img[..., 0][r_core].min() > 0.5 * img[..., 0][g_core].mean()
    finally:
        eng.release()


def test_shadows_use_the_captured_light_transform(gl_ctx):
    lpos = np.array([-1.0, 2.5, 0.3])
    stage = usda_stage(HEADER + BOX + light("L", lpos))
    eng = Engine(stage, RenderSettings(width=W, height=H))
    try:
        eng.render_frame()
        before = eng.aovs["color"][..., 0].copy()
        pts = ground_points(stage)
        old = segment_hits_box(pts, lpos, (0, 0, -0.5), (1, 1, 0.5)) & ~sees_box(pts)
        atlas = eng.task("shadow_atlas")
        atlas.frozen = True  # no re-capture: the map keeps the old transform
        new_pos = np.array([2.5, 2.5, 0.3])
        UsdGeom.XformCommonAPI(stage.GetPrimAtPath("/L")).SetTranslate(tuple(new_pos))
        eng.render_frame()
        frozen = eng.aovs["color"][..., 0].copy()
        # the shadow is still the one of the captured position, not garbage
        dark = frozen < 0.02 * before.max()
        core_old = old & ~dilate(~old, 3)
        assert dark[core_old].mean() > 0.95
        atlas.frozen = False
        eng.render_frame()
        moved = eng.aovs["color"][..., 0]
        new = segment_hits_box(pts, new_pos, (0, 0, -0.5), (1, 1, 0.5)) & ~sees_box(pts)
        core_new = new & ~dilate(~new, 3) & ~dilate(old, 3)
        assert core_new.sum() > 20
        assert (moved[core_new] < 0.02 * moved.max()).mean() > 0.95
        assert (moved[core_old & ~dilate(new, 3)] > 0.02 * moved.max()).mean() > 0.95
    finally:
        eng.release()


def test_shadow_color_and_distance(gl_ctx):
    lpos = np.array([-1.0, 2.5, 0.3])
    base = HEADER + BOX
    tinted = light("L", lpos, extra="    color3f inputs:shadow:color = (0.5, 0, 0)\n")
    img, eng = render(usda_stage(base + tinted))
    eng.release()
    nos, eng = render(usda_stage(base + light("L", lpos)), shadows=False)
    eng.release()
    pts = ground_points(usda_stage(base))
    occ = segment_hits_box(pts, lpos, (0, 0, -0.5), (1, 1, 0.5)) & ~sees_box(pts)
    core = occ & ~dilate(~occ, 3)
    np.testing.assert_allclose(img[..., 0][core], 0.5 * nos[..., 0][core], rtol=0.02)
    assert img[..., 1][core].max() < 1e-3


POLE = """def Cube "Pole"
{
    double size = 1
    double3 xformOp:translate = (0.6, 1.0, 0)
    float3 xformOp:scale = (0.5, 2, 0.5)
    uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:scale"]
}
"""


def test_shadow_distance(gl_ctx):
    """shadow:distance D: a receiver further than D from its occluder -- the first
    surface the light's ray meets, which is what a depth map records -- is lit.
    A 2 m pole: the receiver-occluder distance grows along its shadow."""
    lpos = np.array([-1.0, 3.5, 0.0])
    lo, hi = np.array([0.35, 0.0, -0.25]), np.array([0.85, 2.0, 0.25])
    D = 2.2
    short = light("L", lpos, extra=f"    float inputs:shadow:distance = {D}\n")
    img, eng = render(usda_stage(HEADER + POLE + short))
    eng.release()
    nos, eng = render(usda_stage(HEADER + POLE + light("L", lpos)), shadows=False)
    eng.release()
    pts = ground_points(usda_stage(HEADER))
    cam = np.broadcast_to(np.array([0.0, 7.0, 5.0]), pts.shape)
    occ = segment_hits_box(pts, lpos, lo, hi) & ~segment_hits_box(cam, pts, lo, hi)
    d = pts - lpos
    with np.errstate(divide="ignore", invalid="ignore"):
        t0 = (lo - lpos) / d
        t1 = (hi - lpos) / d
    t_enter = np.nanmax(np.minimum(t0, t1), axis=-1)
    to_occ = np.linalg.norm(d, axis=-1) * (1.0 - t_enter)
    core = occ & ~dilate(~occ, 1)
    near = core & (to_occ < D - 0.2)
    far = core & (to_occ > D + 0.2)
    assert near.sum() > 5 and far.sum() > 5
    assert img[..., 0][near].max() < 0.05 * nos[..., 0][near].min()
    np.testing.assert_allclose(img[..., 0][far], nos[..., 0][far], rtol=0.02)


def test_atlas_stats_reported(gl_ctx):
    stage = usda_stage(HEADER + BOX + light("A", (-1, 2.5, 0)) + light("B", (2, 2.5, 1)))
    eng = Engine(stage, RenderSettings(width=64, height=36))
    try:
        f = eng.render_frame()
        for k in (
            "shadow_maps_updated",
            "shadow_texels_rendered",
            "shadow_budget_texels",
            "shadow_staleness_p95",
            "shadow_atlas_occupancy",
            "shadow_atlas_fragmentation",
            "shadow_evictions",
            "shadow_downgrades",
        ):
            assert k in f.stats, k
        assert f.stats["shadow_maps_updated"] == 2
        assert 0 < f.stats["shadow_atlas_occupancy"] < 1
        f = eng.render_frame()
        assert f.stats["shadow_maps_updated"] == 0  # static maps, nothing moved
    finally:
        eng.release()


def test_stochastic_pcf_softens_but_agrees_away_from_edges(gl_ctx):
    lpos = np.array([-1.0, 2.5, 0.3])
    stage = usda_stage(HEADER + BOX + light("L", lpos))
    pcf, eng = render(stage)
    eng.release()
    eng = Engine(stage, RenderSettings(width=W, height=H, shadow_filter="stochastic"))
    try:
        eng.render(accumulate=8)
        sto = eng.aovs["color"][..., :3]
    finally:
        eng.release()
    assert np.isfinite(sto).all()
    pts = ground_points(stage)
    occ = segment_hits_box(pts, lpos, (0, 0, -0.5), (1, 1, 0.5)) & ~sees_box(pts)
    far = ~dilate(occ, 3) & ~sees_box(pts)
    core = occ & ~dilate(~occ, 3)
    np.testing.assert_allclose(sto[far], pcf[far], rtol=1e-2, atol=1e-4)
    assert sto[..., 0][core].max() < 0.05 * pcf[..., 0][far].mean()


@pytest.mark.gl
@pytest.mark.slow
def test_offline_render_captures_every_map_before_its_first_frame(gl_ctx):
    """``stb_hydra.render`` (like ``stb render``) ignores the real-time budget: its
    single frame equals a real-time engine's image once all maps are fresh, while
    the real-time engine's first frame still has lights waiting for their maps."""
    import stb_hydra
    from stb_hydra.scenegen.lights import build_lights_stage

    # 150 omni maps: more than one real-time frame of budget (pass overhead included).
    stage = build_lights_stage(n_lights=150, seed=5, shadow_fraction=1.0, size=10.0)
    w, h = 96, 54
    still = stb_hydra.render(stage, width=w, height=h, lighting="reference")
    rt = RenderSettings(width=w, height=h, lighting="reference", shadow_budget=200_000)
    eng = Engine(stage, rt)
    try:
        eng.request_aovs({"color"})
        eng.render_frame()
        first = eng.aovs["color"][..., :3].copy()
        atlas = eng.task("shadow_atlas")
        for _ in range(200):
            if all(atlas.scheduler.is_fresh(k) for k in atlas.registered_keys()):
                break
            eng.render_frame()
        assert all(atlas.scheduler.is_fresh(k) for k in atlas.registered_keys())
        eng.render_frame()
        settled = eng.aovs["color"][..., :3].copy()
    finally:
        eng.release()
    assert np.abs(first - settled).max() > 1e-2  # maps were still missing in frame 1
    np.testing.assert_allclose(still, settled, rtol=1e-4, atol=1e-4)
