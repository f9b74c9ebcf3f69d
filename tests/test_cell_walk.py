"""tiled / clustered list walk (issue 34 item C): each list entry carries its light's
``pos_range`` (the walk's range test reads one vec4), clustered keeps its CPU lists
while nothing they depend on changes -- and the images still equal the reference's;
the per-light reach measure (``metrics.light_reach``) against closed forms; the scene
generator's authored ``light_range``."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pxr import Gf
from stagegen import USDA_HEADER, camera_usda, ground_usda, usda_stage

from stb_hydra import limits
from stb_hydra.metrics.light_reach import light_reach
from stb_hydra.renderer.engine import Engine
from stb_hydra.renderer.frame import RenderSettings
from stb_hydra.renderer.records import InViewLights

W, H = 64, 36


# --- the reach measure against closed forms (no GL) ----------------------------------------


def _ground_grid(half: float, n: int) -> np.ndarray:
    """n x n cell-centre points of the square [-half, half]^2 at y = 0 (m)."""
    c = (np.arange(n) + 0.5) / n * 2.0 * half - half
    x, z = np.meshgrid(c, c)
    return np.stack([x.ravel(), np.zeros(x.size), z.ravel()], axis=-1)


def test_light_reach_matches_the_disc_areas():
    """A light at height h with range R over a ground square seen from straight above
    (orthographic rays down): it reaches the disc of radius sqrt(R^2 - h^2) and its
    sphere covers the disc of radius R; fractions of the square's area, to the grid's
    resolution. Per-pixel counts add up to the per-light counts."""
    half, n = 10.0, 400
    P = _ground_grid(half, n)
    origin = P + np.array([0.0, 50.0, 0.0])
    down = np.tile([0.0, -1.0, 0.0], (len(P), 1))
    lights = np.array(
        [[0.0, 1.0, 0.0], [5.0, 2.0, -3.0], [-20.0, 1.0, 0.0]]
    )  # last: off the square
    ranges = np.array([3.0, 2.5, 4.0])
    st = light_reach(P, np.ones(len(P), bool), origin, down, lights, ranges)
    area = (2 * half) ** 2
    assert st.reach[0] == pytest.approx(math.pi * (9.0 - 1.0) / area, rel=0.01)
    assert st.reach[1] == pytest.approx(math.pi * (6.25 - 4.0) / area, rel=0.02)
    assert st.cover[0] == pytest.approx(math.pi * 9.0 / area, rel=0.01)
    assert st.cover[1] == pytest.approx(math.pi * 6.25 / area, rel=0.01)
    assert st.reach[2] == 0.0 and st.cover[2] == 0.0
    assert st.per_pixel.sum() == pytest.approx(st.reach.sum() * len(P))
    s = st.summary(limit=0.05)
    assert s["reach_max"] == pytest.approx(st.reach[0]) and s["reach_over_limit"] == 1
    # pixels without a surface are never reached, but still count in the view
    none = light_reach(P, np.zeros(len(P), bool), origin, down, lights, ranges)
    assert none.reach.max() == 0.0 and none.cover[0] == pytest.approx(st.cover[0])


def test_light_reach_cover_of_a_sphere_behind_the_eye():
    """Perspective rays from one eye: a sphere wholly behind it covers nothing, one
    around the eye covers every pixel."""
    d = np.random.default_rng(1).normal(size=(500, 3))
    d[:, 2] = -np.abs(d[:, 2])  # looking down -z
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    P = d * 5.0
    st = light_reach(
        P,
        np.ones(len(P), bool),
        np.zeros(3),
        d,
        np.array([[0, 0, 10.0], [0, 0, 0.5]]),
        np.array([2.0, 1.0]),
    )
    assert st.cover[0] == 0.0 and st.cover[1] == 1.0
    assert st.reach[1] == 0.0  # the surface is 5 m away


# --- images: the walk's copies and the kept lists -------------------------------------------


def _scene(n: int = 60) -> str:
    rng = np.random.default_rng(7)
    s = [USDA_HEADER + camera_usda((0, 7, 10), -35, clipping=(0.1, 200)) + ground_usda(30)]
    for i in range(n):
        x, y, z = rng.uniform([-8, 0.3, -8], [8, 1.5, 6])
        s.append(
            f'def SphereLight "L{i}" (\n    prepend apiSchemas = ["StbLightAPI"]\n)\n{{\n'
            f"    float inputs:intensity = {rng.uniform(5e3, 4e4):.0f}\n"
            f"    float inputs:radius = {rng.uniform(0.02, 0.2):.3f}\n"
            f"    float stb:range = {rng.uniform(1.0, 4.0):.3f}\n"
            f"    double3 xformOp:translate = ({x:.3f}, {y:.3f}, {z:.3f})\n"
            '    uniform token[] xformOpOrder = ["xformOp:translate"]\n}\n'
        )
    return "".join(s)


def _image(eng: Engine) -> bytes:
    return eng.render_frame().buffers.textures["lighting"].read()


@pytest.mark.gl
@pytest.mark.parametrize("copies", [True, False])
@pytest.mark.parametrize(
    ("method", "opts"),
    [("tiled", {"tile_cap": None}), ("clustered", {}), ("clustered", {"assign": "gpu"})],
)
def test_cell_lists_equal_the_reference_with_and_without_the_entry_copies(
    gl_ctx, monkeypatch, method, opts, copies
):
    """With each entry's pos_range beside its index and without (past
    CELL_POS_RANGE_MAX_BYTES the walk reads the light buffer) the image is the
    reference's, bit for bit."""
    if not copies:
        monkeypatch.setattr(limits, "CELL_POS_RANGE_MAX_BYTES", 0)
    stage = usda_stage(_scene())
    imgs = []
    for m, o in (("reference", {}), (method, opts)):
        eng = Engine(stage, RenderSettings(width=W, height=H, lighting=m, method_options=o))
        try:
            imgs.append(np.frombuffer(_image(eng), dtype=np.float16).astype(np.float32))
        finally:
            eng.release()
    assert imgs[0].max() > 0.0
    assert np.array_equal(imgs[0], imgs[1])


@pytest.mark.gl
def test_clustered_lists_follow_a_light_that_moves(gl_ctx):
    """clustered keeps its lists while the view and the lights' positions / ranges stay
    the same; a light moved across the view rebuilds them: after the move the image is
    the reference's (the kept lists would miss the light where it now is)."""
    stage = usda_stage(_scene())
    engines = {
        m: Engine(stage, RenderSettings(width=W, height=H, lighting=m))
        for m in ("reference", "clustered")
    }
    try:
        before = {m: _image(e) for m, e in engines.items()}
        again = _image(engines["clustered"])
        assert again == before["clustered"]  # kept lists, same image
        stage.GetPrimAtPath("/L0").GetAttribute("xformOp:translate").Set(Gf.Vec3d(0.0, 0.5, 2.0))
        after = {m: _image(e) for m, e in engines.items()}
        assert after["reference"] != before["reference"]  # the move shows
        assert after["clustered"] == after["reference"]
    finally:
        for e in engines.values():
            e.release()


# --- the generator's authored range ---------------------------------------------------------


@pytest.mark.gl
def test_generated_lights_carry_the_authored_range(gl_ctx):
    """gen:lights ``light_range``: every light's influence radius is the authored one,
    whatever its type (spheres, spots, IES, disks, rects)."""
    from stb_hydra.scenegen.lights import build_lights_stage

    eng = Engine(
        build_lights_stage(n_lights=40, seed=3, light_range=3.5),
        RenderSettings(width=W, height=H, lighting="reference"),
    )
    try:
        frame = eng.render_frame()
        rows = frame.get(InViewLights).rows
        rng = np.asarray(eng.delegate.light_table.range[rows], dtype=np.float64)
    finally:
        eng.release()
    assert len(rng) > 20  # most of the 40 in view
    assert np.allclose(rng, 3.5)
    with pytest.raises(ValueError, match="light_range"):
        build_lights_stage(n_lights=4, light_range=-1.0)
