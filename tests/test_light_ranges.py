"""Culling that culls only what cannot be seen (issue 34 item 3): a light's automatic
influence range is where its illuminance, at the camera's exposure, falls to
``limits.LIGHT_CUTOFF_LUX``; what the range window removes from the exposed image is
bounded by that, at any exposure; and the cell-list methods report per-cell counts."""

from __future__ import annotations

import math

import numpy as np
import pytest
from stagegen import USDA_HEADER, camera_usda, ground_usda, usda_stage

from stb_hydra import limits
from stb_hydra.renderer.engine import Engine
from stb_hydra.renderer.frame import RenderSettings
from stb_hydra.renderer.records import InViewLights

pytestmark = pytest.mark.gl

W, H = 96, 54
INTENSITY_CD = 2.0  # a dim light (2 cd): its 0.05 lx radius, 6.3 m, lies in view


def _stage(exposure: float, authored_range: float | None) -> str:
    cam = camera_usda((0, 6, 9), -40, clipping=(0.1, 100)).replace(
        "    float focalLength = 18\n",
        f"    float focalLength = 18\n    float exposure = {exposure:g}\n",
    )
    rng = f"    float stb:range = {authored_range:g}\n" if authored_range else ""
    light = (
        'def SphereLight "L" (\n    prepend apiSchemas = ["StbLightAPI"]\n)\n{\n'
        f"    float inputs:intensity = {INTENSITY_CD / (math.pi * 0.01**2):.6g}\n"
        "    float inputs:radius = 0.01\n    bool treatAsPoint = 1\n"
        f"{rng}"
        "    double3 xformOp:translate = (0, 0.5, 0)\n"
        '    uniform token[] xformOpOrder = ["xformOp:translate"]\n}\n'
    )
    return USDA_HEADER + cam + ground_usda(40) + light


def _render(exposure: float, authored_range: float | None) -> tuple[np.ndarray, float, float]:
    """(scene-linear colour, the light's range (m), the camera's exposure scale)."""
    eng = Engine(
        usda_stage(_stage(exposure, authored_range)),
        RenderSettings(width=W, height=H, lighting="reference", shadows=False),
    )
    try:
        frame = eng.render_frame()
        t = eng.delegate.light_table
        rows = frame.get(InViewLights).rows
        assert len(rows) == 1
        return eng.aovs["color"][..., :3].copy(), float(t.range[rows[0]]), t.exposure_scale
    finally:
        eng.release()


@pytest.mark.parametrize("exposure", [0.0, -4.0])
def test_range_window_removes_less_than_the_cutoff_at_the_exposure(gl_ctx, exposure):
    """Against the same light never culled (stb:range 1 km): the exposed difference is
    nowhere above what a 0.5 albedo floor reflects at the cutoff illuminance where the
    window starts (0.9 of the range), E = LIGHT_CUTOFF_LUX / 0.81 / exposure; and the
    range is sqrt(I x exposure / cutoff), so 4x shorter 4 stops darker."""
    auto, rng, scale = _render(exposure, None)
    full, _r, _s = _render(exposure, 1000.0)
    assert scale == pytest.approx(2.0**exposure, rel=1e-6)
    assert rng == pytest.approx(math.sqrt(INTENSITY_CD * scale / limits.LIGHT_CUTOFF_LUX), rel=1e-5)
    diff = (full - auto).max(axis=2) * scale
    assert diff.max() > 0.0  # the range cut something in view
    fade = limits.RANGE_FADE_START**2
    bound = 0.5 / math.pi * limits.LIGHT_CUTOFF_LUX / fade * 1.1  # + specular of the default
    assert diff.max() <= bound, (diff.max(), bound)


def _lights_scene(n: int = 40) -> str:
    rng = np.random.default_rng(5)
    s = [USDA_HEADER + camera_usda((0, 9, 9), -45, clipping=(0.1, 200)) + ground_usda(30)]
    for i in range(n):
        x, y, z = rng.uniform([-8, 0.3, -8], [8, 1.5, 8])
        s.append(
            f'def SphereLight "L{i}" (\n    prepend apiSchemas = ["StbLightAPI"]\n)\n{{\n'
            "    float inputs:intensity = 20000\n    float inputs:radius = 0.02\n"
            f"    float stb:range = {rng.uniform(0.8, 2.5):.3f}\n"
            f"    double3 xformOp:translate = ({x:.3f}, {y:.3f}, {z:.3f})\n"
            '    uniform token[] xformOpOrder = ["xformOp:translate"]\n}\n'
        )
    return "".join(s)


@pytest.mark.parametrize(
    ("method", "opts"), [("tiled", {"tile_cap": None}), ("clustered", {}), ("lighttree", {})]
)
def test_cell_counts_are_bench_numbers(gl_ctx, method, opts):
    """Per-cell light counts in frame.stats (what `stb bench` records carry): their mean
    over the cells is the list entries per cell, their max the longest list, and short
    ranges keep far less than the brute-force share (1)."""
    eng = Engine(
        usda_stage(_lights_scene()),
        RenderSettings(width=W, height=H, lighting=method, method_options=opts),
    )
    try:
        st = dict(eng.render_frame().stats)
    finally:
        eng.release()
    cells = st.get("clusters") or -(-W // 16) * -(-H // 16)
    assert st["cell_lights_mean"] * cells == pytest.approx(st["list_entries"], rel=1e-3)
    assert st["cell_lights_max"] == st.get("max_cell_lights", st.get("max_tile_lights"))
    assert st["cell_lights_p50"] <= st["cell_lights_p95"] <= st["cell_lights_max"]
    assert st["cell_light_share"] == pytest.approx(
        st["cell_lights_mean"] / st["fov_lights"], rel=1e-3
    )
    assert 0.0 < st["cell_light_share"] < 0.3
