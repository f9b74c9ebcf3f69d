"""Every ``stb validate`` rule with a threshold, at exactly its limit and one past it
(issue 21). The layers are written here and the expected findings are spelled out
in each test (not read back from ``validate/synth.py``); the limits are the
documented values of ``stb_hydra/limits.py``, restated here so that a changed limit
is a visible test change.

Prefab: metres, Y up, a 10 m ground quad, sphere lights of radius 5 cm 1.5 m above
it with ``stb:range = 3`` and shadows off unless a test says otherwise. Flux of a
sphere light of radius r without normalize: I = L pi r^2 (cd), Phi = 4 pi I.
"""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from pxr import Usd

import stb_hydra.validate  # noqa: F401  (registers the stb validators)
from stb_hydra import limits
from stb_hydra.renderer.delegate import RenderDelegate
from stb_hydra.renderer.render_index import RenderIndex
from stb_hydra.scene.stage_scene_index import StageSceneIndex
from stb_hydra.validate.runner import Selection, validate_in_process

R = 0.05
CLEAN_NITS = 8000.0  # Phi = 4 pi^2 r^2 L = 790 lm: inside every band


def nits_for_flux(lm: float) -> float:
    return lm / (4 * math.pi * math.pi * R * R)


def light(
    name: str,
    x: float = 0.0,
    z: float = 0.0,
    nits: float = CLEAN_NITS,
    attrs: str = "",
    schemas: str = "",
    shadow: bool = False,
    rng: float = 3.0,
) -> str:
    meta = f" (\n        prepend apiSchemas = [{schemas}]\n    )" if schemas else ""
    sh = "" if shadow else "bool inputs:shadow:enable = 0"
    return f"""    def SphereLight "{name}"{meta}
    {{
        float inputs:intensity = {nits!r}
        float inputs:radius = {R}
        float stb:range = {rng}
        {sh}
        {attrs}
        double3 xformOp:translate = ({x}, 1.5, {z})
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }}
"""


def prefab(lights: list[str], mpu: float = 1.0, extra_root: str = "") -> str:
    return (
        f'#usda 1.0\n(\n    defaultPrim = "Prefab"\n    metersPerUnit = {mpu!r}\n'
        '    upAxis = "Y"\n)\n\n'
        'def Xform "Prefab" (\n    kind = "component"\n)\n{\n'
        '    def Mesh "Ground"\n    {\n'
        "        int[] faceVertexCounts = [4]\n"
        "        int[] faceVertexIndices = [0, 1, 2, 3]\n"
        "        point3f[] points = [(-5, 0, 5), (5, 0, 5), (5, 0, -5), (-5, 0, -5)]\n"
        "        float3[] extent = [(-5, 0, -5), (5, 0, 5)]\n"
        "    }\n" + "".join(lights) + "}\n" + extra_root
    )


@pytest.fixture(scope="module")
def selection():
    return Selection.parse(None)


def findings(
    tmp_path: Path, selection, text: str, name: str = "asset.usda"
) -> set[tuple[str, str]]:
    """(rule, prim) of every stb finding of the layer ``text``."""
    p = tmp_path / name
    p.write_text(text)
    rep = validate_in_process(str(p), str(tmp_path), selection, False)
    assert rep.opened and rep.status != "crash", rep
    return {(f.rule, f.prim) for f in rep.findings if ":" not in f.rule}


def L(name: str) -> str:
    return f"/Prefab/{name}"


def test_the_limits_are_the_documented_ones():
    """The values the boundaries below are written for (docs/VALIDATE.md)."""
    assert limits.VALIDATE_LIGHT_FLUX_RANGE_LM == (1.0, 200_000.0)
    assert limits.VALIDATE_PREFAB_FLUX_MAX_LM == 1_000_000.0
    assert limits.VALIDATE_SHADOWED_LIGHTS_PER_PREFAB_MAX == 8
    assert limits.VALIDATE_DYNAMIC_SHADOWS_PER_PREFAB_MAX == 2
    assert limits.VALIDATE_PREFAB_ATLAS_FRACTION_MAX == 0.25
    assert limits.SHADOW_ATLAS_SIZE_DEFAULT == 4096 and limits.SHADOW_MAP_MAX_SIZE == 1024
    assert limits.VALIDATE_STB_OVERLAP_MAX == 16
    assert limits.MAX_ABS_EXPOSURE == 30.0
    assert limits.VALIDATE_IES_ANGLE_SCALE_MAX == 10.0
    assert limits.VALIDATE_UNITS_RTOL == 0.01


def test_clean_prefab_has_no_findings(tmp_path, selection):
    assert findings(tmp_path, selection, prefab([light("A"), light("B", x=2)])) == set()


# --- flux -------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "lm,reported",
    [
        (1.0 * (1 + 1e-6), False),  # just inside the low end
        (1.0 * (1 - 1e-3), True),
        (200_000.0 * (1 - 1e-6), False),
        (200_000.0 * (1 + 1e-3), True),
    ],
)
def test_light_flux_band_edges(tmp_path, selection, lm, reported):
    got = findings(tmp_path, selection, prefab([light("A", nits=nits_for_flux(lm))]))
    assert got == ({("flux_light", L("A"))} if reported else set())


def engine_flux(tmp_path: Path, text: str, paths: list[str]) -> list[float]:
    """The engine's flux estimate (lm) of the lights ``paths`` of layer ``text``."""
    p = tmp_path / "flux.usda"
    p.write_text(text)
    ri = RenderIndex(StageSceneIndex(Usd.Stage.Open(str(p))), RenderDelegate())
    ri.sync_all()
    return [float(ri.delegate.lights[q].light.flux) for q in paths]


def test_light_flux_exactly_at_the_band_ends_is_allowed(tmp_path, selection, monkeypatch):
    """The band is closed: a light whose flux equals an end is not reported (the ends
    moved onto the light's own flux, so the comparison itself is checked)."""
    text = prefab([light("A")])
    (flux,) = engine_flux(tmp_path, text, [L("A")])
    assert flux == pytest.approx(4 * math.pi**2 * R * R * CLEAN_NITS, rel=1e-6)
    for band in ((flux, 2 * flux), (flux / 2, flux)):
        monkeypatch.setattr(limits, "VALIDATE_LIGHT_FLUX_RANGE_LM", band)
        assert findings(tmp_path, selection, text, f"b{band[0]:g}.usda") == set()
    monkeypatch.setattr(limits, "VALIDATE_LIGHT_FLUX_RANGE_LM", (flux * (1 + 1e-9), 2 * flux))
    assert findings(tmp_path, selection, text, "c.usda") == {("flux_light", L("A"))}


def test_prefab_flux_at_and_past_the_limit(tmp_path, selection, monkeypatch):
    """Five lights just under 200 klm (inside their own band) are just under 1e6 lm:
    allowed; six are 1.2e6 lm: reported. The limit moved onto the five lights' exact
    total (the engine's own sum) is allowed; a hair under it is reported."""
    each = 200_000.0 * (1 - 1e-7)
    five = [light(f"L{i}", x=2.0 * i - 4, nits=nits_for_flux(each)) for i in range(5)]
    assert findings(tmp_path, selection, prefab(five), "five.usda") == set()
    six = [*five, light("L5", z=2.0, nits=nits_for_flux(each))]
    assert findings(tmp_path, selection, prefab(six), "six.usda") == {("flux_prefab", "/Prefab")}
    total = float(sum(engine_flux(tmp_path, prefab(five), [L(f"L{i}") for i in range(5)])))
    assert total == pytest.approx(5 * each, rel=1e-6)
    monkeypatch.setattr(limits, "VALIDATE_PREFAB_FLUX_MAX_LM", total)
    assert findings(tmp_path, selection, prefab(five), "five_b.usda") == set()
    monkeypatch.setattr(limits, "VALIDATE_PREFAB_FLUX_MAX_LM", total * (1 - 1e-9))
    assert findings(tmp_path, selection, prefab(five), "five_c.usda") == {
        ("flux_prefab", "/Prefab")
    }


# --- shadows ----------------------------------------------------------------------------


def _grid(n: int, **kw) -> list[str]:
    return [light(f"L{i}", x=2.0 * (i % 4) - 3, z=2.0 * (i // 4) - 3, **kw) for i in range(n)]


@pytest.mark.parametrize("n,reported", [(8, False), (9, True)])
def test_shadowed_lights_per_prefab(tmp_path, selection, n, reported):
    got = findings(tmp_path, selection, prefab(_grid(n, shadow=True, rng=0.5)))
    assert got == ({("shadow_count", "/Prefab")} if reported else set())


@pytest.mark.parametrize("n,reported", [(2, False), (3, True)])
def test_dynamic_shadows_per_prefab(tmp_path, selection, n, reported):
    dyn = 'uniform token stb:shadow:update = "dynamic"'
    got = findings(tmp_path, selection, prefab(_grid(n, shadow=True, rng=0.5, attrs=dyn)))
    expected = {("shadow_dynamic", L(f"L{i}")) for i in range(n)}  # info, one per light
    if reported:
        expected.add(("shadow_dynamic_count", "/Prefab"))
    assert got == expected


@pytest.mark.parametrize("n,reported", [(4, False), (5, True)])
def test_shadow_atlas_share(tmp_path, selection, n, reported):
    """Lights of range 100 m and 20 klm seen from 100 m (the reference distance
    floored at the range): 1080 px x 100 / (100 tan 30 deg) = 1871 px radius,
    x 2 x 0.5 texel/px x sqrt(20) = 8366 -> the largest map, 1024^2. Four are
    4 x 1024^2 / 4096^2 = exactly 25 % of the atlas (allowed); five are 31 %."""
    lights = _grid(n, shadow=True, rng=100.0, nits=nits_for_flux(20_000.0))
    got = findings(tmp_path, selection, prefab(lights))
    assert got == ({("shadow_atlas", "/Prefab")} if reported else set())


# --- overlap ----------------------------------------------------------------------------


@pytest.mark.parametrize("n,reported", [(16, False), (17, True)])
def test_stb_overlap_at_one_point(tmp_path, selection, n, reported):
    """n lights whose 50 m influence spheres all cover the whole ground: 16 = K big-tile
    slots is the limit, 17 is reported on the ground mesh."""
    lights = [light(f"L{i}", x=0.1 * i - 0.8, rng=50.0) for i in range(n)]
    got = findings(tmp_path, selection, prefab(lights))
    assert got == ({("stb_overlap", "/Prefab/Ground")} if reported else set())


# --- per-light values -------------------------------------------------------------------


@pytest.mark.parametrize(
    "exposure,nits,reported",
    [
        (30.0, 1e-7, False),  # 2^30 x 1e-7 nits: ~10 lm, inside the flux band
        (30.5, 1e-7, True),
        (-30.0, 1e11, False),  # 2^-30 x 1e11 nits: ~9 lm
        (-30.5, 1e11, True),
    ],
)
def test_exposure_limit(tmp_path, selection, exposure, nits, reported):
    a = light("A", nits=nits, attrs=f"float inputs:exposure = {exposure}")
    got = findings(tmp_path, selection, prefab([a]))
    assert ("exposure_invalid", L("A")) in got if reported else got == set()


@pytest.mark.parametrize(
    "angle,reported", [(180.0, False), (180.01, True), (0.0, True), (0.01, False), (90.0, False)]
)
def test_cone_angle_limits(tmp_path, selection, angle, reported):
    a = light(
        "A",
        nits=CLEAN_NITS * 1e4,  # a 0.01-degree cone emits almost nothing: keep it in band
        attrs=f"float inputs:shaping:cone:angle = {angle}",
        schemas='"ShapingAPI"',
    )
    got = findings(tmp_path, selection, prefab([a]))
    assert (("cone_angle_invalid", L("A")) in got) == reported


@pytest.mark.parametrize(
    "attr,value,rule",
    [
        ("float inputs:intensity", "-1e-6", "intensity_invalid"),
        ("float inputs:radius", "-1e-6", "shape_invalid"),
        ("color3f inputs:color", "(1, -1e-6, 1)", "color_invalid"),
        ("float inputs:shaping:focus", "-1e-6", "focus_invalid"),
    ],
)
def test_negative_values_just_below_zero(tmp_path, selection, attr, value, rule):
    if "intensity" in attr:
        a = light("A", nits=float(value))
    else:
        a = light("A", attrs=f"{attr} = {value}", schemas='"ShapingAPI"')
    got = findings(tmp_path, selection, prefab([a]))
    assert (rule, L("A")) in got


@pytest.mark.parametrize(
    "attr,value",
    [
        ("float inputs:radius", "0"),
        ("color3f inputs:color", "(1, 0, 1)"),
        ("float inputs:shaping:focus", "0"),
    ],
)
def test_zero_is_allowed(tmp_path, selection, attr, value):
    a = light("A", attrs=f"{attr} = {value}", schemas='"ShapingAPI"')
    if "radius" in attr:
        a = a.replace(f"float inputs:radius = {R}\n", "")
    got = findings(tmp_path, selection, prefab([a]))
    assert not {r for r, _ in got} & {"shape_invalid", "color_invalid", "focus_invalid"}, got


@pytest.mark.parametrize("scale,reported", [(10.0, False), (10.01, True)])
def test_ies_angle_scale_degrees_limit(tmp_path, selection, testdata, scale, reported):
    ies = testdata / "ies" / "luxtest__test_linear_vertical.ies"
    a = light(
        "A",
        attrs=f"asset inputs:shaping:ies:file = @{ies}@\n"
        f"        float inputs:shaping:ies:angleScale = {scale}",
        schemas='"ShapingAPI"',
    )
    (tmp_path / ies.name).write_bytes(ies.read_bytes())
    a = a.replace(f"@{ies}@", f"@./{ies.name}@")
    got = findings(tmp_path, selection, prefab([a]))
    assert (("ies_angle_scale", L("A")) in got) == reported


# --- units ------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "ref_mpu,reported", [(1.01, False), (0.9901, False), (1.0103, True), (0.9899, True)]
)
def test_units_tolerance(tmp_path, selection, ref_mpu, reported):
    """A reference whose metersPerUnit is within 1 % of the stage's is the same unit."""
    (tmp_path / "part.usda").write_text(prefab([light("A")], mpu=ref_mpu))
    root = (
        '#usda 1.0\n(\n    defaultPrim = "World"\n    metersPerUnit = 1.0\n    upAxis = "Y"\n)\n'
        'def Xform "World" (\n    prepend references = @./part.usda@\n)\n{\n}\n'
    )
    got = findings(tmp_path, selection, root, "root.usda")
    assert (("units_mismatch", "/World") in got) == reported


@pytest.mark.parametrize("exposure", [None, -4.0, -8.0])
def test_static_light_reach_follows_the_camera_exposure(tmp_path, selection, exposure):
    """``static_light_dynamic_geometry`` uses the range the renderer and the bake use:
    the automatic range sqrt(I e / cutoff) at the stage camera's exposure e (I =
    L pi r^2 for a sphere light), not at exposure 1."""
    peak_cd = CLEAN_NITS * math.pi * R * R
    e = 1.0 if exposure is None else 2.0**exposure
    reach = math.sqrt(peak_cd * e / limits.LIGHT_CUTOFF_LUX)
    gap = 5.0  # from the light to the nearest point of the crate
    lamp = (
        '    def SphereLight "Lamp"\n    {\n'
        f"        float inputs:intensity = {CLEAN_NITS!r}\n        float inputs:radius = {R}\n"
        '        bool inputs:shadow:enable = 0\n        uniform token stb:mobility = "static"\n'
        "        double3 xformOp:translate = (0, 1.5, 0)\n"
        '        uniform token[] xformOpOrder = ["xformOp:translate"]\n    }\n'
        '    def Cube "Crate" (\n        prepend apiSchemas = ["StbGeometryAPI"]\n    )\n    {\n'
        "        double size = 1\n        uniform bool stb:dynamic = 1\n"
        f"        double3 xformOp:translate = ({gap + 0.5}, 1.5, 0)\n"
        '        uniform token[] xformOpOrder = ["xformOp:translate"]\n    }\n'
    )
    cam = (
        'def Camera "Cam"\n{\n'
        f"    float exposure = {exposure!r}\n"
        "    double3 xformOp:translate = (0, 3, 12)\n"
        '    uniform token[] xformOpOrder = ["xformOp:translate"]\n}\n'
        if exposure is not None
        else ""
    )
    got = findings(tmp_path, selection, prefab([lamp], extra_root=cam))
    assert (("static_light_dynamic_geometry", L("Lamp")) in got) == (reach > gap), reach
