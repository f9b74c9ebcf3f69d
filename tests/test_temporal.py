"""Temporal reuse for a moving camera (``--temporal taa``, issue 14) on real GL:
a camera orbit of the courtyard against per-frame references, a light switched
off, a still camera against accumulation, a box sliding across a lit floor.
Small images, fixed seeds."""

from __future__ import annotations

import numpy as np
import optimised
import pytest
from masks import dilate
from material_scenes import preview_material
from pxr import Gf, Usd, UsdGeom
from stagegen import USDA_HEADER, camera_usda, ground_usda, usda_stage

from stb_hydra.metrics import (
    frames_to_settle,
    instability_ratio,
    per_frame_flip,
    region_error,
    relmse,
)
from stb_hydra.renderer.camera import view_setup
from stb_hydra.renderer.engine import Engine
from stb_hydra.renderer.frame import RenderSettings
from stb_hydra.renderer.tasks.temporal import halton_jitter, is_camera_cut, young_weights
from stb_hydra.scenegen.orbit import orbit_camera

pytestmark = pytest.mark.usefixtures("gl_ctx")


def _sequence(stage, frames, lighting, temporal, w, h, times=None, aovs=(), seed=0, **options):
    settings = RenderSettings(
        width=w, height=h, lighting=lighting, temporal=temporal, seed=seed, method_options=options
    )
    eng = Engine(stage, settings)
    out, extra = [], []
    try:
        eng.request_aovs(set(aovs))
        for i in range(frames):
            eng.render(time=None if times is None else times[i])
            out.append(eng.aovs["color"][..., :3].copy())
            extra.append({a: eng.aovs[a].copy() for a in aovs})
    finally:
        eng.release()
    return np.array(out), extra


def _orbit(repo, frames: int) -> Usd.Stage:
    stage = Usd.Stage.Open(str(repo / "usd_scenes" / "default.usda"))
    stage.SetEditTarget(stage.GetSessionLayer())
    orbit_camera(stage, frames, 1.0)
    return stage


def _orbit_figures(repo, frames: int, w: int, h: int, skip: int) -> tuple[float, float, float]:
    """(raw STB's and taa's median per-frame HDR-FLIP against the per-frame reference
    from frame ``skip`` on, taa's instability ratio) of the courtyard orbit. Module
    level: it runs in the optimised child (tests/optimised.py)."""
    stage = _orbit(repo, frames)
    times = [1 + i for i in range(frames)]
    # Without a temporal pass each frame stands alone: the reference and raw STB render
    # only the frames compared (from `skip` on); taa runs the whole orbit (its history).
    ref, _ = _sequence(stage, frames - skip, "reference", "off", w, h, times[skip:])
    raw, _ = _sequence(stage, frames - skip, "stb", "off", w, h, times[skip:])
    taa, _ = _sequence(stage, frames, "stb", "taa", w, h, times)
    f_raw = float(np.median(per_frame_flip(raw, ref)))
    f_taa = float(np.median(per_frame_flip(taa[skip:], ref)))
    return f_raw, f_taa, instability_ratio(taa[skip:], ref)


@pytest.mark.slow
def test_orbit_taa_below_raw_stb(repo):
    """A 24-frame orbit (1 degree a frame) of the courtyard at 160x90: from frame 8
    on, taa's median HDR-FLIP against the per-frame reference is at most 0.7x raw
    one-frame STB's (measured 0.53x), and its frame-to-frame change at most 2.5x the
    reference's own (raw STB: ~7x)."""
    f_raw, f_taa, inst = optimised.call(_orbit_figures, repo, 24, 160, 90, 8)
    assert f_taa <= 0.7 * f_raw, (f_taa, f_raw)
    assert inst <= 2.5, inst


LIGHTS = [  # (x, y, z, intensity): sphere lights over the ground
    (-4.0, 1.5, -2.0, 8000.0),
    (3.0, 2.0, -3.0, 6000.0),
    (0.0, 1.0, 1.0, 20000.0),
    (-2.0, 2.5, 3.0, 5000.0),
    (4.0, 1.2, 2.0, 7000.0),
    (1.0, 3.0, -5.0, 9000.0),
]


def _lights_usda() -> str:
    s = []
    for i, (x, y, z, it) in enumerate(LIGHTS):
        s.append(
            f'def SphereLight "L{i}"\n{{\n    float inputs:intensity = {it}\n'
            f"    float inputs:radius = 0.05\n"
            f"    double3 xformOp:translate = ({x}, {y}, {z})\n"
            '    uniform token[] xformOpOrder = ["xformOp:translate"]\n}\n'
        )
    return "".join(s)


def _lit_floor(box_track: str = "") -> Usd.Stage:
    return usda_stage(
        USDA_HEADER + camera_usda((0, 8, 8), -45) + ground_usda(20) + box_track + _lights_usda()
    )


def _render_one(stage, lighting, w=96, h=54, time=None):
    eng = Engine(stage, RenderSettings(width=w, height=h, lighting=lighting))
    try:
        eng.render(time)
        return eng.aovs["color"][..., :3].copy()
    finally:
        eng.release()


@pytest.mark.slow
def test_light_switched_off_vanishes_within_two_frames():
    """Still camera, taa converged over 12 frames; the brightest light's intensity
    set to 0: 2 frames later its light is gone (where it shone, the image is within
    10 % of its contribution of the reference without it, on average)."""
    stage = _lit_floor()
    on = _render_one(stage, "reference")
    eng = Engine(stage, RenderSettings(width=96, height=54, lighting="stb", temporal="taa"))
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
    # Signed: a lingering light is a bias, STB's one-frame noise averages out.
    left = [((a - off) @ lum)[mask].mean() / contrib[mask].mean() for a in after]
    assert abs(left[-1]) < 0.1, left


@pytest.mark.slow
def test_still_camera_taa_converges_like_accumulate(repo):
    """64 frames of a still courtyard at 96x54: taa's relMSE is within 2x of
    accumulate's (the issue's figure; measured 1.26x with K = 64: 0.067 vs 0.053; it was
    2.14x with K = 16). taa jitters the camera (its image is antialiased), so it is
    compared with the exact method through the same taa pass (the jittered reference),
    accumulate with the plain reference."""
    # The reference's own accumulation is converged at 8 frames (relMSE 3e-6 against
    # its 64, beside STB's 0.05); its taa sequence runs the full 64 (taa's state).
    # In the optimised child (tests/optimised.py): 200 frames.
    taa, acc = optimised.call(_still_relmse, str(repo / "usd_scenes" / "default.usda"))
    assert taa <= 2.0 * acc, (taa, acc)


def _still_relmse(stage: str, w: int = 96, h: int = 54, n: int = 64) -> tuple[float, float]:
    """(taa's relMSE against the reference through taa, accumulate's against the
    accumulated reference) after ``n`` frames of a still camera."""

    def run(lighting, temporal, frames=n):
        eng = Engine(stage, RenderSettings(width=w, height=h, lighting=lighting, temporal=temporal))
        try:
            if temporal == "accumulate":
                eng.render(accumulate=frames)
            else:
                for _ in range(n):
                    eng.render()
            return eng.aovs["color"][..., :3].copy()
        finally:
            eng.release()

    acc = relmse(run("stb", "accumulate"), run("reference", "accumulate", 8))
    taa = relmse(run("stb", "taa"), run("reference", "taa"))
    return taa, acc


def _box_track(frames: int, moving: bool = True) -> str:
    """``/Box`` (a 2 m mesh cube on the ground) at x = -3 until frame 12, sliding to
    x = +3 over frames 13..16 (1.5 m a frame), still after (``moving`` False: at
    x = +3 throughout)."""
    xs = [
        -3.0 if moving and t <= 12 else min(3.0, -3.0 + 1.5 * (t - 12)) if moving else 3.0
        for t in range(1, frames + 1)
    ]
    samples = ", ".join(f"{t}: ({x}, 1, 0)" for t, x in zip(range(1, frames + 1), xs))
    pts = [(x, y, z) for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]
    faces = [0, 1, 3, 2, 4, 6, 7, 5, 0, 4, 5, 1, 2, 3, 7, 6, 0, 2, 6, 4, 1, 5, 7, 3]
    return (
        'def Mesh "Box"\n{\n'
        "    int[] faceVertexCounts = [4, 4, 4, 4, 4, 4]\n"
        f"    int[] faceVertexIndices = {faces}\n"
        f"    point3f[] points = {[tuple(p) for p in pts]}\n"
        "    color3f[] primvars:displayColor = [(0.8, 0.2, 0.2)]\n"
        f"    double3 xformOp:translate.timeSamples = {{{samples}}}\n"
        '    uniform token[] xformOpOrder = ["xformOp:translate"]\n}\n'
    )


SLIDE_SEEDS = (0, 1, 2)


@pytest.mark.slow
def test_sliding_box_leaves_no_trail():
    """A box slides away over a lit floor (still camera, taa): the error in the floor
    it uncovered is back to the still level within 8 frames of the uncovering. The
    yardstick is STB itself (64 accumulated frames of the final state, box gone):
    this floor's STB is biased against the exact reference (a method matter, not a
    temporal one). Still level: the same region in a taa sequence whose box never
    moved (at its final place), x 1.5. The talk's pipeline (``-o reuse=off``); STB's
    default, the reuse: tests/test_stb_reuse.py's test_taa_sliding_box_leaves_no_trail."""
    frames, w, h = 30, 96, 54
    stage = _lit_floor(_box_track(frames))
    times = [1 + i for i in range(frames)]
    _, geo = _sequence(stage, frames, "reference", "off", w, h, times, aovs=("depth",))
    d_before = geo[11]["depth"].reshape(h, w)
    d_after = geo[-1]["depth"].reshape(h, w)
    uncovered = (d_before > 0) & (d_before < d_after - 0.3)
    assert uncovered.sum() > 30
    talk = {"reuse": False}
    eng = Engine(stage, RenderSettings(width=w, height=h, lighting="stb", method_options=talk))
    try:
        eng.render(time=frames, accumulate=64)
        settled = eng.aovs["color"][..., :3].copy()
    finally:
        eng.release()
    refs = np.repeat(settled[None], frames, axis=0)
    # The region's error in one sequence is a noisy curve (a few hundred pixels): with
    # one seed, whether it stays under the level from frame 8 on depended on the seed
    # (settled after 0, 7 or 10 frames for seeds 2, 0, 1 with the same shader), so the
    # curves are averaged over three seeds.
    still_stage = _lit_floor(_box_track(frames, moving=False))
    err, still_err = np.zeros(frames), np.zeros(frames)
    for seed in SLIDE_SEEDS:
        moving, _ = _sequence(stage, frames, "stb", "taa", w, h, times, seed=seed, **talk)
        still, _ = _sequence(still_stage, frames, "stb", "taa", w, h, times, seed=seed, **talk)
        err += region_error(moving, refs, uncovered) / len(SLIDE_SEEDS)
        still_err += region_error(still, refs, uncovered) / len(SLIDE_SEEDS)
    level = 1.5 * float(np.median(still_err[13:]))
    # Frame index 13 (time 14): the box has left the whole region.
    settle = frames_to_settle(err[13:], level)
    assert settle <= 8, (settle, err[13:].round(3).tolist(), level)


def test_halton_jitter_and_camera_cut():
    """Jitter offsets are subpixel and cover the pixel; the jittered view moves the
    image by the jitter while the unjittered matrix stays; a 90 degree turn is a cut."""
    js = np.array([halton_jitter(i) for i in range(16)])
    assert np.all(np.abs(js) < 0.5)
    assert abs(js[:, 0].mean()) < 0.1 and abs(js[:, 1].mean()) < 0.1
    from stb_hydra.scene.prims import CameraPrim
    from stb_hydra.shadows.capture import look_at

    cam = CameraPrim(path="/c")
    cam.transform = look_at(np.array([0.0, 1.0, 5.0]), np.zeros(3))
    v0 = view_setup(cam, 100, 50)
    v1 = view_setup(cam, 100, 50, jitter=(0.25, -0.5))
    p = np.array([0.3, 0.2, -0.1, 1.0])
    c0, c1 = p @ v0.view_proj, p @ v1.view_proj
    px0 = (c0[:2] / c0[3]) * 0.5 * np.array([100, 50])
    px1 = (c1[:2] / c1[3]) * 0.5 * np.array([100, 50])
    assert np.allclose(px1 - px0, [0.25, -0.5], atol=1e-6)
    assert np.allclose(v1.unjittered_view_proj, v0.view_proj)
    cam2 = CameraPrim(path="/c")
    cam2.transform = look_at(np.array([0.0, 1.0, 5.0]), np.array([5.0, 1.0, 5.0]))
    assert is_camera_cut(v0, view_setup(cam2, 100, 50), 10.0)
    assert not is_camera_cut(v0, v1, 10.0)


def test_young_weights_fit_a_quadratic():
    """taa's young-history estimate (temporal.young_weights): the centre value of a
    least-squares quadratic through the 13-tap neighbourhood, i.e. a 2D Savitzky-Golay
    filter. Closed form for those taps: 3/11 at the centre, 2/11 on the axes at 1 px,
    1/11 on the diagonals, -1/11 at 2 px; exact on any quadratic sampled there, not on
    x^4; 1 / sum(w^2) = 11/3 independent taps. On a 5x5 grid: 27/175 - r^2/35, exact on
    cubics too."""
    from stb_hydra.renderer.tasks.temporal import NEIGHBOURHOOD

    w = young_weights()
    x, y = (np.array(v, dtype=np.float64) for v in zip(*NEIGHBOURHOOD))
    r2 = x * x + y * y
    expect = np.select([r2 == 0, r2 == 1, r2 == 2, r2 == 4], [3 / 11, 2 / 11, 1 / 11, -1 / 11])
    np.testing.assert_allclose(w, expect, atol=1e-12)
    rng = np.random.default_rng(3)
    c = rng.normal(size=6)
    quad = c[0] + c[1] * x + c[2] * y + c[3] * x * x + c[4] * x * y + c[5] * y * y
    assert abs(float(w @ quad) - c[0]) < 1e-9
    assert abs(float(w @ x**4)) > 0.5
    assert abs(1 / float(w @ w) - 11 / 3) < 1e-9
    o = np.arange(5) - 2
    gy, gx = (v.ravel() for v in np.meshgrid(o, o, indexing="ij"))
    g = young_weights(tuple(zip(gx.tolist(), gy.tolist())))
    np.testing.assert_allclose(g, 27 / 175 - (gx * gx + gy * gy) / 35, atol=1e-12)
    cubic = c[0] + c[1] * gx + c[2] * gy + c[3] * gx * gx + c[4] * gx * gy + c[5] * gy * gy
    cubic = cubic + c[1] * gx**3 - c[2] * gx * gy * gy
    assert abs(float(g @ cubic) - c[0]) < 1e-9


def test_lent_spread_only_under_the_reuse():
    """The temporal pass takes a lent history's spread out of its clip box only when STB
    lights with reservoir reuse (docs/STB_NOTES.md "(taa12)"), STB's default since
    issue 31's deliverable 7: the talk's pipeline and other methods keep the whole
    spread (1: their images unchanged)."""
    from stb_hydra.renderer.tasks.temporal import LENT_SPREAD_MOVING, lit_by_reuse

    def spread(lighting, **o):
        return LENT_SPREAD_MOVING[lit_by_reuse(RenderSettings(lighting=lighting, method_options=o))]

    assert spread("stb") < 1.0
    assert spread("stb", reuse="off") == 1.0
    assert spread("reference") == 1.0
    assert spread("tiled") == 1.0
    assert spread("stb", reuse="on") < 1.0
    assert spread("stb", reuse=True, N=4, big_tile=16) < 1.0


def test_temporal_setting_is_checked():
    with pytest.raises(ValueError, match="temporal must be one of"):
        RenderSettings(temporal="blur")


def test_sequence_metrics():
    """Per-frame metrics: identical sequences score 0 / 1x; a region's error and the
    frames it takes to settle."""
    rng = np.random.default_rng(3)
    ref = rng.uniform(0.1, 1.0, (4, 8, 8, 3))
    assert np.allclose(per_frame_flip(ref, ref), 0.0)
    assert instability_ratio(ref, ref) == pytest.approx(1.0)
    mask = np.zeros((8, 8), bool)
    mask[:4] = True
    test = ref.copy()
    test[0, :4] *= 2.0  # frame 0 wrong in the region only
    err = region_error(test, ref, mask)
    assert err[0] > 0.5 and np.allclose(err[1:], 0.0)
    assert frames_to_settle(err, 0.1) == 1
    assert frames_to_settle([0.5, 0.5, 0.5], 0.1) == 4
    assert frames_to_settle([0.0, 0.0], 0.1) == 0


def test_taa_history_spans_render_calls(repo):
    """A --frames sequence is one engine rendering time after time: with taa the
    history carries over between ``Engine.render`` calls (no reset for a 1 degree
    move), and a jump of the camera far away is a cut."""
    stage = _orbit(repo, 3)
    eng = Engine(stage, RenderSettings(width=64, height=36, lighting="stb", temporal="taa"))
    try:
        resets = []
        for t in (1, 2, 3):
            eng.render(time=t)
            resets.append(eng.temporal.last_reset)
        assert resets == ["start", "", ""]
        assert eng.temporal.count == 3
        cam = UsdGeom.Xformable(stage.GetPrimAtPath("/Camera"))
        cam.GetOrderedXformOps()[0].Set(Gf.Matrix4d().SetTranslate(Gf.Vec3d(0, 50, 0)), 4)
        eng.render(time=4)
        assert eng.temporal.last_reset == "cut"
    finally:
        eng.release()


def _parallax_orbit(frames: int, step_deg: float = 2.5) -> Usd.Stage:
    """A lit 1.5 m box 4 m in front of a far grey wall (8 m from the camera), the camera
    orbiting the box (radius 4 m, ``step_deg`` a frame, centred on frame 13): the box
    stays near the image centre and the wall behind it slides by ~1 px a frame at
    96x54 (the chess orbit's back row against the table, issue 31 "(taa10)"), so the
    wall emerges from behind the box's trailing silhouette every frame. One sphere
    light above the camera: the wall is ~15x darker than the box's face."""
    ang = [np.radians(step_deg * (t - 13)) for t in range(1, frames + 1)]
    pos = ", ".join(
        f"{t}: ({4 * np.sin(a):.5f}, 1, {4 + 4 * np.cos(a):.5f})" for t, a in enumerate(ang, 1)
    )
    rot = ", ".join(f"{t}: {np.degrees(a):.4f}" for t, a in enumerate(ang, 1))
    s = 0.75
    pts = [(x, y, z) for x in (-s, s) for y in (-s, s) for z in (-s, s)]
    faces = [0, 1, 3, 2, 4, 6, 7, 5, 0, 4, 5, 1, 2, 3, 7, 6, 0, 2, 6, 4, 1, 5, 7, 3]
    order = '    uniform token[] xformOpOrder = ["xformOp:translate"]\n}\n'
    return usda_stage(
        USDA_HEADER + 'def Camera "Cam"\n{\n    float focalLength = 18\n'
        "    float horizontalAperture = 36\n    float verticalAperture = 20.25\n"
        f"    double3 xformOp:translate.timeSamples = {{{pos}}}\n"
        f"    float xformOp:rotateY.timeSamples = {{{rot}}}\n"
        '    uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateY"]\n}\n'
        'def Mesh "Box"\n{\n    int[] faceVertexCounts = [4, 4, 4, 4, 4, 4]\n'
        f"    int[] faceVertexIndices = {faces}\n    point3f[] points = {pts}\n"
        "    color3f[] primvars:displayColor = [(0.8, 0.8, 0.8)]\n"
        f"    double3 xformOp:translate = (0, 1, 4)\n{order}"
        'def Mesh "Wall"\n{\n    int[] faceVertexCounts = [4]\n'
        "    int[] faceVertexIndices = [0, 1, 2, 3]\n"
        "    point3f[] points = [(-20, -10, 0), (20, -10, 0), (20, 10, 0), (-20, 10, 0)]\n"
        "    color3f[] primvars:displayColor = [(0.5, 0.5, 0.5)]\n}\n"
        'def SphereLight "L"\n{\n    float inputs:intensity = 3000\n'
        f"    float inputs:radius = 0.05\n    double3 xformOp:translate = (0, 3, 7)\n{order}"
    )


def test_parallax_leaves_no_ghost_of_the_occluder():
    """The background that emerges from behind a nearer silhouette while the camera
    orbits is not lent the occluder's history (issue 31 "(taa11)": the chess orbit's
    bright streaks of the back-row pieces over the dark table). Exact lighting (no
    noise: any excess is taa's) against the per-frame reference: on frames 4-20 no wall
    pixel farther than 2 px from the box exceeds the reference by a tenth of the box's
    face. (Before the fix: 10-26 such pixels a frame, up to 0.41 of the box.)"""
    frames, w, h = 22, 96, 54
    stage = _parallax_orbit(frames)
    times = [1 + i for i in range(frames)]
    ref, geo = _sequence(stage, frames, "reference", "off", w, h, times, aovs=("depth",))
    taa, _ = _sequence(stage, frames, "reference", "taa", w, h, times)
    lum = np.array([0.2126, 0.7152, 0.0722])
    worst = []
    for f in range(4, 21):
        d = geo[f]["depth"].reshape(h, w)
        box = (d > 0) & (d < 6)
        near = dilate(box, 2)  # the silhouette's own antialiasing
        wall = (d > 6) & ~near
        assert box.sum() > 100 and wall.sum() > 2000
        face = float(np.median((ref[f] @ lum)[box]))
        excess = ((taa[f] - ref[f]) @ lum)[wall] / face
        worst.append(float(excess.max()))
    assert max(worst) < 0.1, np.round(worst, 3).tolist()


def _glossy_orbit(frames: int, step_deg: float = 4.0) -> Usd.Stage:
    """A dark glossy floor (UsdPreviewSurface, roughness 0.3) under one small sphere
    light 0.4 m above it; the camera (3 m out, 1.5 m up, looking at the light's foot)
    orbits that foot by ``step_deg`` a frame (``orbit_camera``): the highlight stays near
    the image centre while the floor turns under it, so a history that follows the floor
    drags the highlight back to where it was."""
    up, out = 1.5, 3.0
    pitch = np.degrees(np.arctan2(up, out))
    stage = usda_stage(
        USDA_HEADER
        + camera_usda((0, up, out), -pitch)
        + preview_material(
            "Gloss",
            "        color3f inputs:diffuseColor = (0.2, 0.2, 0.2)\n"
            "        float inputs:roughness = 0.3\n",
        )
        + 'def Mesh "Floor" (\n    prepend apiSchemas = ["MaterialBindingAPI"]\n)\n{\n'
        "    int[] faceVertexCounts = [4]\n    int[] faceVertexIndices = [0, 1, 2, 3]\n"
        "    point3f[] points = [(-10, 0, -10), (-10, 0, 10), (10, 0, 10), (10, 0, -10)]\n"
        "    rel material:binding = </Gloss>\n}\n"
        'def SphereLight "L"\n{\n    float inputs:intensity = 300\n'
        "    float inputs:radius = 0.05\n    double3 xformOp:translate = (0, 0.4, 0)\n"
        '    uniform token[] xformOpOrder = ["xformOp:translate"]\n}\n'
    )
    orbit_camera(stage, frames, step_deg, float(np.hypot(up, out)))
    return stage


def test_reuse_highlight_keeps_up_with_a_moving_camera():
    """Under STB's reuse a pixel's history is capped by its specular lobe against how
    far the view turned (docs/STB_NOTES.md "(taa13)"): a highlight slides over the
    surface as the camera moves, and history that follows the surface holds it where it
    was. One light, so STB with the reuse is exact each frame (the reference's image)
    and what differs is taa's own. Medians over frames 8-15: the error (L1 of luminance
    over the reference's sum) under 0.30, the highlight's peak above 0.36 of the
    reference's. Measured 0.25 / 0.41; without the lobe's cap 0.35 / 0.30; with STB
    defaults' moving history (32 frames, the neighbourhood mean) 0.37 / 0.29."""
    frames, w, h = 16, 96, 54
    stage = _glossy_orbit(frames)
    times = [1 + i for i in range(frames)]
    ref, _ = _sequence(stage, frames, "reference", "off", w, h, times)
    taa, _ = _sequence(stage, frames, "stb", "taa", w, h, times, reuse="on")
    lum = np.array([0.2126, 0.7152, 0.0722])
    t, r = taa[8:16] @ lum, ref[8:16] @ lum
    err = (np.abs(t - r).sum(axis=(1, 2)) / r.sum(axis=(1, 2))).tolist()
    peak = (t.max(axis=(1, 2)) / r.max(axis=(1, 2))).tolist()
    assert np.median(err) < 0.30, np.round(err, 3).tolist()
    assert np.median(peak) > 0.36, np.round(peak, 2).tolist()


def _camera_stage(anim: str = "") -> Usd.Stage:
    """A floor, one light and /Cam; ``anim`` is authored on the camera (USDA body)."""
    stage = usda_stage(USDA_HEADER + ground_usda(20) + camera_usda((0, 3, 8), -15) + _lights_usda())
    stage.SetEditTarget(stage.GetRootLayer())
    cam = stage.GetPrimAtPath("/Cam")
    if anim == "translate":
        op = UsdGeom.Xformable(cam).GetOrderedXformOps()[0]
        op.Set(Gf.Vec3d(0, 3, 8), 1)
        op.Set(Gf.Vec3d(1, 3, 8), 3)
    elif anim == "constant":
        op = UsdGeom.Xformable(cam).GetOrderedXformOps()[0]
        for t in (1, 2, 3):
            op.Set(Gf.Vec3d(0, 3, 8), t)
    elif anim == "focal":
        a = UsdGeom.Camera(cam).GetFocalLengthAttr()
        a.Set(18.0, 1)
        a.Set(35.0, 3)
    elif anim == "parent":
        parent = UsdGeom.Xform.Define(stage, "/Rig")
        op = parent.AddTranslateOp()
        op.Set(Gf.Vec3d(0, 0, 0), 1)
        op.Set(Gf.Vec3d(0, 0, 2), 3)
        stage.DefinePrim("/Rig/Cam", "Camera")  # moves with its parent
        return stage
    return stage


@pytest.mark.parametrize(
    ("anim", "path", "moves"),
    [
        ("", "/Cam", False),
        ("constant", "/Cam", False),  # time samples that never change: still
        ("translate", "/Cam", True),
        ("focal", "/Cam", True),
        ("parent", "/Rig/Cam", True),  # an animated ancestor moves the view
    ],
)
def test_camera_moves(anim, path, moves):
    from stb_hydra.scene.cameras import camera_moves

    stage = _camera_stage(anim)
    assert camera_moves(stage, path, [1.0, 2.0, 3.0]) is moves
    assert camera_moves(stage, path, [1.0]) is False  # one frame: nothing to reuse
    assert camera_moves(stage, None, [1.0, 2.0, 3.0]) is False  # free framing camera


@pytest.mark.parametrize(("anim", "expected"), [("translate", "taa"), ("", "accumulate")])
def test_render_cli_temporal_auto(tmp_path, anim, expected):
    """``stb render --frames`` picks taa for a moving camera, accumulate for a still one
    (``--temporal auto``, the default); an explicit mode is kept."""
    import json

    from stb_hydra.apps import cli

    stage = _camera_stage(anim)
    scene = tmp_path / "s.usda"
    stage.Flatten().Export(str(scene))
    for mode, want in (("auto", expected), ("off", "off")):
        stats = tmp_path / f"{mode}.json"
        argv = ["render", str(scene), str(tmp_path / f"{mode}.####.exr"), "--frames", "1:3"]
        argv += ["--width", "32", "--height", "18", "--lighting", "stb", "--stats", str(stats)]
        assert cli.main([*argv, "--temporal", mode]) == 0
        assert json.loads(stats.read_text())["settings"]["temporal"] == want


def test_set_temporal_switches_a_live_engine(repo):
    stage = _camera_stage()
    eng = Engine(stage, RenderSettings(width=32, height=18, lighting="stb"))
    try:
        eng.render()
        assert eng.temporal is None
        eng.set_temporal("taa")
        assert eng.temporal is not None and eng.settings.temporal == "taa"
        eng.render()
        assert np.isfinite(eng.aovs["color"]).all()
        with pytest.raises(ValueError, match="temporal must be one of"):
            eng.set_temporal("nope")
    finally:
        eng.release()
