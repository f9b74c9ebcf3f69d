"""The display image does not depend on the unit scale of the lights: intensities
x 1e-3 with the camera exposure raised by log2(1000) stops give the same image for
the reference, clustered and STB (influence ranges follow the camera exposure, and
every sampler decision is relative)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from stagegen import BOX_USDA, USDA_HEADER, ground_usda, usda_stage

from stb_hydra.metrics import display_referred, relmse

pytestmark = pytest.mark.gl

STOPS = math.log2(1000.0)  # 9.966 stops


def scene(scale: float, exposure: float) -> str:
    """Ground, box, and lights at very different levels: a bright shadowed sphere, a
    spot, a downward disk and many dim spheres whose light reaches far only
    through the exposure (a fixed lux cutoff would cull them in the dim version)."""
    cam = (
        'def Camera "Cam"\n{\n    float focalLength = 18\n    float horizontalAperture = 36\n'
        f"    float verticalAperture = 20.25\n    float exposure = {exposure!r}\n"
        "    double3 xformOp:translate = (0, 6, 11)\n    float xformOp:rotateX = -28\n"
        '    uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateX"]\n}\n'
    )
    s = [USDA_HEADER, cam, ground_usda(20), BOX_USDA]
    s.append(
        'def SphereLight "Key" (prepend apiSchemas = ["ShadowAPI"])\n{\n'
        f"    float inputs:intensity = {2000.0 * scale!r}\n    float inputs:radius = 0.1\n"
        "    double3 xformOp:translate = (2, 3, 1)\n"
        '    uniform token[] xformOpOrder = ["xformOp:translate"]\n}\n'
    )
    s.append(
        'def SphereLight "Spot" (prepend apiSchemas = ["ShapingAPI"])\n{\n'
        f"    float inputs:intensity = {3000.0 * scale!r}\n    float inputs:radius = 0.05\n"
        "    float inputs:shaping:cone:angle = 30\n    float inputs:shaping:cone:softness = 0.3\n"
        "    double3 xformOp:translate = (-3, 4, 0)\n    float xformOp:rotateX = -90\n"
        '    uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateX"]\n}\n'
    )
    s.append(
        'def DiskLight "Disk"\n{\n'
        f"    float inputs:intensity = {500.0 * scale!r}\n    float inputs:radius = 0.3\n"
        "    double3 xformOp:translate = (0, 3.5, 4)\n    float xformOp:rotateX = -90\n"
        '    uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateX"]\n}\n'
    )
    rng = np.random.default_rng(5)
    for i in range(24):
        x, z = rng.uniform(-12, 12, 2)
        s.append(
            f'def SphereLight "Dim{i}"\n{{\n'
            f"    float inputs:intensity = {float(rng.uniform(2, 20)) * scale!r}\n"
            "    float inputs:radius = 0.05\n"
            f"    double3 xformOp:translate = ({x:.3f}, 0.6, {z:.3f})\n"
            '    uniform token[] xformOpOrder = ["xformOp:translate"]\n}\n'
        )
    return "".join(s)


def render(text: str, method: str, frames: int) -> tuple[np.ndarray, list[float]]:
    from stb_hydra.renderer.engine import Engine
    from stb_hydra.renderer.frame import RenderSettings

    eng = Engine(usda_stage(text), RenderSettings(width=96, height=54, lighting=method, seed=3))
    try:
        eng.render(accumulate=frames)
        ranges = sorted(float(r) for r in eng.delegate.light_table.range if 0 < r < 1e30)
        return eng.aovs["color"][..., :3].copy(), ranges
    finally:
        eng.release()


@pytest.mark.parametrize(("method", "frames"), [("reference", 1), ("clustered", 1), ("stb", 64)])
def test_display_image_is_invariant_to_the_unit_scale(method: str, frames: int):
    base, r_base = render(scene(1.0, 0.0), method, frames)
    dim, r_dim = render(scene(1e-3, STOPS), method, frames)
    np.testing.assert_allclose(r_dim, r_base, rtol=1e-3)  # ranges follow the exposure
    a, b = display_referred(dim), display_referred(base)
    assert float(base.mean()) > 0.01
    err = relmse(a, b)
    assert err <= 1e-3, f"{method}: relMSE {err:.3g} between the two unit scales"


def test_ranges_grow_with_the_square_root_of_the_exposure():
    from stb_hydra import limits
    from stb_hydra.scene.lights import influence_range

    peak = np.array([1.0, 100.0, 1e4])
    r1 = influence_range(peak, 1.0)
    np.testing.assert_allclose(
        r1,
        np.clip(
            np.sqrt(peak / limits.LIGHT_CUTOFF_LUX),
            limits.MIN_LIGHT_RANGE_M,
            limits.MAX_LIGHT_RANGE_M,
        ),
    )
    np.testing.assert_allclose(influence_range(peak * 1e-3, 1000.0), r1, rtol=1e-12)
