"""The exact methods' streamed area integrals (issue 34): common/area.glsl's
``area_integrals`` (the polygon generated, horizon-clipped and summed vertex by vertex,
no vertex arrays) against the array form it replaces (``area_polygon`` +
``polygon_form_factor`` + ``ltc_specular``, the path validated against Mitsuba in
tests/test_area_lights.py, still what STB's ``light_reflect`` runs), selected with the
test-only define ``AREA_ARRAY_INTEGRALS``; and ``NO_CYLINDER_LIGHTS`` compiled exactly
when no cylinder light is in view."""

from __future__ import annotations

import numpy as np
import pytest
from area_scenes import area_stage, glossy_stage, many_area_lights_stage

from stb_hydra.renderer.engine import Engine
from stb_hydra.renderer.frame import RenderSettings
from stb_hydra.renderer.lighting import base

W, H = 48, 27


def _render(stage, method: str, monkeypatch, extra: dict[str, object]) -> tuple[np.ndarray, list]:
    """The method's colour AOV with ``extra`` added to its scene defines, and every
    define set the method compiled with."""
    seen: list[dict[str, object]] = []
    orig = base.LightingMethod.scene_defines

    def defines(self, frame):
        d = orig(self, frame)
        d.update(extra)
        seen.append(dict(d))
        return d

    with monkeypatch.context() as m:
        m.setattr(base.LightingMethod, "scene_defines", defines)
        eng = Engine(stage, RenderSettings(width=W, height=H, lighting=method))
        try:
            eng.render()
            return eng.aovs["color"][..., :3].astype(np.float64), seen
        finally:
            eng.release()


CASES = [
    # the box's faces and the sphere cut by the floor cross the receivers' horizons
    ("rect", lambda: area_stage("rect")),
    ("disk", lambda: area_stage("disk")),
    ("sphere", lambda: area_stage("sphere")),
    ("cylinder", lambda: area_stage("cylinder")),
    # GGX floor: the LTC integral (wide against the lobe)
    ("rect_glossy", lambda: glossy_stage("rect", 0.3)),
    ("disk_glossy", lambda: glossy_stage("disk", 0.4)),
    ("sphere_glossy", lambda: glossy_stage("sphere", 0.3)),
    ("cylinder_glossy", lambda: glossy_stage("cylinder", 0.3)),
    ("mixed24", lambda: many_area_lights_stage(24, seed=3)),
]


@pytest.mark.gl
@pytest.mark.parametrize("name,make", CASES, ids=[c[0] for c in CASES])
def test_streamed_area_integrals_equal_the_array_form(name, make, gl_ctx, monkeypatch):
    stage = make()
    streamed, defs = _render(stage, "reference", monkeypatch, {})
    arrays, _ = _render(stage, "reference", monkeypatch, {"AREA_ARRAY_INTEGRALS": True})
    peak = float(arrays.max())
    assert peak > 0.0 and (arrays > 1e-4 * peak).sum() > 100, name  # a lit image
    # only the order of each contour sum differs: float rounding (the AOV is half float:
    # a value on a rounding boundary moves by its ulp, 2^-11 relative)
    np.testing.assert_allclose(streamed, arrays, rtol=1e-3, atol=1e-5 * peak, err_msg=name)
    no_cylinder = ["NO_CYLINDER_LIGHTS" in d for d in defs]
    if "cylinder" in name or name == "mixed24":
        assert not any(no_cylinder), name
    else:
        assert any(no_cylinder), name
