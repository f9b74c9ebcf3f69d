"""UsdLux -> physical units, checked against hand-computed values."""

from __future__ import annotations

import math

import numpy as np
import pytest
from stagegen import usda_stage

from stb_hydra import limits
from stb_hydra.renderer.delegate import RenderDelegate
from stb_hydra.renderer.render_index import RenderIndex
from stb_hydra.scene.stage_scene_index import StageSceneIndex

HEADER = """#usda 1.0
(
    metersPerUnit = {mpu}
    upAxis = "Y"
)
"""


def light(body: str, type_: str = "SphereLight", mpu: float = 1.0, extra: str = ""):
    """Read one light /L authored with ``body``; returns (LightPrim, warnings)."""
    stage = usda_stage(HEADER.format(mpu=mpu) + f'def {type_} "L" {extra}\n{{\n{body}\n}}\n')
    si = StageSceneIndex(stage)
    ri = RenderIndex(si, RenderDelegate())
    ri.sync_all()
    return ri.delegate.lights["/L"].light, si.warnings


def test_sphere_point_intensity():
    lp, _ = light("float inputs:intensity = 1000\nfloat inputs:radius = 0.1")
    # I = L * pi * r^2
    np.testing.assert_allclose(lp.intensity, 1000 * math.pi * 0.01, rtol=1e-6)
    assert lp.flux == pytest.approx(4 * math.pi * 1000 * math.pi * 0.01, rel=1e-3)
    r = math.sqrt(1000 * math.pi * 0.01 / limits.LIGHT_CUTOFF_LUX)
    assert lp.range == pytest.approx(r, rel=1e-6)


def test_exposure_doubles():
    a, _ = light("float inputs:intensity = 10\nfloat inputs:exposure = 0")
    b, _ = light("float inputs:intensity = 10\nfloat inputs:exposure = 1")
    c, _ = light("float inputs:intensity = 10\nfloat inputs:exposure = -2.5")
    np.testing.assert_allclose(b.intensity, 2 * a.intensity, rtol=1e-6)
    np.testing.assert_allclose(c.intensity, a.intensity * 2**-2.5, rtol=1e-6)


def test_normalize_divides_by_area():
    r = 0.25
    on, _ = light(
        f"float inputs:intensity = 100\nfloat inputs:radius = {r}\nbool inputs:normalize = 1"
    )
    # L / (4 pi r^2) * pi r^2 = L / 4 whatever the radius
    np.testing.assert_allclose(on.intensity, 25.0, rtol=1e-6)
    disk, _ = light(
        f"float inputs:intensity = 100\nfloat inputs:radius = {r}\nbool inputs:normalize = 1",
        "DiskLight",
    )
    np.testing.assert_allclose(disk.intensity, 100.0, rtol=1e-6)  # L/(pi r^2) * pi r^2
    rect, _ = light("float inputs:intensity = 8\nfloat inputs:width = 2\nfloat inputs:height = 0.5")
    # (RectLight authored as a sphere above would be wrong: use the rect type)
    rect, _ = light(
        "float inputs:intensity = 8\nfloat inputs:width = 2\nfloat inputs:height = 0.5", "RectLight"
    )
    np.testing.assert_allclose(rect.intensity, 8 * 2 * 0.5, rtol=1e-6)
    assert rect.flux == pytest.approx(math.pi * 8.0, rel=1e-3)  # cosine lobe: pi * I0
    cyl, _ = light(
        "float inputs:intensity = 3\nfloat inputs:radius = 0.1\nfloat inputs:length = 2",
        "CylinderLight",
    )
    np.testing.assert_allclose(cyl.intensity, 3 * 2 * 0.1 * 2, rtol=1e-6)
    assert cyl.flux == pytest.approx(math.pi**2 * 3 * 2 * 0.1 * 2, rel=2e-3)


def test_color_temperature_6500_is_white_and_warm_is_red():
    w, _ = light(
        "float inputs:intensity = 1\nbool inputs:enableColorTemperature = 1\n"
        "float inputs:colorTemperature = 6500"
    )
    np.testing.assert_allclose(w.intensity / w.intensity[0], [1.0, 1.0, 1.0], rtol=1e-6)
    warm, _ = light(
        "float inputs:intensity = 1\nbool inputs:enableColorTemperature = 1\n"
        "float inputs:colorTemperature = 2000"
    )
    assert warm.intensity[0] > warm.intensity[1] > warm.intensity[2]


def test_meters_per_unit_scales_radius():
    lp, _ = light("float inputs:intensity = 100\nfloat inputs:radius = 10", mpu=0.01)
    assert lp.radius == pytest.approx(0.1)
    np.testing.assert_allclose(lp.intensity, 100 * math.pi * 0.1**2, rtol=1e-6)


def test_transform_scale_scales_radius_and_shape():
    lp, _ = light(
        "float inputs:intensity = 100\nfloat inputs:radius = 0.1\n"
        'double3 xformOp:scale = (2, 2, 2)\nuniform token[] xformOpOrder = ["xformOp:scale"]'
    )
    assert lp.radius == pytest.approx(0.2)


def test_distant_light_illuminance():
    lp, _ = light("float inputs:intensity = 500\nbool inputs:normalize = 1", "DistantLight")
    np.testing.assert_allclose(lp.intensity, 500.0, rtol=1e-6)  # normalize: intensity = lux
    lp, _ = light("float inputs:intensity = 50000\nfloat inputs:angle = 0.53", "DistantLight")
    tmax = math.radians(0.53) / 2
    np.testing.assert_allclose(lp.intensity, 50000 * math.pi * math.sin(tmax) ** 2, rtol=1e-6)
    lp, _ = light("float inputs:intensity = 7\nfloat inputs:angle = 0", "DistantLight")
    np.testing.assert_allclose(lp.intensity, 7.0, rtol=1e-6)
    np.testing.assert_allclose(lp.direction, [0, 0, -1], atol=1e-12)


def test_dome_light_uniform_radiance():
    lp, _ = light(
        "float inputs:intensity = 0.3\ncolor3f inputs:color = (1, 0.5, 0.25)", "DomeLight"
    )
    np.testing.assert_allclose(lp.intensity, [0.3, 0.15, 0.075], rtol=1e-6)


def test_cone_flux_and_defaults():
    # ShapingAPI applied with nothing authored: UsdLux's 90 degree cone (hemisphere)
    hemi, _ = light(
        "float inputs:intensity = 100", extra='(\n    prepend apiSchemas = ["ShapingAPI"]\n)'
    )
    assert hemi.has_cone and hemi.cone_angle == 90.0
    i0 = float(hemi.intensity[0])
    assert hemi.flux == pytest.approx(2 * math.pi * i0, rel=2e-3)
    spot, _ = light("float inputs:intensity = 100\nfloat inputs:shaping:cone:angle = 30")
    assert spot.flux == pytest.approx(2 * math.pi * (1 - math.cos(math.radians(30))) * i0, rel=5e-3)
    plain, _ = light("float inputs:intensity = 100")
    assert not plain.has_cone
    assert plain.shadow_enable  # ShadowAPI's fallback: shadows on by default
    assert plain.shadow_update == "static"


def test_stb_attributes():
    lp, _ = light(
        'uniform token stb:shadow:update = "dynamic"\nfloat stb:range = 3',
        extra='(\n    prepend apiSchemas = ["StbLightAPI"]\n)',
    )
    assert lp.shadow_update == "dynamic"
    assert lp.range == pytest.approx(3.0) and lp.range_authored


@pytest.mark.parametrize(
    ("body", "what"),
    [
        ("float inputs:intensity = nan", "intensity"),
        ("float inputs:intensity = inf", "intensity"),
        ("float inputs:intensity = -5", "intensity"),
        ("float inputs:radius = -1", "radius"),
        ("float inputs:shaping:cone:angle = 200", "cone angle"),
        ("float inputs:shaping:cone:angle = -3", "cone angle"),
        ("float inputs:exposure = 40", "exposure"),
        ("color3f inputs:color = (nan, 1, 1)", "colour"),
    ],
)
def test_bad_values_disable_the_light_with_a_warning(body, what):
    lp, warnings = light(body)
    assert not lp.enabled and not lp.valid
    assert any("</L>" in w and what in w for w in warnings), warnings
    assert all("\n" not in w for w in warnings)


def test_legacy_unnamespaced_attributes_are_read_with_a_warning():
    lp, warnings = light("float intensity = 200\nfloat radius = 0.5\nfloat shaping:cone:angle = 40")
    np.testing.assert_allclose(lp.intensity, 200 * math.pi * 0.25, rtol=1e-6)
    assert lp.has_cone and lp.cone_angle == 40.0
    assert any("legacy" in w and "shaping:cone:angle" in w for w in warnings)


def test_invisible_light_is_off():
    lp, _ = light('float inputs:intensity = 1\ntoken visibility = "invisible"')
    assert lp.valid and not lp.enabled


def test_shadow_params_in_metres():
    lp, _ = light(
        "bool inputs:shadow:enable = 0\ncolor3f inputs:shadow:color = (1, 0, 0)\n"
        "float inputs:shadow:distance = 200\nfloat inputs:shadow:falloff = 50",
        mpu=0.01,
    )
    assert not lp.shadow_enable
    np.testing.assert_allclose(lp.shadow_color, [1, 0, 0])
    assert lp.shadow_distance == pytest.approx(2.0)
    assert lp.shadow_falloff == pytest.approx(0.5)


def test_area_lights_do_not_warn():
    """Issue 20: disk/rect/cylinder lights are shaded as areas, so the old "lit as
    punctual lights" approximation warning is gone."""
    stage = usda_stage(
        HEADER.format(mpu=1.0)
        + 'def DiskLight "A" {}\ndef RectLight "B" {}\ndef CylinderLight "C" {}\n'
    )
    si = StageSceneIndex(stage)
    RenderIndex(si, RenderDelegate()).sync_all()
    assert not any("punctual" in w for w in si.warnings)
