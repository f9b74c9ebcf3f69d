"""The reference method against closed-form radiometry (real GL, small images).

Expected values use USD's own camera (``Gf.Camera`` pick rays) to find the
point each pixel sees, never the renderer's projection code.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from pxr import Gf, Usd, UsdGeom
from stagegen import LAMBERT_FLOOR_USDA, plane_points, usda_stage

import stb_hydra

W, H = 160, 90
RHO = 0.5


def render_scene(light: str) -> tuple[np.ndarray, np.ndarray]:
    stage = usda_stage(LAMBERT_FLOOR_USDA.format(rho=RHO, light=light))
    img = stb_hydra.render(stage, width=W, height=H, lighting="reference")
    return img, plane_points(stage, W, H)


POINT = """def SphereLight "L"
{{
    float inputs:intensity = {L}
    float inputs:radius = 0.1
    float inputs:exposure = {exposure}
    bool inputs:normalize = {normalize}
    float inputs:specular = 0
    bool treatAsPoint = 1
    double3 xformOp:translate = (0.3, 2, -0.2)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}}
"""


def expected_point(pts: np.ndarray, I: float, lpos=(0.3, 2.0, -0.2)) -> np.ndarray:
    lp = np.array(lpos)
    d = lp - pts
    dist = np.linalg.norm(d, axis=-1)
    cos = d[..., 1] / dist
    return RHO / math.pi * I * cos / dist**2


def test_point_light_over_lambertian_plane(gl_ctx):
    img, pts = render_scene(POINT.format(L=10000, exposure=0, normalize=0))
    I = 10000 * math.pi * 0.1**2
    exp = expected_point(pts, I)
    got = img[..., 0]
    assert np.isfinite(img).all()
    rel = np.abs(got - exp) / exp
    assert rel.max() < 0.01, f"max relative error {rel.max():.4f}"
    np.testing.assert_allclose(img[..., 1], img[..., 0], rtol=1e-3)


def test_exposure_plus_one_doubles(gl_ctx):
    a, _ = render_scene(POINT.format(L=5000, exposure=0, normalize=0))
    b, _ = render_scene(POINT.format(L=5000, exposure=1, normalize=0))
    np.testing.assert_allclose(b, 2 * a, rtol=2e-3, atol=1e-6)


def test_normalize_divides_by_area(gl_ctx):
    img, pts = render_scene(POINT.format(L=8000, exposure=0, normalize=1))
    # L / (4 pi r^2) * pi r^2 = L / 4 cd
    exp = expected_point(pts, 8000 / 4)
    assert (np.abs(img[..., 0] - exp) / exp).max() < 0.01


SPOT = """def SphereLight "L" (
    prepend apiSchemas = ["ShapingAPI"]
)
{
    float inputs:intensity = 20000
    float inputs:radius = 0.1
    float inputs:specular = 0
    float inputs:shaping:cone:angle = 30
    float inputs:shaping:cone:softness = 0
    double3 xformOp:translate = (0, 2, 0)
    float xformOp:rotateX = -90
    uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateX"]
}
"""


def _dilate(m: np.ndarray) -> np.ndarray:
    out = m.copy()
    out[1:] |= m[:-1]
    out[:-1] |= m[1:]
    out[:, 1:] |= m[:, :-1]
    out[:, :-1] |= m[:, 1:]
    return out


def test_spot_cone_edge_within_one_pixel(gl_ctx):
    img, pts = render_scene(SPOT)
    lp = np.array([0.0, 2.0, 0.0])
    w = pts - lp
    cos = -w[..., 1] / np.linalg.norm(w, axis=-1)  # axis points down (-Y)
    expected_lit = cos > math.cos(math.radians(30.0))
    lit = img[..., 0] > 1e-6
    wrong = lit != expected_lit
    band = _dilate(expected_lit) & _dilate(~expected_lit)  # pixels within 1 px of the edge
    assert expected_lit.sum() > 100
    assert not np.any(wrong & ~band), f"{int((wrong & ~band).sum())} pixels off by more than 1 px"
    # inside the cone the value is the plain point-light value
    I = 20000 * math.pi * 0.01
    exp = expected_point(pts, I, (0.0, 2.0, 0.0))
    inner = cos > math.cos(math.radians(28.0))
    assert (np.abs(img[..., 0] - exp)[inner] / exp[inner]).max() < 0.01


WALL = """#usda 1.0
(
    metersPerUnit = 1
    upAxis = "Y"
)
def Camera "Cam"
{{
    float focalLength = 12
    float horizontalAperture = 36
    float verticalAperture = 36
    float2 clippingRange = (0.1, 100)
    double3 xformOp:translate = (0, 0, 1)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}}
def Mesh "Wall"
{{
    int[] faceVertexCounts = [4]
    int[] faceVertexIndices = [0, 1, 2, 3]
    point3f[] points = [(-20, -20, -2), (20, -20, -2), (20, 20, -2), (-20, 20, -2)]
    color3f[] primvars:displayColor = [(0.5, 0.5, 0.5)]
}}
def SphereLight "L" (
    prepend apiSchemas = ["ShapingAPI"]
)
{{
    float inputs:intensity = 1000
    float inputs:radius = 0.1
    float inputs:specular = 0
    asset inputs:shaping:ies:file = @{ies}@
    float xformOp:rotateX = -90
    uniform token[] xformOpOrder = ["xformOp:rotateX"]
}}
"""


def test_ies_linear_vertical_ramp_on_a_wall(gl_ctx, testdata):
    ies = testdata / "ies" / "luxtest__test_linear_vertical.ies"
    stage = usda_stage(WALL.format(ies=ies))
    n = 96
    img = stb_hydra.render(stage, width=n, height=n, lighting="reference")
    cam = UsdGeom.Camera(stage.GetPrimAtPath("/Cam")).GetCamera(Usd.TimeCode.Default())
    fr = cam.frustum
    exp = np.zeros((n, n))
    from stb_hydra.scene.ies import load_ies

    peak = load_ies(ies).max_candela()  # the file's own maximum (the ramp's 0-degree value)
    I0 = 1000 * math.pi * 0.01
    for j in range(n):
        for i in range(n):
            ray = fr.ComputePickRay(Gf.Vec2d(2 * (i + 0.5) / n - 1, 1 - 2 * (j + 0.5) / n))
            o, d = np.array(ray.startPoint), np.array(ray.direction)
            p = o + (-2 - o[2]) / d[2] * d
            dist = np.linalg.norm(p)
            theta = math.acos(-p[1] / dist)  # from nadir (light axis points down)
            ramp = 1.0 - theta / math.pi  # the file: 1 at 0 degrees -> 0 at 180, linear
            exp[j, i] = 0.5 / math.pi * I0 * peak * ramp * (2.0 / dist) / dist**2
    got = img[..., 0]
    rel = np.abs(got - exp) / np.maximum(exp, 1e-9)
    assert rel.max() < 0.02, f"max relative error {rel.max():.4f}"
    # Light aimed down: the wall is brighter below the light than above it.
    assert got[n - 1, n // 2] > 3 * got[0, n // 2]


@pytest.mark.parametrize(
    "rel",
    [
        "luxtest/usd/sphere.usda",
        "luxtest/usd/disk.usda",
        "luxtest/usd/rect.usda",
        "luxtest/usd/cylinder.usda",
        "luxtest/usd/distant.usda",
        "luxtest/usd/dome.usda",
        "luxtest/usd/iesTest.usda",
        "luxtest/usd/ies_scale.usda",
        "arnold-usd/test_0139/data/test.usda",
        "arnold-usd/test_0140/data/test.usda",
        "arnold-usd/test_1316/data/test.usda",
        "arnold-usd/test_2477.1/data/test.usda",
        "arnold-usd/test_0193/data/scene.usda",
        "arnold-usd/test_0047/data/scene.usda",
        "arnold-usd/test_1939/data/scene.usda",
        "arnold-usd/test_2439.13/data/test.usda",
        "openusd/usd/usdLux/testenv/testUsdLuxLightListAPI/root_with_instances.usda",
        "openusd/usd/usdLux/testenv/testUsdLuxLinkingAPI/linking_example.usda",
        "openusd/usdImaging/usdImagingGL/testenv/testUsdImagingGLMaterialXBasic/mxLights.usda",
        "usd-wg/test_assets/NormalsTextureBiasAndScale/NormalsTextureBiasAndScale.usda",
    ],
)
def test_usdlux_testdata_renders_finite(gl_ctx, testdata, rel):
    img = stb_hydra.render(testdata / "usd" / rel, width=128, height=72, lighting="reference")
    assert img.shape == (72, 128, 3)
    assert np.isfinite(img).all()
    assert (img >= 0).all()
