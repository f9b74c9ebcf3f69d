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
@pytest.mark.slow
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


# --- Every light x 1e-6 and x 1e+6 on the courtyard (issue 33 item 1) ------------------

COURTYARD = "usd_scenes/default.usda"
METHODS = ("reference", "sun", "tiled", "clustered", "lighttree", "stb")


def scaled_courtyard(repo, k: float):
    """The courtyard flattened (instanceable prefabs made plain, so their lamps can be
    edited) with every light's intensity and every emissive colour times ``k`` and
    the camera exposure lowered by log2(k) stops: the same picture in other units."""
    from pxr import Usd, UsdGeom, UsdLux, UsdShade

    st = Usd.Stage.Open(Usd.Stage.Open(str(repo / COURTYARD)).Flatten())
    for p in list(st.Traverse()):
        if p.IsInstanceable():
            p.SetInstanceable(False)
    lights = 0
    for p in st.Traverse():
        if p.HasAPI(UsdLux.LightAPI):
            a = p.GetAttribute("inputs:intensity")
            if not a.HasAuthoredValue():
                a.Set(1.0)
            for t in a.GetTimeSamples() or [Usd.TimeCode.Default()]:
                a.Set(a.Get(t) * k, t)
            lights += 1
        elif p.IsA(UsdShade.Shader):
            a = p.GetAttribute("inputs:emissiveColor")
            if a and a.HasAuthoredValue():
                a.Set(a.Get() * k)
        elif p.IsA(UsdGeom.Camera):
            e = p.GetAttribute("exposure")
            e.Set(float(e.Get() or 0.0) - math.log2(k))
    assert lights >= 20, "the courtyard's lights were not found"
    return st


@pytest.mark.slow
@pytest.mark.parametrize("temporal", ["still", "taa"])
@pytest.mark.parametrize("method", METHODS)
def test_every_method_is_scale_free_over_twelve_decades(repo, method: str, temporal: str):
    """Shadow-map sizes (a flux factor in lumens) and the fp16 emission G-buffer
    (emissive lamps overflowed at x1e6) depended on absolute radiance: display relMSE
    0.013 (reference) and 0.36 (STB) at x1e-6 before."""
    import stb_hydra.api as api

    kw: dict = dict(width=64, height=36, lighting=method, seed=3)
    if temporal == "taa":
        kw.update(accumulate=3, temporal="taa")
    base = api.render(scaled_courtyard(repo, 1.0), **kw)
    assert float(base.mean()) > 0.005
    for k in (1e-6, 1e6):
        img = api.render(scaled_courtyard(repo, k), **kw)
        assert np.all(np.isfinite(img))
        err = relmse(display_referred(img), display_referred(base))
        assert err <= 1e-3, f"{method} {temporal} x{k:g}: relMSE {err:.3g}"
