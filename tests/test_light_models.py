"""How the exact methods split their in-view lights by light model (issue 34): point
lights, sphere lights narrow against every lobe they reach, other sphere lights, the
rest (renderer/light_buffer.by_light_model, narrow_spheres); and the closed-form sphere
diffuse against a numeric integral over the sphere's visible cap."""

from __future__ import annotations

import math

import numpy as np
import pytest

from stb_hydra import limits
from stb_hydra.renderer import shader_constants as sc
from stb_hydra.renderer.light_buffer import by_light_model, narrow_spheres
from stb_hydra.renderer.light_table import LightTable
from stb_hydra.renderer.lighting.base import light_loops, light_models
from stb_hydra.renderer.records import InViewLights
from stb_hydra.scene import prims
from stb_hydra.scene.prims import LightPrim


def _table(lights: list[tuple[str, float, float, bool]]) -> LightTable:
    """(type, radius or rect width, height above y = 0, treatAsPoint) per light, at
    x = 3 i so that they do not overlap."""
    t = LightTable()
    for i, (kind, size, h, tap) in enumerate(lights):
        lp = LightPrim(path=f"/L{i}", type=kind)
        lp.position = np.array([3.0 * i, h, 0.0])
        lp.intensity = np.ones(3)
        lp.treat_as_point = tap
        if kind == prims.RECT_LIGHT:
            lp.width = lp.height = size
        else:
            lp.radius = size
        t.write(t.alloc(lp.path), lp)
    return t


def test_by_light_model_orders_points_narrow_wide_rest():
    t = _table(
        [
            (prims.RECT_LIGHT, 0.5, 2.0, False),  # rest
            (prims.SPHERE_LIGHT, 0.1, 2.0, False),  # sphere: narrow (mask)
            (prims.SPHERE_LIGHT, 0.1, 2.0, True),  # treatAsPoint: point
            (prims.SPHERE_LIGHT, 0.2, 2.0, False),  # sphere: wide (mask)
            (prims.SPHERE_LIGHT, 0.0, 2.0, False),  # zero radius: point
            (prims.DISK_LIGHT, 0.1, 2.0, False),  # rest
        ]
    )
    rows = np.arange(6)
    narrow = np.array([False, True, False, False, False, True])  # a disk is never a sphere
    out, n_point, n_thin, n_wide = by_light_model(t, rows, narrow)
    assert out.tolist() == [2, 4, 1, 3, 0, 5]
    assert (n_point, n_thin, n_wide) == (2, 1, 1)
    out, n_point, n_thin, n_wide = by_light_model(t, rows, None)
    assert out.tolist() == [2, 4, 1, 3, 0, 5] and (n_thin, n_wide) == (0, 2)


def test_narrow_spheres_is_the_spec_weight_bound_over_the_nearest_receiver():
    """Over a ground box (top at y = 0) and nothing else, a sphere of radius r at height
    h reaches receivers no nearer than h: area_spec_weight (common/area.glsl) is 0 at
    every one iff r / (h alpha) <= AREA_SPEC_POINT, what the mask must say (with its
    float32 margin): lights a hair inside and outside the bound."""
    alpha = 0.36
    k = limits.AREA_SPEC_POINT * alpha
    hs = [1.0, 2.0, 0.5, 4.0]
    lights = []
    for h in hs:
        lights.append((prims.SPHERE_LIGHT, 0.99 * k * h, h, False))  # narrow
        lights.append((prims.SPHERE_LIGHT, 1.01 * k * h, h, False))  # not
    t = _table(lights)
    lo = np.array([[-100.0, -1.0, -100.0]])
    hi = np.array([[100.0, 0.0, 100.0]])
    rows = np.arange(len(lights))
    m = narrow_spheres(t, rows, lo, hi, alpha)
    assert m.tolist() == [True, False] * len(hs)
    # A box beside a light brings its receivers nearer: then it is not narrow.
    near_lo = np.array([[3.0 * 2 + 0.3, 0.0, -1.0]])
    near_hi = near_lo + np.array([1.0, 2.0, 2.0])
    m2 = narrow_spheres(t, rows, np.r_[lo, near_lo], np.r_[hi, near_hi], alpha)
    assert not m2[2] and m2[0]
    # A light without specular never needs the LTC integral.
    t.cols["specular"][1] = 0.0
    assert narrow_spheres(t, rows, lo, hi, alpha)[1]
    # Only sphere lights are ever narrow.
    t2 = _table([(prims.DISK_LIGHT, 0.01, 5.0, False)])
    assert not narrow_spheres(t2, np.arange(1), lo, hi, alpha).any()
    assert t.area_kind[0] == sc.AREA_SPHERE


def test_narrow_spheres_with_each_boxs_alpha():
    """Each receiver box with its own smallest alpha (``box_alpha``): a light over a
    rough ground (alpha 0.64) is narrow up to AREA_SPEC_POINT x 0.64 x h, beyond the
    scene-wide bound of a smooth box far away (alpha 0.1); brought near the smooth box
    (distance e), the smooth box's e x 0.1 is the bound."""
    k = limits.AREA_SPEC_POINT
    h = 2.0
    t = _table(
        [
            (prims.SPHERE_LIGHT, 0.99 * k * 0.64 * h, h, False),  # narrow over the ground
            (prims.SPHERE_LIGHT, 1.01 * k * 0.64 * h, h, False),  # not
        ]
    )
    lo = np.array([[-100.0, -1.0, -100.0], [50.0, 0.0, 50.0]])
    hi = np.array([[100.0, 0.0, 100.0], [51.0, 1.0, 51.0]])
    rows = np.arange(2)
    assert narrow_spheres(t, rows, lo, hi, 0.1, np.array([0.64, 0.1])).tolist() == [True, False]
    assert not narrow_spheres(t, rows, lo, hi, 0.1).any()  # one alpha for all: 0.1
    # the smooth box 0.5 m beside light 0 (x = 0): its 0.5 x 0.1 now bounds it
    lo[1], hi[1] = [0.5, 0.0, -1.0], [1.5, 3.0, 1.0]
    assert not narrow_spheres(t, rows, lo, hi, 0.1, np.array([0.64, 0.1]))[0]
    r_ok = 0.99 * k * 0.1 * 0.5
    t.cols["area_size"][0, 0] = r_ok
    assert narrow_spheres(t, rows, lo, hi, 0.1, np.array([0.64, 0.1]))[0]


def _cap_form_factor(d: float, r: float, theta: float, n: int = 400) -> float:
    """Form factor of a sphere (radius r, centre at distance d, at angle theta from the
    normal) by midpoint quadrature over its cone of directions, clipped to the upper
    hemisphere: (1 / pi) * integral of max(cos, 0) dw."""
    s = math.asin(r / d)
    a = (np.arange(n) + 0.5) / n * s
    b = (np.arange(2 * n) + 0.5) / (2 * n) * 2 * math.pi
    A, B = np.meshgrid(a, b, indexing="ij")
    # direction at angle A from the centre direction c = (sin th, 0, cos th), azimuth B
    c = np.array([math.sin(theta), 0.0, math.cos(theta)])
    u = np.array([math.cos(theta), 0.0, -math.sin(theta)])
    v = np.array([0.0, 1.0, 0.0])
    w = np.cos(A)[..., None] * c + np.sin(A)[..., None] * (
        np.cos(B)[..., None] * u + np.sin(B)[..., None] * v
    )
    cos_n = np.maximum(w[..., 2], 0.0)
    dw = np.sin(A) * (s / n) * (2 * math.pi / (2 * n))
    return float((cos_n * dw).sum() / math.pi)


def sphere_form_factor(c: np.ndarray, r: float, n: np.ndarray) -> float:
    """common/area.glsl's sphere_form_factor, line for line in numpy."""
    d2 = float(c @ c)
    s2 = min(r * r / d2, 1.0)
    ct = float(n @ c) / math.sqrt(d2)
    if ct * ct >= s2:
        return s2 * ct if ct > 0 else 0.0
    st = math.sqrt(max(1 - ct * ct, 1e-12))
    x = math.sqrt(max(1 / s2 - 1, 0.0))
    y = min(max(-x * ct / st, -1.0), 1.0)
    sy = st * math.sqrt(1 - y * y)
    e = (ct * math.acos(y) - x * sy) * s2 + math.atan2(sy, x)
    return min(max(e / math.pi, 0.0), 1.0)


def test_sphere_form_factor_closed_form_matches_quadrature():
    """Above, across and below the horizon: the closed form the sphere loops use agrees
    with a direct integral over the visible cap to 1e-4 of the unclipped value."""
    nrm = np.array([0.0, 0.0, 1.0])
    for d, r in ((2.0, 0.5), (1.0, 0.9), (5.0, 0.1)):
        full = (r / d) ** 2
        for theta in np.linspace(0.0, math.pi, 19):
            c = d * np.array([math.sin(theta), 0.0, math.cos(theta)])
            got = sphere_form_factor(c, r, nrm)
            want = _cap_form_factor(d, r, theta)
            assert abs(got - want) <= 1e-4 * full + 1e-9, (d, r, theta, got, want)


MODELS = ("point", "sphere_narrow", "sphere_wide", "general")


@pytest.mark.parametrize("clearcoat", [False, True])
def test_light_loops_cover_every_model_with_the_fewest_loops(clearcoat):
    """Every subset of light models: each model present has its loop or runs in the
    general loop (whose range starts where the previous loop ends: the models it takes
    must follow every compiled special loop in the light order); no loop for a model
    the scene lacks; never the wide-sphere and the general loop together (the LTC code
    twice); with a clearcoat no sphere loop (each would inline the coated
    light_radiance)."""
    order = {m: i for i, m in enumerate(MODELS)}
    for k in range(1 << len(MODELS)):
        models = frozenset(m for i, m in enumerate(MODELS) if k >> i & 1)
        loops = light_loops(models, clearcoat)
        assert set(loops) <= set(MODELS)
        assert not {"sphere_wide", "general"} <= loops
        uncovered = models - loops
        if uncovered:
            assert "general" in loops
            last_special = max((order[m] for m in loops - {"general"}), default=-1)
            assert min(order[m] for m in uncovered) > last_special, (models, loops)
        for m in loops - {"general"}:
            assert m in models
        if "general" in loops:
            assert models - {"point"}
        if clearcoat:
            assert not loops & {"sphere_narrow", "sphere_wide"}
    assert light_loops(frozenset({"point"}), clearcoat) == {"point"}
    assert light_loops(frozenset(), clearcoat) == frozenset()
    # the courtyard: sphere lights (IES spots, none narrow) and rects -> one loop
    assert light_loops(frozenset({"sphere_wide", "general"}), clearcoat) == {"general"}


def test_light_models_from_partition_counts():
    def iv(n, p, s, w):
        return InViewLights(rows=np.arange(n), point_count=p, sphere_count=s, wide_sphere_count=w)

    assert light_models(iv(0, 0, 0, 0)) == frozenset()
    assert light_models(iv(5, 5, 0, 0)) == {"point"}
    assert light_models(iv(5, 0, 2, 3)) == {"sphere_narrow", "sphere_wide"}
    assert light_models(iv(7, 1, 1, 1)) == set(MODELS)
    assert light_models(iv(4, 0, 0, 0)) == {"general"}  # not split: one general loop


@pytest.mark.gl
def test_a_model_switching_every_frame_builds_its_loop_once(gl_ctx):
    """A light that turns from a sphere into a point light and back every frame: the
    point loop is compiled in once (one new lighting program), then stays in -- no
    program is built on the later frames."""
    from stagegen import USDA_HEADER, camera_usda, ground_usda, usda_stage

    from stb_hydra.renderer.engine import Engine
    from stb_hydra.renderer.frame import RenderSettings
    from stb_hydra.renderer.gl import shader_library

    light = (
        'def SphereLight "L"\n{\n    float inputs:intensity = 500\n'
        "    float inputs:radius = 0.05\n    double3 xformOp:translate = (0, 1, 0)\n"
        '    uniform token[] xformOpOrder = ["xformOp:translate"]\n}\n'
    )
    stage = usda_stage(USDA_HEADER + camera_usda((0, 4, 6), -30) + ground_usda(10) + light)
    radius = stage.GetPrimAtPath("/L").GetAttribute("inputs:radius")
    eng = Engine(stage, RenderSettings(width=32, height=18, lighting="reference"))
    lib = shader_library(eng.ctx)
    try:
        eng.render()
        assert eng.method.light_models & {"sphere_narrow", "sphere_wide"}
        built = []
        for k in range(4):
            radius.Set(0.0 if k % 2 == 0 else 0.05)
            before = lib.compiled
            eng.render()
            built.append(lib.compiled - before)
        assert "point" in eng.method.light_models
        assert built[0] >= 1 and built[1:] == [0, 0, 0], built
    finally:
        eng.release()


@pytest.mark.gl
def test_focus_tint_is_compiled_in_when_a_light_in_view_has_a_focus(gl_ctx):
    """``NO_FOCUS`` (issue 34) leaves the focusTint ``pow`` out only when no light in
    view has a focus: a downward point light (treatAsPoint) with focus 3 and a red focusTint over a
    grey ground, seen from straight above (orthographic, so a pixel's ground distance
    from the light's foot is known from its place on the grid), against the same light
    without focus. The tint is mix(focusTint, 1, cos^focus): red unchanged, green (and
    blue) times cos^focus, cos = h / sqrt(h^2 + rho^2) -- for every exact method."""
    from stagegen import USDA_HEADER, camera_usda, ground_usda, usda_stage

    from stb_hydra.renderer.engine import Engine
    from stb_hydra.renderer.frame import RenderSettings

    h, focus, w, ht = 2.0, 3.0, 32, 18

    def light(f: float) -> str:
        return (
            'def SphereLight "L"\n{\n    float inputs:intensity = 2000\n'
            "    float inputs:radius = 0.05\n    bool treatAsPoint = 1\n"
            f"    float inputs:shaping:focus = {f:g}\n"
            "    color3f inputs:shaping:focusTint = (1, 0, 0)\n"
            f"    double3 xformOp:translate = (0, {h:g}, 0)\n    float xformOp:rotateX = -90\n"
            '    uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateX"]\n}\n'
        )

    def render(f: float, method: str) -> np.ndarray:
        text = USDA_HEADER + camera_usda((0, 10, 0), -90, ortho=True) + ground_usda(15)
        eng = Engine(
            usda_stage(text + light(f)), RenderSettings(width=w, height=ht, lighting=method)
        )
        try:
            eng.render()
            return eng.aovs["color"][..., :3].astype(np.float64)
        finally:
            eng.release()

    # pixel centres on the 20 m x 11.25 m view centred on the light's foot (the grid is
    # symmetric about the centre, so rho does not depend on the image's orientation)
    x = (np.arange(w) + 0.5) / w * 20.0 - 10.0
    z = (np.arange(ht) + 0.5) / ht * 11.25 - 5.625
    rho2 = x[None, :] ** 2 + z[:, None] ** 2
    want = (h / np.sqrt(h * h + rho2)) ** focus
    for method in ("reference", "tiled", "clustered", "lighttree"):
        plain, tinted = render(0.0, method), render(focus, method)
        lit = plain[..., 1] > 1e-4 * plain[..., 1].max()
        assert lit.sum() > 50, method
        np.testing.assert_allclose(tinted[..., 0][lit], plain[..., 0][lit], rtol=1e-4)
        got = tinted[..., 1][lit] / plain[..., 1][lit]
        np.testing.assert_allclose(got, want[lit], rtol=2e-3, atol=1e-5, err_msg=method)
        assert want[lit].min() < 0.5  # the tint is far from 1 somewhere in view
