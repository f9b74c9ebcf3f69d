"""STB reservoir reuse (issue 31, ``-o reuse=on``) on real GL: unbiasedness against a
closed-form many-light scene, disocclusion, the M cap, determinism, finite output.
Small images, fixed seeds."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import optimised
import pytest
from convergence import convergence, snapshot_counts
from stagegen import (
    LAMBERT_FLOOR_USDA,
    USDA_HEADER,
    camera_usda,
    ground_usda,
    plane_points,
    usda_stage,
)

import stb_hydra
from stb_hydra.renderer.engine import Engine
from stb_hydra.renderer.frame import RenderSettings
from stb_hydra.renderer.lighting.stb_reuse import CURRENT, fov_remap

W, H = 160, 90
RHO = 0.5
#: The ReSTIR-style configuration under test: the small tile's N = 4 samples as each
#: pixel's candidates (``reuse_candidates=0``: 128 px big tiles, per-pixel reservoirs,
#: temporal and spatial reuse), unbiased MIS. STB's default (candidates from the big
#: tile, shared over the 2x2 quad): ``SHARE_TILE`` and the cases that set them.
REUSE = dict(reuse=True, N=4, reuse_mis="balance", reuse_candidates=0)


def floor_lights(n: int, seed: int = 3) -> tuple[str, np.ndarray, np.ndarray]:
    """n point lights (no specular) over LAMBERT_FLOOR_USDA's plane: (light prims, their
    positions (n, 3) m, their intensities (n,) cd)."""
    rng = np.random.default_rng(seed)
    pos = rng.uniform([-5.0, 0.3, -3.0], [5.0, 2.0, 3.0], (n, 3))
    radiance = rng.uniform(500.0, 20000.0, n)
    prims = "".join(
        f'def SphereLight "L{i}"\n{{\n    float inputs:intensity = {radiance[i]:.3f}\n'
        "    float inputs:radius = 0.1\n    float inputs:specular = 0\n"
        "    bool treatAsPoint = 1\n"
        f"    double3 xformOp:translate = ({p[0]:.4f}, {p[1]:.4f}, {p[2]:.4f})\n"
        '    uniform token[] xformOpOrder = ["xformOp:translate"]\n}\n'
        for i, p in enumerate(pos)
    )
    # treatAsPoint: intensity (cd) = radiance x pi r^2 (tests/test_render_closed_form.py).
    return prims, np.round(pos, 4), np.round(radiance, 3) * math.pi * 0.1**2


def closed_form(pts: np.ndarray, pos: np.ndarray, inten: np.ndarray) -> np.ndarray:
    """Lambertian radiance of the plane y = 0 (nits): sum of rho / pi I cos / d^2."""
    out = np.zeros(pts.shape[:2])
    for p, i in zip(pos, inten, strict=True):  # test-side closed form, not the frame path
        d = p - pts
        dist = np.linalg.norm(d, axis=-1)
        out += RHO / math.pi * i * (d[..., 1] / dist) / dist**2
    return out


def many_lights_scene():
    """(stage, closed-form image) of the unbiasedness tests: 150 point lights over the
    Lambertian floor (also ``tools/convergence_spread.py``'s ``reuse`` cases)."""
    prims, pos, inten = floor_lights(150)
    stage = usda_stage(LAMBERT_FLOOR_USDA.format(rho=RHO, light=prims))
    return stage, closed_form(plane_points(stage, W, H), pos, inten)


#: The unbiasedness tests' options under the case's own: reuse with the weight cap off.
UNBIASED = dict(REUSE, weight_cap=None, K=64, big_tile=32)


@pytest.fixture(scope="module")
def many_lights():
    return many_lights_scene()


def test_closed_form_scene_is_what_the_reference_renders(gl_ctx, many_lights):
    """The expected image of the unbiasedness tests: every light's contribution by the
    closed form; the reference method agrees (so a failure below is the reuse's)."""
    stage, exp = many_lights
    ref = stb_hydra.render(stage, width=W, height=H, lighting="reference")
    assert np.abs(ref[..., 0] / exp - 1.0).max() < 0.01


@pytest.mark.parametrize(
    "extra,tol,frames",
    [
        ({}, 3e-3, 64),  # spatial reuse (temporal is off under accumulation: auto)
        # frames correlated by the history: fewer independent ones (its mean spreads 1 % at 64)
        ({"reuse_temporal": "on"}, 6e-3, 256),
        ({"reuse_k": 0}, 3e-3, 64),  # the per-pixel resampling of the N candidates alone
        ({"reuse_mis": "pairwise"}, 3e-3, 64),  # pairwise MIS: also unbiased, 2k + 1 targets
        # Candidates straight from the big tile (a random stratum of 16 of its K = 64
        # reservoirs per pixel, no small-tile pass), with and without spatial reuse.
        ({"reuse_candidates": 16}, 3e-3, 64),
        ({"reuse_candidates": 16, "reuse_k": 0, "reuse_mis": "pairwise"}, 3e-3, 64),
        ({"reuse_candidates": 64, "reuse_k": 0}, 3e-3, 32),  # noise 10x below: 32 frames
        # One reservoir per 2x2 quad (its defensive floor): unbiased at all four pixels.
        ({"reuse_candidates": 16, "reuse_k": 0, "reuse_res": "quad"}, 3e-3, 64),
        # The cheap initial target (point lights here: it differs by no cone / area).
        ({"reuse_candidates": 32, "reuse_k": 0, "reuse_target": "cheap"}, 3e-3, 64),
        # The 2x2 quad shares: 16 candidates per pixel, the quad's four reservoirs
        # combined at each pixel (fine-derivative exchange), with the per-slot target
        # (the shaping once per big-tile slot; the pixel's part from three texels -- the
        # cone per pixel -- and a rational stand-in for the specular pow).
        (
            {"reuse_candidates": 64, "reuse_k": 0, "reuse_res": "share", "reuse_target": "tile"},
            3e-3,
            32,  # C = 64 candidates a pixel: noise 10x below the others
        ),
        ({"reuse_candidates": 16, "reuse_target": "tile"}, 3e-3, 64),  # two passes, k = 4
        # 16 px big tiles (reuse7's still configuration): their slots' 2 x 2 grid
        (
            {
                "reuse_candidates": 64,
                "reuse_k": 0,
                "reuse_res": "share",
                "reuse_target": "tile",
                "big_tile": 16,
            },
            3e-3,
            32,
        ),
        # The default with many lights (big_tile=0 above 2 x 32^2 lights: 32 px tiles
        # drawing from light clusters, a cluster's light by its flux), forced at 150:
        # 10 clusters over the floor are a poor fit (relMSE 2.6e-3 at 32 frames), so
        # 256 frames for the mean's 1 % (seeds 0-2 at 1,024 frames: 0.9996 on average).
        (
            {
                "reuse_candidates": 64,
                "reuse_k": 0,
                "reuse_res": "share",
                "reuse_target": "tile",
                "big_tile": 0,
                "bigtile": "clusters",
            },
            3e-3,
            256,
        ),
    ],
)
@pytest.mark.slow
def test_unbiased_mean_converges_to_closed_form(gl_ctx, many_lights, extra, tol, frames):
    """Weight cap off: the mean of ``frames`` frames converges to the closed form (150
    lights > K, so the big tile's SRS is part of it). ``tol`` is the relMSE budget a
    256-frame mean had; now (tests/convergence.py) the split-half squared bias <= tol / 3
    (the relMSE test allowed ~tol less the noise: 2.5e-3 at 3e-3), the noise within the
    same budget scaled to the frames and falling as 1/M, the image mean within 1 % (its
    spread at the frames chosen: 0.3 % or less; tools/mutation_check.py plants biases)."""
    stage, exp = many_lights
    opts = dict(UNBIASED, **extra)
    imgs = optimised.render_progressive(
        stage, snapshot_counts(frames), width=W, height=H, lighting="stb", **opts
    )
    c = convergence({n: im[..., 0] for n, im in imgs.items()}, exp)
    assert c.finite and np.isfinite(imgs[frames]).all()
    assert c.bias2 <= tol / 3.0, c
    assert c.relmse <= tol * 256 / frames, c
    assert c.relmse < c.relmse_early / 3.0, c  # 8x the frames: error falls roughly as 1/M
    assert abs(c.mean_ratio - 1.0) < 0.01, c


#: The courtyard's narrowest IES profile (a ~20 degree lobe) and a phi-asymmetric one.
IES_PROFILES = [
    str(Path(__file__).resolve().parents[1] / "usd_scenes" / "ies" / f)
    for f in ("downlight_narrow.ies", "streetlamp_typeII.ies")
]


def spot_lights(n: int, seed: int = 5, ies: bool = False) -> str:
    """n narrow spot lights (cones of 12-30 deg, soft edges) pointing straight down at
    LAMBERT_FLOOR_USDA's plane: their cone edges cross the big tiles. ``ies``: IES
    profiles (IES_PROFILES, alternating; the lobes narrower than the big tiles) instead of
    cones, tilted up to 40 degrees about x and z."""
    rng = np.random.default_rng(seed)
    pos = rng.uniform([-5.0, 0.6, -3.0], [5.0, 2.5, 3.0], (n, 3))

    def shaping(i: int) -> str:
        if ies:
            tilt = rng.uniform(-40.0, 40.0, 2)
            return (
                f"    asset inputs:shaping:ies:file = @{IES_PROFILES[i % 2]}@\n"
                "    bool inputs:shaping:ies:normalize = 1\n"
                f"    float3 xformOp:rotateXYZ = ({-90 + tilt[0]:.2f}, 0, {tilt[1]:.2f})\n"
            )
        return (
            f"    float inputs:shaping:cone:angle = {rng.uniform(12.0, 30.0):.2f}\n"
            "    float inputs:shaping:cone:softness = 0.3\n"
            "    float3 xformOp:rotateXYZ = (-90, 0, 0)\n"
        )

    return "".join(
        f'def SphereLight "S{i}" (\n    prepend apiSchemas = ["ShapingAPI"]\n)\n{{\n'
        f"    float inputs:intensity = {rng.uniform(2000.0, 40000.0):.1f}\n"
        "    float inputs:radius = 0.05\n    float inputs:specular = 0\n"
        "    bool treatAsPoint = 1\n"
        + shaping(i)
        + f"    double3 xformOp:translate = ({p[0]:.4f}, {p[1]:.4f}, {p[2]:.4f})\n"
        '    uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateXYZ"]\n}\n'
        for i, p in enumerate(pos)
    )


def spot_scene_and_reference(ies: bool = False):
    stage = usda_stage(LAMBERT_FLOOR_USDA.format(rho=RHO, light=spot_lights(96, ies=ies)))
    return stage, stb_hydra.render(stage, width=W, height=H, lighting="reference")[..., 0]


TILE_SPOTS = dict(
    REUSE, weight_cap=None, K=64, big_tile=32, reuse_k=0, reuse_candidates=64, reuse_target="tile"
)


@pytest.mark.parametrize(
    "extra, ies",
    # Every pair of per pixel / share, cones / IES and 32 / 16 px big tiles (the slots'
    # 4 x 4 or 2 x 2 grid, stb_reuse.slot_grid) in four cases (docs/TESTING.md,
    # "Sweeps"): each value twice, each pair of values once.
    [
        ({}, False),
        ({"big_tile": 16}, True),
        ({"reuse_res": "share", "big_tile": 16}, False),
        ({"reuse_res": "share"}, True),
    ],
)
@pytest.mark.slow
def test_tile_target_unbiased_and_quiet_with_spot_cones(gl_ctx, extra, ies):
    """``reuse_target=tile`` takes a light's cone per pixel from its slot's texels (cos
    space, the cutoff widened a hair) and an IES light's table maximum over phi per
    pixel: with 96 narrow spots (or IES lights) whose edges cross the tiles, 128 frames
    (tests/convergence.py) converge to the reference -- split-half squared bias
    <= 2e-3 (the old 64 -> 256 "falls 2x" test saw a bias floor above ~1.7e-3), the
    error falling > 3x over 8x the frames, the image mean within 1 % (weight cap off).
    Per-pixel targets are also as quiet as the full target's: relMSE <= 5e-3 at 128
    frames, i.e. the 256-frame budget 2.5e-3 (full target 8.5e-4 spots, 1.5e-4 IES; the
    tile target 8.6e-4 / 1.5e-3; with the cone in a per-tile maximum floored at 1 % it
    was 0.043: fireflies where a cone fell between the grid's points; docs/STB_NOTES.md).
    Share mode's picks are correlated within the quad: no noise budget there."""
    stage, ref = spot_scene_and_reference(ies)
    assert ref.mean() > 0.0 and (ies or (ref < 1e-3 * ref.max()).mean() > 0.05)  # dark outside
    opts = dict(TILE_SPOTS, **extra)
    imgs = optimised.render_progressive(
        stage, snapshot_counts(128), width=W, height=H, lighting="stb", **opts
    )
    c = convergence({n: im[..., 0] for n, im in imgs.items()}, ref)
    assert c.finite and np.isfinite(imgs[128]).all()
    assert c.bias2 <= 2e-3, c
    assert c.relmse < c.relmse_early / 3.0, c
    assert abs(c.mean_ratio - 1.0) < 0.01, c
    if extra.get("reuse_res") != "share":
        assert c.relmse <= 5e-3, c


def test_reuse_off_is_the_talks_pipeline(gl_ctx, many_lights):
    """``reuse=off`` is the talk's whole configuration (128 px big tiles, N = 1, K = 64:
    the defaults before the reuse became STB's): bit for bit what those options render
    explicitly, and not the default's image. (Its images are also the regression set's
    ``stb_talk`` rows, kept from before the switch: tests/test_regression_images.py.)"""
    stage, _ = many_lights
    kw = dict(width=64, height=36, lighting="stb", accumulate=2)
    talk = stb_hydra.render(stage, **kw, reuse=False)
    spelled = stb_hydra.render(stage, **kw, reuse=False, big_tile=128, N=1, K=64)
    assert np.array_equal(talk, spelled)
    assert not np.array_equal(talk, stb_hydra.render(stage, **kw))
    assert np.array_equal(
        stb_hydra.render(stage, **kw), stb_hydra.render(stage, **kw, **SHARE_TILE)
    )


# --- history ----------------------------------------------------------------------------

SLIDER = """def Cube "Slider"
{
    double size = 2
    double3 xformOp:translate.timeSamples = {1: (-2, 1, 0), 2: (2, 1, 0)}
    uniform token[] xformOpOrder = ["xformOp:translate"]
}
def SphereLight "A"
{
    float inputs:intensity = 30000
    float inputs:radius = 0.1
    double3 xformOp:translate = (-3, 4, 3)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}
def SphereLight "B"
{
    float inputs:intensity = 30000
    float inputs:radius = 0.1
    double3 xformOp:translate = (3, 4, 3)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}
"""


def engine(stage, w: int, h: int, **opts) -> Engine:
    """One STB engine rendering single frames (``temporal="off"``: the reuse keeps its
    history between calls, ``reuse_temporal=auto`` -> on)."""
    settings = RenderSettings(
        width=w, height=h, lighting="stb", temporal="off", method_options=dict(REUSE, **opts)
    )
    return Engine(stage, settings)


def reservoir_m(eng: Engine) -> np.ndarray:
    """M of this frame's reservoirs after temporal reuse, (h, w), top row first."""
    tex = eng.buffers.textures[CURRENT]
    w, h = tex.size
    raw = np.frombuffer(tex.read(), dtype=np.uint32).reshape(h, w, 4)
    return raw[::-1, :, 2].copy().view(np.float32)


def depth(eng: Engine) -> np.ndarray:
    tex = eng.buffers.textures["g_depth"]
    w, h = tex.size
    return np.frombuffer(tex.read(), dtype=np.float32).reshape(h, w)[::-1].copy()


def test_disocclusion_resets_history(gl_ctx):
    """A box slides away: pixels that saw the box and now see the ground start from the
    frame's own candidates (M = 1); pixels that saw the ground both times keep their
    history (M > 1, up to the cap)."""
    stage = usda_stage(USDA_HEADER + camera_usda((0, 8, 8), -45) + ground_usda(20) + SLIDER)
    eng = engine(stage, 128, 72)
    try:
        for _ in range(6):
            eng.render(time=1.0)
        d1 = depth(eng)
        eng.render(time=2.0)
        d2, m = depth(eng), reservoir_m(eng)
    finally:
        eng.release()
    both = (d1 > 0) & (d2 > 0)
    # Disoccluded: farther now (the box moved off them, uncovering the ground). Pixels
    # the box moved onto keep their history (the box's own surface, reprojected).
    changed = both & (d2 > 1.2 * d1)
    kept = both & (np.abs(d2 - d1) < 1e-4 * d1)
    assert changed.sum() > 100 and kept.sum() > 1000
    assert np.all(m[changed] == 1.0), np.unique(m[changed])
    assert np.median(m[kept]) > 3.0  # 6 frames of history (M counts neighbours' too)


SWITCH = """def SphereLight "A"
{
    float inputs:intensity.timeSamples = {1: 40000, 2: 0, 3: 40000}
    float inputs:radius = 0.1
    double3 xformOp:translate = (-2, 1.5, 0)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}
def SphereLight "B"
{
    float inputs:intensity = 20000
    float inputs:radius = 0.1
    double3 xformOp:translate = (2, 1.5, 0)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}
"""


def frame_means(stage, times: list[float], **opts) -> tuple[list[float], list[float]]:
    """Image mean and the largest reservoir M after temporal reuse, per frame."""
    eng = engine(stage, 96, 54, **opts)
    try:
        means, ms = [], []
        for t in times:
            eng.render(time=t)
            means.append(float(eng.aovs["color"][..., :3].mean()))
            ms.append(float(reservoir_m(eng).max()))
        return means, ms
    finally:
        eng.release()


@pytest.mark.parametrize("cap", [20.0, 4.0])
def test_m_cap_and_switched_lights(gl_ctx, cap):
    """The history's confidence never exceeds the M cap (a reservoir after temporal reuse
    holds at most cap + 1 frames' worth), so the history can never outvote a frame's
    own candidates by more than that. Light A switched off (time 2) and on again (time
    3): the history inside A's influence sphere is dropped (its W was made for the old
    lights), so the first frame after each switch is already within noise of the
    reference -- no lag, for any cap."""
    stage = usda_stage(USDA_HEADER + camera_usda((0, 8, 8), -45) + ground_usda(20) + SWITCH)
    ref = {
        t: float(stb_hydra.render(stage, width=96, height=54, lighting="reference", time=t).mean())
        for t in (1.0, 2.0, 3.0)
    }
    assert ref[1.0] > 1.5 * ref[2.0]  # A is a large part of the image
    times = [1.0] * 30 + [2.0] * 3 + [3.0] * 3
    means, ms = frame_means(stage, times, reuse_m_cap=cap)
    assert max(ms) <= cap + 1.0, (cap, max(ms))
    assert ms[29] == cap + 1.0  # 30 still frames: the cap is reached
    for k, t in ((30, 2.0), (31, 2.0), (33, 3.0), (34, 3.0)):
        assert abs(means[k] / ref[t] - 1.0) < 0.1, (cap, k, means[k], ref[t])


def test_fov_remap():
    """Previous FoV index -> this frame's, through the light-table rows."""
    prev = np.array([5, 2, 9, 7])
    cur = np.array([2, 7, 1])
    assert fov_remap(prev, cur, 10).tolist() == [-1, 0, -1, 1]


# --- determinism and numerics -----------------------------------------------------------


def test_same_seed_same_image(gl_ctx, many_lights):
    stage, _ = many_lights
    runs = []
    for _ in range(2):
        eng = engine(stage, 96, 54)
        try:
            for _ in range(3):
                eng.render(time=1.0)
            runs.append(eng.aovs["color"].copy())
        finally:
            eng.release()
    assert np.array_equal(runs[0], runs[1])


def shadowed_scene() -> str:
    rng = np.random.default_rng(7)
    s = [USDA_HEADER + camera_usda((0, 8, 8), -45) + ground_usda(20)]
    s.append(
        'def Cube "Box"\n{\n    double size = 2\n    double3 xformOp:translate = (0, 1, 0)\n'
        '    uniform token[] xformOpOrder = ["xformOp:translate"]\n}\n'
    )
    for i in range(40):
        p = rng.uniform([-6, 0.5, -6], [6, 3, 6])
        cone = (
            "    float inputs:shaping:cone:angle = 40\n    float xformOp:rotateX = -90\n"
            if i % 3 == 0
            else ""
        )
        order = '"xformOp:translate", "xformOp:rotateX"' if cone else '"xformOp:translate"'
        schema = ' (\n    prepend apiSchemas = ["ShapingAPI", "ShadowAPI"]\n)' if cone else ""
        s.append(
            f'def SphereLight "L{i}"{schema}\n{{\n    float inputs:intensity = 8000\n'
            f"    float inputs:radius = 0.05\n{cone}"
            f"    double3 xformOp:translate = ({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f})\n"
            f"    uniform token[] xformOpOrder = [{order}]\n}}\n"
        )
    return "".join(s)


@pytest.mark.parametrize(
    "opts",
    [
        {"N": 1},
        {"reuse_mis": "count"},
        {"reuse_mis": "count", "reuse_visibility": True},
        {"reuse_mis": "pairwise", "reuse_k": 8},
        {"reuse_shadow_floor": 0.1},
        {"select": "ris"},
        {"reuse_k": 8, "reuse_radius": 2.0},
        {"reuse_k": 0, "reuse_temporal": "off"},
        {"reuse_m_cap": 0.0},
        {"weight_cap": None, "shadow_res": "pixel"},
        {"reuse_candidates": 16},  # big-tile candidates, temporal + spatial (two passes)
        {"reuse_candidates": 64, "reuse_k": 0, "reuse_temporal": "off"},  # fused
        {"reuse_candidates": 8, "reuse_res": "quad", "reuse_shadow_floor": 0.1},
        {"reuse_candidates": 16, "reuse_k": 0, "reuse_target": "cheap", "weight_cap": None},
        # quad-shared candidates; under taa too (reuse_temporal is then ignored)
        {"reuse_candidates": 32, "reuse_k": 0, "reuse_res": "share", "reuse_target": "tile"},
        {
            "reuse_candidates": 4,
            "reuse_k": 0,
            "reuse_res": "share",
            "reuse_target": "tile",
            "reuse_temporal": "on",
            "weight_cap": None,
        },
        {"reuse_candidates": 16, "reuse_target": "tile", "reuse_shadow_floor": 0.1},
        # 16 px big tiles (the slots' 2 x 2 grid), shared quad and per pixel
        {
            "reuse_candidates": 64,
            "reuse_k": 0,
            "reuse_res": "share",
            "reuse_target": "tile",
            "big_tile": 16,
        },
        {"reuse_candidates": 32, "reuse_target": "tile", "big_tile": 16},
    ],
)
def test_no_nan_or_inf(gl_ctx, opts):
    stage = usda_stage(shadowed_scene())
    eng = engine(stage, 64, 36, **opts)
    try:
        for _ in range(4):
            eng.render(time=1.0)
            img = eng.aovs["color"]
            assert np.isfinite(img).all(), opts
            assert img[..., :3].max() > 0.0
    finally:
        eng.release()


#: The configuration of the cost bound (issue 31), its fused pass with the area pass.
COST_CONFIG = dict(reuse_candidates=64, reuse_k=0, reuse_res="share", reuse_target="tile")


@pytest.mark.parametrize(
    "opts, temporal",
    [
        (COST_CONFIG, "off"),
        (dict(COST_CONFIG, reuse_visibility=True), "taa"),  # the taa inputs, the history
        ({"reuse_candidates": 32, "reuse_k": 0, "reuse_temporal": "off"}, "off"),  # per pixel
    ],
)
def test_area_pass_changes_no_pixel(gl_ctx, opts, temporal):
    """The fused pass's compacted area pass (stb_reuse_area.frag) renders bit for bit
    what light_reflect in the shading pass renders -- colour, taa's inputs through taa,
    and the reservoir history -- on the bench generator's mix of spheres, spots, IES,
    disks and rects, where it shades a good part of the pixels."""
    from stb_hydra.renderer.lighting.stb_reuse import HISTORY
    from stb_hydra.scenegen.lights import build_lights_stage

    stage = build_lights_stage(n_lights=60, seed=2, shadow_fraction=0.5, size=8.0)
    imgs, hist, listed = [], [], []
    for area in (True, False):
        settings = RenderSettings(
            width=96,
            height=54,
            lighting="stb",
            temporal=temporal,
            method_options=dict(REUSE, **opts),
        )
        eng = Engine(stage, settings)
        try:
            eng.method.reuse.area_pass = area  # type: ignore[attr-defined]
            for _ in range(3):
                eng.render(time=1.0)
            listed.append(eng.method.reuse.last_area_pixels)  # type: ignore[attr-defined]
            imgs.append(eng.aovs["color"].copy())
            hist.append([eng.buffers.textures[n].read() for n in HISTORY])
        finally:
            eng.release()
    assert listed[0] > 96 * 54 // 20 and listed[1] == 0, listed
    assert np.isfinite(imgs[0]).all() and imgs[0][..., :3].max() > 0.0
    assert np.array_equal(imgs[0], imgs[1])
    assert hist[0] == hist[1]


def test_reuse_with_light_links_is_unbiased(gl_ctx):
    """Light A linked to quad Q1 only (tests/test_links.py's scene): with reuse the
    linked light is never shaded on Q2 -- its target there is 0, so neither the pixel's
    own candidates nor its neighbours' reservoirs can bring it in -- and the mean of many
    frames matches the reference with the same link on each quad within 2.5 %."""
    from test_links import Q1_COLS, Q2_COLS, _links, _rel, _render, two_quads

    o = {"method_options": dict(REUSE, weight_cap=None)}
    st = two_quads(_links("/Geom/Q1"))
    ref = _render(st, "reference")
    got = _render(st, "stb", accumulate=48, **o)
    for cols in (Q1_COLS, Q2_COLS, slice(None)):
        assert abs(got[:, cols].mean() / ref[:, cols].mean() - 1.0) < 0.025, cols
    assert _rel(got[:, Q2_COLS], ref[:, Q2_COLS]) < 0.05


@pytest.mark.parametrize("big_tile", [16, 32])
def test_share_is_exact_with_one_light(gl_ctx, big_tile):
    """One sphere light over the Lambertian floor (tests/test_closed_form_hard.py's closed
    form): the quad-shared reservoirs (16 of the K = 64 slots per pixel; the one light's
    slot lands in one pixel's stratum) give every pixel the light with W = 1: within
    0.2 % of the closed form at every pixel, one frame. (The balance heuristic
    p_i / sum p_j left each quad a per-quad error of its targets' spread: 2.7 % median,
    4.4 % max.)"""
    from test_closed_form_hard import RHO as rho
    from test_closed_form_hard import floor_stage, ground_points, local_light, point_illuminance
    from test_closed_form_hard import render as render_floor

    lpos = (0.3, 2.0, -0.2)
    stage = floor_stage(local_light("SphereLight", lpos))
    exp = rho / math.pi * point_illuminance(ground_points(stage), 1000 * math.pi * 0.01, lpos)
    img = render_floor(stage, "stb", **dict(SHARE_TILE, big_tile=big_tile))
    rel = np.abs(img[..., 0] - exp) / exp
    assert rel.max() < 2e-3, (np.median(rel), rel.max())


def test_live_toggle(gl_ctx, many_lights):
    """The previewer's path (``Engine.set_lighting``, what its options panel calls): reuse
    switched on and off on a live engine renders finite images, and the reuse's history
    builds up while it is on."""
    stage, _ = many_lights
    eng = Engine(stage, RenderSettings(width=64, height=36, lighting="stb", temporal="off"))
    try:
        eng.render()
        eng.set_lighting("stb", **REUSE)
        for _ in range(3):
            eng.render()
            assert np.isfinite(eng.aovs["color"]).all()
        assert eng.method.reuse.count == 3  # type: ignore[attr-defined]
        eng.set_lighting("stb", reuse=False)
        eng.render()
        assert np.isfinite(eng.aovs["color"]).all()
    finally:
        eng.release()


# --- through taa (tests/test_temporal.py's checks, with reuse) --------------------------


def test_taa_light_switched_off_vanishes_within_two_frames(gl_ctx):
    """tests/test_temporal.py's switched-off light with reuse on under taa (reservoir
    history on): 2 frames after the brightest light is set to 0 its light is gone (within
    10 % of its contribution where it shone)."""
    from test_temporal import _lit_floor, _render_one

    stage = _lit_floor()
    on = _render_one(stage, "reference")
    settings = RenderSettings(
        width=96, height=54, lighting="stb", temporal="taa", method_options=REUSE
    )
    eng = Engine(stage, settings)
    try:
        for _ in range(12):
            eng.render()
        stage.GetPrimAtPath("/L2").GetAttribute("inputs:intensity").Set(0.0)
        after = []
        for _ in range(2):
            eng.render()
            after.append(eng.aovs["color"][..., :3].copy())
    finally:
        eng.release()
    off = _render_one(stage, "reference")
    lum = np.array([0.2126, 0.7152, 0.0722])
    contrib = (on - off) @ lum
    mask = contrib > 0.3 * (on @ lum)
    assert mask.sum() > 50
    left = [((a - off) @ lum)[mask].mean() / contrib[mask].mean() for a in after]
    assert abs(left[-1]) < 0.1, left


#: STB's default spelled out (the opt-in configuration of docs/STB_NOTES.md's reuse3 /
#: reuse4, 16 px big tiles since reuse7, the default since deliverable 7): per-pixel
#: candidates shared over the 2x2 quad, the tile target, no spatial reuse (no reservoir
#: history: taa does all the temporal work).
SHARE_TILE = dict(
    reuse=True,
    N=4,
    reuse_k=0,
    big_tile=16,
    reuse_candidates=64,
    reuse_res="share",
    reuse_target="tile",
)
SLIDE_FRAMES = 30
#: Frame index at which the box has left the whole uncovered region (time 14).
SLIDE_UNCOVERED = 13


def _slide_errors(opts: dict) -> dict[str, np.ndarray]:
    """tests/test_temporal.py's sliding box (still camera, taa, 96x54) with the STB
    options ``opts``, over its three seeds: the uncovered floor's error per frame
    (``region_error``, mean over the seeds) against 64 accumulated frames of the final
    state, for the moving box ("moving"), the box parked at its final place ("still")
    and the moving box with taa's history dropped everywhere at the uncovering
    ("restart": what a perfect disocclusion does). Computed once per option set."""
    key = tuple(sorted(opts.items()))
    if key not in _SLIDE_CACHE:  # 270 frames: in the optimised child (tests/optimised.py)
        _SLIDE_CACHE[key] = optimised.call(_slide_run, opts)
    return _SLIDE_CACHE[key]


_SLIDE_CACHE: dict[tuple, dict[str, np.ndarray]] = {}


def _slide_run(opts: dict) -> dict[str, np.ndarray]:
    from test_temporal import SLIDE_SEEDS, _box_track, _lit_floor

    from stb_hydra.metrics import region_error

    frames, w, h = SLIDE_FRAMES, 96, 54
    stage = _lit_floor(_box_track(frames))
    times = [1 + i for i in range(frames)]

    def sequence(st, temporal: str, seed: int = 0, lighting: str = "stb", restart: int = -1):
        settings = RenderSettings(
            width=w,
            height=h,
            lighting=lighting,
            temporal=temporal,
            seed=seed,
            method_options=opts if lighting == "stb" else {},
        )
        eng = Engine(st, settings)
        out, depth_maps = [], []
        try:
            if lighting == "reference":
                eng.request_aovs({"depth"})
            for i, t in enumerate(times):
                if i == restart:
                    eng.temporal.reset()  # type: ignore[union-attr]
                eng.render(time=t)
                out.append(eng.aovs["color"][..., :3].copy())
                if lighting == "reference":
                    depth_maps.append(eng.aovs["depth"].reshape(h, w).copy())
        finally:
            eng.release()
        return np.array(out), depth_maps

    _, geo = sequence(stage, "off", lighting="reference")
    uncovered = (geo[11] > 0) & (geo[11] < geo[-1] - 0.3)
    assert uncovered.sum() > 30
    eng = Engine(stage, RenderSettings(width=w, height=h, lighting="stb", method_options=opts))
    try:
        eng.render(time=frames, accumulate=64)
        settled = eng.aovs["color"][..., :3].copy()
    finally:
        eng.release()
    refs = np.repeat(settled[None], frames, axis=0)
    still_stage = _lit_floor(_box_track(frames, moving=False))
    out = {k: np.zeros(frames) for k in ("moving", "still", "restart")}
    for seed in SLIDE_SEEDS:
        runs = {
            "moving": sequence(stage, "taa", seed)[0],
            "still": sequence(still_stage, "taa", seed)[0],
            "restart": sequence(stage, "taa", seed, restart=SLIDE_UNCOVERED)[0],
        }
        for k, seq in runs.items():
            out[k] += region_error(seq, refs, uncovered) / len(SLIDE_SEEDS)
    return out


@pytest.mark.parametrize(
    "opts",
    [
        pytest.param(REUSE, id="reuse"),
        pytest.param(SHARE_TILE, id="share_tile"),
    ],
)
def test_taa_sliding_box_leaves_no_trail(gl_ctx, opts):
    """tests/test_temporal.py's sliding box with reuse on under taa: the error in the
    floor the box uncovered is back to the still level (the same region with the box
    parked at its final place, x 1.5) within 8 frames of the uncovering, averaged over
    three seeds; the yardstick is STB with reuse itself, 64 accumulated frames of the
    final state. (Before issue 31's reuse6 fix -- taa's edge test took the box's old
    texels for a jitter edge -- ``reuse`` settled in 9 frames. ``share_tile`` settled in
    16 before taa8 -- a young history's noise and the history mixed at the box's edge --
    and in 7 with taa's young-history estimate and edge-left cap, docs/STB_NOTES.md
    "(taa8)"; 11-14 with either alone.) A young history cannot beat a perfect
    disocclusion, so the level at each frame is also 1.2x the error of the same sequence
    with taa's whole history dropped at the uncovering ("restart"): since share's MIS
    fix (docs/STB_NOTES.md "(share MIS)") its still level is 39 % lower, and even the
    restart takes 11 frames to reach 1.5x it (``share_tile`` 13, 1.1x the restart)."""
    from stb_hydra.metrics import frames_to_settle

    e = _slide_errors(opts)
    after = slice(SLIDE_UNCOVERED, None)
    level = np.maximum(1.5 * float(np.median(e["still"][after])), 1.2 * e["restart"][after])
    settle = frames_to_settle(e["moving"][after] / level, 1.0)
    assert settle <= 8, (settle, e["moving"][after].round(3).tolist(), level.round(3).tolist())


def test_taa_sliding_box_leaves_no_ghost(gl_ctx):
    """The trail as a persisting deviation, not a young history's noise: from 8 frames
    after the uncovering on, the uncovered floor's error with the box sliding away is
    within 1.6x (mean over those frames) of the same sequence with taa's whole history
    dropped at the uncovering -- the best any disocclusion test can do. With the opt-in
    configuration (the lowest still level, so the most sensitive): 1.34x; 2.8x before
    issue 31's reuse6 fix (the floor took the box's history as a jitter edge), 1.49x with
    that fix but without the tangent-plane test (the box's side at the crease), 1.34x
    after it; 1.08x with taa8's edge-left cap (the history the jitter mixed at the box's
    far top edge is capped once the edge has gone), hence the bound of 1.2."""
    e = _slide_errors(SHARE_TILE)
    late = slice(SLIDE_UNCOVERED + 8, SLIDE_FRAMES)
    ratio = float(np.mean(e["moving"][late] / e["restart"][late]))
    assert ratio <= 1.2, (
        ratio,
        e["moving"][late].round(3).tolist(),
        e["restart"][late].round(3).tolist(),
    )


def test_reuse_candidate_options_are_checked():
    """reuse_candidates must divide K; quad reservoirs need big-tile candidates; the
    quad-shared reservoirs need no spatial reuse and the tile target without a shadow
    gather."""
    from stb_hydra.renderer.lighting.options import OptionError
    from stb_hydra.renderer.lighting.stb import StbLighting

    for bad in (
        {"reuse_candidates": 24},
        {"reuse_candidates": 32, "K": 16},
        {"reuse_res": "quad", "reuse_candidates": 0},
        {"reuse_res": "share", "reuse_candidates": 32, "reuse_k": 4},  # spatial reuse on
        {"reuse_res": "share", "reuse_candidates": 0, "reuse_k": 0},
        # the exchange reads textures only (llvmpipe's helper invocations load no SSBO)
        {"reuse_res": "share", "reuse_candidates": 32, "reuse_k": 0, "reuse_target": "full"},
        {"reuse_res": "share", "reuse_candidates": 32, "reuse_k": 0, "reuse_target": "cheap"},
        {
            "reuse_res": "share",
            "reuse_candidates": 32,
            "reuse_k": 0,
            "reuse_target": "tile",
            "reuse_shadow_floor": 0.5,
        },
        {"reuse_target": "tile", "reuse_candidates": 16, "reuse_res": "quad"},
    ):
        with pytest.raises(OptionError):
            StbLighting(None, reuse=True, **bad)
    StbLighting(None, reuse=True, reuse_candidates=16, reuse_res="quad").release()
    # share has no temporal reuse: a given reuse_temporal=on is named, once, not silent
    said: list[str] = []
    StbLighting(None, warn=said.append, reuse_temporal="on").release()
    assert len(said) == 1 and "reuse_temporal=on" in said[0] and "share" in said[0]
    said.clear()
    StbLighting(None, warn=said.append, reuse_temporal="on", reuse_res="pixel").release()
    StbLighting(None, warn=said.append).release()
    assert said == []


def test_slot_grid_spacing():
    """The slot pass's grid (``stb_reuse.slot_grid``): points over the tile +- half a
    tile (2 x big_tile px) at least ``limits.STB_REUSE_SLOT_GRID_MIN_PX`` apart, 2 to
    ``limits.STB_REUSE_SLOT_GRID`` per side."""
    from stb_hydra import limits
    from stb_hydra.renderer.lighting.stb_reuse import slot_grid

    assert slot_grid(32) == limits.STB_REUSE_SLOT_GRID == 4  # unchanged for 32 px tiles
    for bt in (16, 32, 64, 128, 256):
        g = slot_grid(bt)
        assert 2 <= g <= limits.STB_REUSE_SLOT_GRID
        assert 2 * bt / g >= limits.STB_REUSE_SLOT_GRID_MIN_PX
    assert slot_grid(16) == 2


def test_ies_cos_rowmax_bounds_the_table():
    """``gl_delegate.ies_cos_rowmax`` (the per-pixel IES of ``reuse_target=tile``): its
    linear lookup at cos(theta), as the shader does it, is never below the table's
    bilinear value (rows theta 0..pi both ends exact, columns periodic phi) in any
    direction with that theta -- the target never under-ranks an IES lobe."""
    from stb_hydra import limits
    from stb_hydra.renderer.gl_delegate import ies_cos_rowmax

    rng = np.random.default_rng(7)
    t_rows, p_cols, bins = limits.IES_TABLE_THETA, limits.IES_TABLE_PHI, 256
    tables = rng.random((2, t_rows, p_cols)) ** 8  # spiky: narrow lobes
    tables[1, :, :] = 0.0
    tables[1, 40:43, 5] = 1.0  # one lobe a few rows wide at one phi
    lut = ies_cos_rowmax(tables.astype(np.float32), bins)
    theta = rng.uniform(0.0, np.pi, 200_000)
    phi = rng.uniform(0.0, 2.0 * np.pi, theta.size)
    layer = rng.integers(0, 2, theta.size)
    # the table's bilinear value (shaders/common/ies.glsl)
    v = theta / np.pi * (t_rows - 1)
    u = phi / (2.0 * np.pi) * p_cols
    r0 = np.floor(v).astype(int)
    r1 = np.minimum(r0 + 1, t_rows - 1)
    c0 = np.floor(u).astype(int) % p_cols
    c1 = (c0 + 1) % p_cols
    fv, fu = v - np.floor(v), u - np.floor(u)
    tab = tables
    val = (1 - fv) * ((1 - fu) * tab[layer, r0, c0] + fu * tab[layer, r0, c1]) + fv * (
        (1 - fu) * tab[layer, r1, c0] + fu * tab[layer, r1, c1]
    )
    # the shader's lookup: linear over bins uniform in cos
    x = (0.5 + 0.5 * np.cos(theta)) * (bins - 1)
    b0 = np.clip(np.floor(x).astype(int), 0, bins - 1)
    b1 = np.minimum(b0 + 1, bins - 1)
    fx = x - np.floor(x)
    got = (1 - fx) * lut[layer, b0] + fx * lut[layer, b1]
    assert (got >= val - 1e-6).all(), float((val - got).max())
    assert lut[1].max() == 1.0 and (lut[1] == 0.0).mean() > 0.5  # still tight
