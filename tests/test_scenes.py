"""The project's USD scenes (usd_scenes/) and scene generators (stb_hydra.scenegen).

Checks composition (every layer and asset path, IES files included, resolves),
the default scene's light inventory, the prefabs' photometry, IES file structure
(with a small reader independent of stb_hydra.scene.ies), and that the generators
give the requested light counts quickly and deterministically.
"""

from __future__ import annotations

import math
import re
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux, UsdShade, UsdUtils

import stb_hydra  # noqa: F401  (registers StbLightAPI / StbGeometryAPI before stages open)

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:  # `tools` (prefab / IES writers) is not installed
    sys.path.insert(0, str(REPO))
SCENES = REPO / "usd_scenes"
USDA_FILES = sorted(SCENES.rglob("*.usda"))
IES_FILES = sorted((SCENES / "ies").glob("*.ies"))
PREFABS = sorted((SCENES / "prefabs").glob("*.usda"))
DEFAULT = SCENES / "default.usda"
TOOLS = [
    "gen_lights_scene",
    "gen_chess_lights",
    "gen_orbs",
    "make_ies_profiles",
    "gen_prefab_library",
]

#: Generous wall-clock bound for one generator call at 10,000 lights on a slow
#: 2-core CI machine (measured ~0.5-1 s here).
GEN_SECONDS = 10.0


# --------------------------------------------------------------------------------------
# helpers
# --------------------------------------------------------------------------------------


def lights_of(stage: Usd.Stage) -> list[Usd.Prim]:
    return [
        p
        for p in Usd.PrimRange.Stage(stage, Usd.TraverseInstanceProxies())
        if p.HasAPI(UsdLux.LightAPI)
    ]


def world_translation(prim: Usd.Prim, t: float) -> Gf.Vec3d:
    m = UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(Usd.TimeCode(t))
    return m.ExtractTranslation()


def transform_varies(prim: Usd.Prim, times) -> bool:
    m0 = UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(Usd.TimeCode(times[0]))
    return any(
        not Gf.IsClose(
            UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(Usd.TimeCode(t)), m0, 1e-6
        )
        for t in times[1:]
    )


def asset_values(stage: Usd.Stage):
    """(attribute, SdfAssetPath) for every authored asset-valued attribute."""
    for prim in Usd.PrimRange.Stage(stage, Usd.TraverseInstanceProxies()):
        for attr in prim.GetAuthoredAttributes():
            if attr.GetTypeName() == Sdf.ValueTypeNames.Asset:
                v = attr.Get()
                if v is not None and v.path:
                    yield attr, v


def read_ies(path: Path) -> dict:
    """Independent minimal LM-63-2002 reader: header keywords, TILT, counts line and
    exactly the number of values the counts line announces."""
    text = path.read_text(encoding="ascii")
    lines = text.splitlines()
    assert lines[0].strip() == "IESNA:LM-63-2002", f"{path.name}: bad format line"
    keywords, i = {}, 1
    while not lines[i].startswith("TILT="):
        m = re.match(r"^\[(\w+)\]\s*(.*)$", lines[i])
        assert m, f"{path.name}: line {i + 1} is neither a [KEYWORD] nor TILT=: {lines[i]!r}"
        keywords.setdefault(m.group(1), []).append(m.group(2))
        i += 1
    assert lines[i].strip() == "TILT=NONE", f"{path.name}: expected TILT=NONE"
    tokens = " ".join(lines[i + 1 :]).split()
    nums = [float(t) for t in tokens]
    (n_lamps, lumens, mult, n_v, n_h, ptype, units, _w, _l, _h) = nums[:10]
    ballast, _future, watts = nums[10:13]
    n_v, n_h = int(n_v), int(n_h)
    body = nums[13:]
    assert len(body) == n_v + n_h + n_v * n_h, (
        f"{path.name}: {len(body)} values after the counts, expected "
        f"{n_v} + {n_h} + {n_v}*{n_h} = {n_v + n_h + n_v * n_h}"
    )
    v = np.array(body[:n_v])
    h = np.array(body[n_v : n_v + n_h])
    cd = np.array(body[n_v + n_h :]).reshape(n_h, n_v) * mult
    return dict(
        keywords=keywords,
        lamps=n_lamps,
        lumens=lumens,
        ptype=int(ptype),
        units=int(units),
        ballast=ballast,
        watts=watts,
        v=v,
        h=h,
        cd=cd,
        size=len(text.encode()),
    )


def ies_flux(v: np.ndarray, h: np.ndarray, cd: np.ndarray) -> float:
    """Type C flux by trapezoid integration (independent of tools/make_ies_profiles)."""
    th = np.radians(v)
    ring = np.array(
        [
            np.sum(0.5 * (r[1:] * np.sin(th[1:]) + r[:-1] * np.sin(th[:-1])) * np.diff(th))
            for r in cd
        ]
    )
    if len(h) == 1:
        return float(2 * math.pi * ring[0])
    part = float(np.sum(0.5 * (ring[1:] + ring[:-1]) * np.diff(np.radians(h))))
    return part * {90.0: 4.0, 180.0: 2.0, 360.0: 1.0}[float(h[-1])]


def sphere_lumens(prim: Usd.Prim, hemispherical_ies: bool) -> tuple[float, float]:
    """(cd, lm) of a sphere light from its authored attributes: I = L*pi*r^2,
    Phi = 4*pi*I (isotropic) or 2*pi*I (normalised hemispherical IES)."""
    light = UsdLux.SphereLight(prim)
    r = light.GetRadiusAttr().Get()
    cd = light.GetIntensityAttr().Get() * math.pi * r * r
    return cd, (2 if hemispherical_ies else 4) * math.pi * cd


# --------------------------------------------------------------------------------------
# every scene file
# --------------------------------------------------------------------------------------


def test_scene_files_exist():
    names = {p.relative_to(SCENES).as_posix() for p in USDA_FILES}
    for required in (
        "default.usda",
        "prefabs/street_lamp.usda",
        "prefabs/wall_torch.usda",
        "prefabs/ceiling_fixture.usda",
        "prefabs/neon_strip.usda",
        "prefabs/enemy_orb.usda",
    ):
        assert required in names
    assert {p.name for p in IES_FILES} >= {
        "streetlamp_typeII.ies",
        "downlight_narrow.ies",
        "wallwash.ies",
        "uplight.ies",
    }


@pytest.mark.parametrize("path", USDA_FILES, ids=lambda p: p.relative_to(SCENES).as_posix())
def test_scene_composes_and_resolves(path: Path):
    stage = Usd.Stage.Open(str(path))
    assert stage, path
    assert stage.GetCompositionErrors() == [], [str(e) for e in stage.GetCompositionErrors()]
    _layers, _assets, unresolved = UsdUtils.ComputeAllDependencies(str(path))
    assert unresolved == [], unresolved
    for attr, value in asset_values(stage):
        assert value.resolvedPath, f"{attr.GetPath()} = {value.path} does not resolve"
        assert Path(value.resolvedPath).is_file()
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.y
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    assert stage.GetDefaultPrim().IsValid()
    # UsdPreviewSurface with constant inputs only.
    for prim in Usd.PrimRange.Stage(stage, Usd.TraverseInstanceProxies()):
        if prim.IsA(UsdShade.Shader):
            shader = UsdShade.Shader(prim)
            assert shader.GetIdAttr().Get() == "UsdPreviewSurface"
            for inp in shader.GetInputs():
                assert not inp.HasConnectedSource(), f"{inp.GetAttr().GetPath()} is connected"
                assert inp.GetBaseName() in {
                    "diffuseColor",
                    "roughness",
                    "metallic",
                    "emissiveColor",
                    "opacity",
                }


# --------------------------------------------------------------------------------------
# prefabs
# --------------------------------------------------------------------------------------


def _prefab(name: str) -> tuple[Usd.Stage, Usd.Prim]:
    stage = Usd.Stage.Open(str(SCENES / "prefabs" / f"{name}.usda"))
    lights = lights_of(stage)
    assert len(lights) == 1, f"{name}: expected one light, got {len(lights)}"
    return stage, lights[0]


@pytest.mark.parametrize("path", PREFABS, ids=lambda p: p.stem)
def test_prefab_structure(path: Path):
    stage = Usd.Stage.Open(str(path))
    root = stage.GetDefaultPrim()
    assert root.IsA(UsdGeom.Xform)
    assert not UsdGeom.Xformable(root).GetOrderedXformOps(), "prefab root must be untransformed"
    assert any(p.IsA(UsdGeom.Mesh) for p in stage.Traverse()), "prefab without geometry"
    assert any(p.IsA(UsdShade.Material) for p in stage.Traverse())
    for mesh in (UsdGeom.Mesh(p) for p in stage.Traverse() if p.IsA(UsdGeom.Mesh)):
        mat, _ = UsdShade.MaterialBindingAPI(mesh.GetPrim()).ComputeBoundMaterial()
        assert mat, f"{mesh.GetPath()} has no material"
    for light in lights_of(stage):
        assert light.GetAttribute("inputs:intensity").Get() > 0
        assert light.GetMetadata("documentation"), f"{light.GetPath()}: photometry doc missing"
        f = light.GetAttribute("inputs:shaping:ies:file")
        if f and f.Get():
            assert f.Get().path.startswith("../ies/"), "IES paths must be relative"
            assert f.Get().resolvedPath


def test_street_lamp_photometry():
    _stage, light = _prefab("street_lamp")
    assert light.IsA(UsdLux.SphereLight)
    assert 0.05 <= light.GetAttribute("inputs:radius").Get() <= 0.1
    shaping = UsdLux.ShapingAPI(light)
    assert light.HasAPI(UsdLux.ShapingAPI)
    assert shaping.GetShapingConeAngleAttr().HasAuthoredValue()
    assert shaping.GetShapingIesFileAttr().Get().path == "../ies/streetlamp_typeII.ies"
    assert shaping.GetShapingIesNormalizeAttr().Get()
    _, lm = sphere_lumens(light, hemispherical_ies=True)
    assert 4000 <= lm <= 6000, lm
    # aimed down: light -Z -> world -Y
    m = UsdGeom.Xformable(light).ComputeLocalToWorldTransform(Usd.TimeCode.Default())
    assert Gf.IsClose(m.TransformDir(Gf.Vec3d(0, 0, -1)).GetNormalized(), Gf.Vec3d(0, -1, 0), 1e-6)


def test_wall_torch_photometry():
    _stage, light = _prefab("wall_torch")
    api = UsdLux.LightAPI(light)
    assert api.GetEnableColorTemperatureAttr().Get()
    assert 1700 <= api.GetColorTemperatureAttr().Get() <= 2100
    _, lm = sphere_lumens(light, hemispherical_ies=False)
    assert 250 <= lm <= 350, lm
    assert UsdLux.ShadowAPI(light).GetShadowEnableAttr().Get()
    assert light.GetAttribute("stb:shadow:update").Get() == "static"


def test_ceiling_fixture_photometry():
    _stage, light = _prefab("ceiling_fixture")
    shaping = UsdLux.ShapingAPI(light)
    assert shaping.GetShapingIesFileAttr().Get().path == "../ies/downlight_narrow.ies"
    assert shaping.GetShapingIesNormalizeAttr().Get()
    if light.IsA(UsdLux.SphereLight):
        _, lm = sphere_lumens(light, hemispherical_ies=True)
        assert 300 <= lm <= 2000, lm


def test_neon_strip_unshadowed_and_coloured():
    stage, light = _prefab("neon_strip")
    assert light.IsA(UsdLux.RectLight) or light.IsA(UsdLux.CylinderLight)
    assert UsdLux.ShadowAPI(light).GetShadowEnableAttr().Get() is False
    c = UsdLux.LightAPI(light).GetColorAttr().Get()
    assert max(c) - min(c) > 0.5, "neon must be saturated"
    vset = stage.GetDefaultPrim().GetVariantSets().GetVariantSet("neonColor")
    colours = set()
    for name in vset.GetVariantNames():
        vset.SetVariantSelection(name)
        colours.add(tuple(round(x, 3) for x in UsdLux.LightAPI(light).GetColorAttr().Get()))
    assert len(colours) == len(vset.GetVariantNames()) >= 2, "variants must change the colour"


def test_enemy_orb_dynamic():
    stage, light = _prefab("enemy_orb")
    assert light.HasAPI("StbLightAPI")
    assert light.GetAttribute("stb:shadow:update").Get() == "dynamic"
    meshes = [p for p in stage.Traverse() if p.IsA(UsdGeom.Mesh)]
    assert meshes
    for mesh in meshes:
        q, dynamic = mesh, None  # StbGeometryAPI may sit on the gprim or an ancestor
        while q and not q.IsPseudoRoot():
            if q.HasAPI("StbGeometryAPI") and q.GetAttribute("stb:dynamic").HasAuthoredValue():
                dynamic = q.GetAttribute("stb:dynamic").Get()
                break
            q = q.GetParent()
        assert dynamic is True, f"{mesh.GetPath()} not marked stb:dynamic"
    # the visible shell fits inside the light (a capture's near plane at r skips it)
    r = light.GetAttribute("inputs:radius").Get()
    for mesh in meshes:
        pts = np.array(UsdGeom.Mesh(mesh).GetPointsAttr().Get())
        assert np.linalg.norm(pts, axis=1).max() < r


def test_prefab_library_in_sync():
    from tools import gen_prefab_library

    stale = [
        p
        for p, text in gen_prefab_library.outputs().items()
        if p.read_text(encoding="utf-8") != text
    ]
    assert not stale, f"regenerate with tools/gen_prefab_library.py: {stale}"


# --------------------------------------------------------------------------------------
# default scene
# --------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def default_stage() -> Usd.Stage:
    return Usd.Stage.Open(str(DEFAULT))


def test_default_scene_inventory(default_stage: Usd.Stage):
    stage = default_stage
    lights = lights_of(stage)
    kinds = Counter(p.GetTypeName() for p in lights)
    assert 30 <= len(lights) <= 60, kinds
    assert kinds["DistantLight"] == 1 and kinds["DomeLight"] == 1, kinds
    assert len(kinds) >= 4, f"mixed light types expected: {kinds}"
    assert sum(p.IsInstanceProxy() for p in lights) >= 20, "lights should come from instances"
    # the sun/moon: normalised lux, low and dim
    moon = next(p for p in lights if p.IsA(UsdLux.DistantLight))
    assert UsdLux.LightAPI(moon).GetNormalizeAttr().Get()
    assert 0.1 <= UsdLux.LightAPI(moon).GetIntensityAttr().Get() <= 20
    dome = next(p for p in lights if p.IsA(UsdLux.DomeLight))
    assert UsdLux.LightAPI(dome).GetIntensityAttr().Get() <= 5
    # instanceable prefab references
    instances = [p for p in stage.Traverse() if p.IsInstance()]
    assert len(instances) >= 20 and stage.GetPrototypes()


def test_default_scene_animation(default_stage: Usd.Stage):
    stage = default_stage
    assert stage.GetTimeCodesPerSecond() == 24
    t0, t1 = stage.GetStartTimeCode(), stage.GetEndTimeCode()
    assert t1 > t0
    times = list(np.linspace(t0, t1, 7))
    lights = lights_of(stage)
    moving = [p for p in lights if transform_varies(p, times)]
    assert len(moving) >= 3, [str(p.GetPath()) for p in moving]
    varying_attr = [
        p
        for p in lights
        if any(
            a.ValueMightBeTimeVarying()
            for a in p.GetAttributes()
            if a.GetName().startswith("inputs:")
        )
    ]
    assert varying_attr, "expected at least one flickering light"
    torch = Usd.Stage.Open(str(SCENES / "prefabs" / "wall_torch.usda"))
    nominal = torch.GetPrimAtPath("/WallTorch/Light").GetAttribute("inputs:intensity").Get()
    for p in varying_attr:  # flicker stays near the prefab's nominal intensity
        attr = p.GetAttribute("inputs:intensity")
        values = [attr.Get(t) for t in attr.GetTimeSamples()]
        assert 0.6 * nominal <= min(values) and max(values) <= 1.4 * nominal, values


def test_default_scene_orbs_and_shadow_modes(default_stage: Usd.Stage):
    lights = lights_of(default_stage)
    modes = Counter()
    for p in lights:
        if p.IsA(UsdLux.DomeLight):
            continue
        shadowed = UsdLux.ShadowAPI(p).GetShadowEnableAttr().Get()
        mode = p.GetAttribute("stb:shadow:update").Get() if p.HasAPI("StbLightAPI") else "static"
        modes["off" if not shadowed else mode] += 1
    assert modes["dynamic"] >= 3 and modes["static"] >= 10 and modes["off"] >= 1, modes
    orbs = [p for p in lights if "Orb" in str(p.GetPath())]
    assert len(orbs) >= 3
    assert all(p.GetAttribute("stb:shadow:update").Get() == "dynamic" for p in orbs)


def test_default_scene_camera_and_budget(default_stage: Usd.Stage):
    stage = default_stage
    prim = stage.GetPrimAtPath("/Camera")
    assert prim.IsA(UsdGeom.Camera)
    cam = UsdGeom.Camera(prim)
    ratio = cam.GetHorizontalApertureAttr().Get() / cam.GetVerticalApertureAttr().Get()
    assert 1.6 <= ratio <= 1.9
    scale = cam.ComputeLinearExposureScale()
    assert 2.0**-6 <= scale <= 0.5, scale
    # a 25 % albedo surface at 5 lx and a 50 % one at 40 lx bracket 0.1 .. 1.0
    assert scale * 0.25 * 5 / math.pi < 0.1 < scale * 0.5 * 40 / math.pi <= 1.5
    # the camera sees the courtyard centre
    gc = cam.GetCamera(Usd.TimeCode(stage.GetStartTimeCode()))
    ndc = (gc.frustum.ComputeViewMatrix() * gc.frustum.ComputeProjectionMatrix()).Transform(
        Gf.Vec3d(0, 0, 0)
    )
    assert abs(ndc[0]) < 0.6 and abs(ndc[1]) < 0.6
    tris = sum(
        sum(c - 2 for c in UsdGeom.Mesh(p).GetFaceVertexCountsAttr().Get())
        for p in Usd.PrimRange.Stage(stage, Usd.TraverseInstanceProxies())
        if p.IsA(UsdGeom.Mesh)
    )
    assert tris < 50_000, tris


# --------------------------------------------------------------------------------------
# IES profiles
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize("path", IES_FILES, ids=lambda p: p.name)
def test_ies_file_is_valid_lm63(path: Path):
    d = read_ies(path)
    for kw in ("TEST", "TESTLAB", "ISSUEDATE", "MANUFAC"):
        assert kw in d["keywords"], f"{path.name}: [{kw}] missing"
    assert "synthetic" in " ".join(d["keywords"]["MANUFAC"]).lower()
    assert "stb_hydra" in " ".join(d["keywords"]["TESTLAB"] + d["keywords"]["MANUFAC"])
    assert d["ptype"] == 1 and d["units"] == 2 and d["lamps"] == 1
    v, h = d["v"], d["h"]
    assert np.all(np.diff(v) > 0) and np.all(np.diff(h) > 0)
    assert (v[0], v[-1]) in ((0, 90), (90, 180), (0, 180))
    assert h[0] == 0 and h[-1] in (0, 90, 180, 360)
    assert np.all(d["cd"] >= 0) and d["cd"].max() > 0
    assert 800 <= d["lumens"] <= 6000
    assert abs(ies_flux(v, h, d["cd"]) / d["lumens"] - 1) < 0.03, "candela do not sum to lumens"
    assert d["size"] < 8192
    assert max(len(line) for line in path.read_text().splitlines()) <= 256


def test_ies_shapes():
    street = read_ies(SCENES / "ies" / "streetlamp_typeII.ies")
    assert (street["v"][-1], street["h"][-1]) == (90, 180)
    cd = street["cd"]
    assert cd[0].max() > 1.3 * cd[-1].max(), "street side must out-throw the house side"
    assert street["v"][np.argmax(cd.max(axis=0))] >= 55, "Type II peaks at high angles"
    down = read_ies(SCENES / "ies" / "downlight_narrow.ies")
    half = np.interp(down["cd"][0].max() / 2, down["cd"][0][::-1], down["v"][::-1])
    assert 20 <= 2 * half <= 30, f"beam {2 * half:.1f} deg, want ~25"
    up = read_ies(SCENES / "ies" / "uplight.ies")
    assert up["v"][0] == 90 and up["v"][-1] == 180
    assert up["cd"][0][-1] == up["cd"].max()


def test_ies_profiles_in_sync():
    from tools import make_ies_profiles

    assert make_ies_profiles.main(["--check"]) == 0


def test_ies_files_parse_with_project_parser():
    try:
        from stb_hydra.scene.ies import load_ies
    except ImportError:
        pytest.skip("stb_hydra.scene.ies not available yet")
    for path in IES_FILES:
        profile = load_ies(path)
        assert profile is not None, path.name


# --------------------------------------------------------------------------------------
# generators
# --------------------------------------------------------------------------------------


@pytest.mark.parametrize("tool", TOOLS)
def test_generator_cli_help(tool: str):
    r = subprocess.run(
        [sys.executable, str(REPO / "tools" / f"{tool}.py"), "--help"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert r.returncode == 0, r.stderr
    assert "usage" in r.stdout.lower()


@pytest.mark.parametrize("module", ["lights", "chess", "orbs"])
def test_generator_module_cli_help(module: str):
    r = subprocess.run(
        [sys.executable, "-m", f"stb_hydra.scenegen.{module}", "--help"],
        capture_output=True,
        text=True,
        timeout=60,
        cwd=Path.home(),
    )
    assert r.returncode == 0, r.stderr
    assert "usage" in r.stdout.lower()


def test_packaged_inputs_are_the_checkouts():
    """The package's IES profiles and orb prefabs (``stb_hydra/data``, what an installed
    wheel has) are byte for byte the checkout's usd_scenes copies."""
    from stb_hydra.scenegen.common import package_data_dir

    ies = package_data_dir("ies")
    assert {p.name for p in ies.glob("*.ies")} == {p.name for p in IES_FILES}
    for f in IES_FILES:
        assert (ies / f.name).read_bytes() == f.read_bytes(), f.name
    pre = package_data_dir("prefabs")
    assert {p.name for p in pre.glob("*.usda")} == {"enemy_orb.usda", "wall_torch.usda"}
    for p in pre.glob("*.usda"):
        assert p.read_bytes() == (SCENES / "prefabs" / p.name).read_bytes(), p.name


def test_generator_inputs_without_a_checkout(tmp_path: Path, monkeypatch, testdata: Path, capsys):
    """Installed (no checkout around the package, no $STB_SHARED): the IES profiles and
    the orbs' prefabs come from the package data, so ``gen:lights`` and ``gen:orbs`` need
    no argument; an explicit folder names the same files; the chess set says what to
    pass."""
    from stb_hydra.scenegen import chess, common, lights, orbs

    packaged = lights.lights_scene_usda(8, seed=1, types="ies,sphere", anchor_dir=tmp_path)
    monkeypatch.setattr(common, "CHECKOUT", tmp_path / "site-packages")
    monkeypatch.delenv("STB_SHARED", raising=False)
    assert "SphereLight" in lights.lights_scene_usda(8, types="sphere,disk")
    text = lights.lights_scene_usda(8, seed=1, types="ies,sphere", anchor_dir=tmp_path)
    assert text == packaged and ".ies@" in text
    ies = common.package_data_dir("ies")
    assert common.ies_dir() == ies and common.prefab_dir() == common.package_data_dir("prefabs")
    # An explicit folder with the same files gives the same scene but for the paths.
    explicit = lights.lights_scene_usda(8, seed=1, types="ies,sphere", ies_dir=SCENES / "ies")
    assert explicit.replace(str((SCENES / "ies").resolve()), str(ies)) == lights.lights_scene_usda(
        8, seed=1, types="ies,sphere"
    )
    with pytest.raises(FileNotFoundError, match="IES profiles folder not found"):
        lights.lights_scene_usda(8, types="ies", ies_dir=tmp_path / "nosuch")
    assert "Orb_0003" in orbs.orbs_scene_usda(4, 24)
    with pytest.raises(FileNotFoundError, match=r"--chess.*\$STB_SHARED"):
        chess.chess_scene_usda(4)
    chess_usda = testdata / "scenes" / "OpenChessSet" / "chess_set.usda"
    assert chess.chess_set(chess_usda) == chess_usda.resolve()
    with pytest.raises(FileNotFoundError, match="chess set not found"):
        chess.chess_set(tmp_path / "nosuch.usda")
    monkeypatch.setenv("STB_SHARED", str(tmp_path))
    with pytest.raises(FileNotFoundError, match=r"from \$STB_SHARED"):
        chess.chess_set()
    monkeypatch.setenv("STB_SHARED", str(testdata.parent))
    assert chess.chess_set() == chess_usda.resolve()


@pytest.mark.parametrize("n", [50, 10_000])
def test_gen_lights_counts_and_speed(n: int):
    from stb_hydra.scenegen.lights import build_lights_stage

    m = max(3, n // 100)
    t = time.perf_counter()
    stage = build_lights_stage(
        n_lights=n, seed=5, animated=m, shadow_fraction=0.3, dynamic_fraction=0.5
    )
    elapsed = time.perf_counter() - t
    assert elapsed < GEN_SECONDS, f"{n} lights took {elapsed:.1f} s"
    assert stage.GetCompositionErrors() == []
    lights = lights_of(stage)
    assert len(lights) == n
    anim = [p for p in lights if UsdGeom.Xformable(p).TransformMightBeTimeVarying()]
    assert len(anim) == m
    assert transform_varies(anim[0], [1, 12, 24])
    kinds = Counter(p.GetTypeName() for p in lights)
    shadowed = sum(bool(UsdLux.ShadowAPI(p).GetShadowEnableAttr().Get()) for p in lights)
    dynamic = sum(
        p.GetAttribute("stb:shadow:update").Get() == "dynamic"
        for p in lights
        if p.HasAPI("StbLightAPI")
    )
    assert 0 < dynamic < shadowed < n
    if n >= 10_000:
        assert set(kinds) == {"SphereLight", "DiskLight", "RectLight"}
        assert abs(shadowed / n - 0.3) < 0.03
        ies = [p for p in lights if p.GetAttribute("inputs:shaping:ies:file").Get()]
        assert ies and all(
            p.GetAttribute("inputs:shaping:ies:file").Get().resolvedPath for p in ies[:50]
        )
    heights = [world_translation(p, 1)[1] for p in lights[:200]]
    assert min(heights) >= 0.3 and max(heights) <= 3.5
    assert stage.GetPrimAtPath("/Camera").IsA(UsdGeom.Camera)
    assert any(p.IsA(UsdGeom.Mesh) for p in stage.Traverse())


def test_gen_point_lights_are_the_spheres_as_points():
    """``--types point``: SphereLights with ``treatAsPoint``, the same draws and nits as
    ``--types sphere`` (one type each, same seed), so the same candela (UsdLux:
    I = L pi r^2, the radius kept) with no extent; not in the default mix."""
    from stb_hydra.scene.lights import LightReadContext, area_half_extent, read_light
    from stb_hydra.scenegen.lights import ALL_TYPES, build_lights_stage

    assert "point" not in ALL_TYPES

    def read(types: str):
        stage = build_lights_stage(n_lights=30, seed=4, types=types)
        ctx = LightReadContext(stage, np.eye(4), lambda m: None, lambda k, m: None)
        t = Usd.TimeCode.Default()
        return [read_light(p, ctx, t, np.eye(4)) for p in lights_of(stage)]

    spheres, points = read("sphere"), read("point")
    assert len(points) == 30
    for s, p in zip(spheres, points, strict=True):
        assert p.treat_as_point and not s.treat_as_point and p.valid
        assert area_half_extent(p) == 0.0 < area_half_extent(s)
        np.testing.assert_allclose(p.intensity, s.intensity, rtol=1e-6)
        assert p.intensity.max() > 0.0


def test_gen_lights_deterministic(tmp_path: Path):
    from stb_hydra.scenegen import lights as gen_lights_scene

    a = gen_lights_scene.lights_scene_usda(500, seed=11, animated=20)
    b = gen_lights_scene.lights_scene_usda(500, seed=11, animated=20)
    c = gen_lights_scene.lights_scene_usda(500, seed=12, animated=20)
    assert a == b and a != c
    out1, out2 = tmp_path / "a" / "s.usda", tmp_path / "b" / "s.usda"
    assert (
        gen_lights_scene.main(
            [
                str(out1),
                "--lights",
                "300",
                "--seed",
                "3",
                "--animated",
                "10",
                "--types",
                "sphere,ies",
            ]
        )
        == 0
    )
    assert (
        gen_lights_scene.main(
            [
                str(out2),
                "--lights",
                "300",
                "--seed",
                "3",
                "--animated",
                "10",
                "--types",
                "sphere,ies",
            ]
        )
        == 0
    )
    assert out1.read_bytes() == out2.read_bytes()
    stage = Usd.Stage.Open(str(out1))
    assert stage.GetCompositionErrors() == []
    assert UsdUtils.ComputeAllDependencies(str(out1))[2] == []
    assert len(lights_of(stage)) == 300
    assert {p.GetTypeName() for p in lights_of(stage)} == {"SphereLight"}


def test_gen_lights_usdc(tmp_path: Path):
    from stb_hydra.scenegen.lights import build_lights_stage

    stage = build_lights_stage(n_lights=50, seed=1, animated=5, path=tmp_path / "l.usdc")
    assert stage.GetRootLayer().GetFileFormat().formatId == "usdc"
    assert len(lights_of(stage)) == 50
    assert stage.GetCompositionErrors() == []


@pytest.mark.parametrize("n", [50, 10_000])
def test_gen_chess_lights(tmp_path: Path, n: int):
    from stb_hydra.scenegen import chess as gen_chess_lights

    out = tmp_path / "chess" / f"chess_{n}.usda"
    t = time.perf_counter()
    assert gen_chess_lights.main([str(out), "--lights", str(n), "--seed", "2"]) == 0
    assert time.perf_counter() - t < GEN_SECONDS
    stage = Usd.Stage.Open(str(out))
    other = [str(e) for e in stage.GetCompositionErrors() if ".mtlx" not in str(e)]
    assert other == [], other  # usd-core cannot read the asset's MaterialX, nothing else
    ref = stage.GetPrimAtPath("/World/ChessSet")
    assert ref.HasAuthoredReferences()
    assert not Path(ref.GetMetadata("references").prependedItems[0].assetPath).is_absolute()
    meshes = [p for p in Usd.PrimRange(ref, Usd.TraverseInstanceProxies()) if p.IsA(UsdGeom.Mesh)]
    assert len(meshes) >= 20, "chess set did not resolve"
    assert stage.GetPrimAtPath("/World/ChessSet/White/Pawns").IsA(UsdGeom.PointInstancer)
    lights = lights_of(stage)
    assert len(lights) == n
    pos = np.array([world_translation(p, Usd.TimeCode.Default()) for p in lights[:500]])
    assert np.abs(pos[:, [0, 2]]).max() < 0.36
    assert pos[:, 1].min() >= 0.018 + 0.019 and pos[:, 1].max() <= 0.018 + 0.201
    radii = [p.GetAttribute("inputs:radius").Get() for p in lights]
    assert 0.001 <= min(radii) and max(radii) <= 0.03
    assert all(UsdLux.ShadowAPI(p).GetShadowEnableAttr().Get() for p in lights[:200])
    # no light inside a piece
    pieces, _top = gen_chess_lights.piece_bounds(gen_chess_lights.chess_set())
    inside = np.zeros(len(pos), bool)
    for b in pieces:
        inside |= np.all((pos > b[:3]) & (pos < b[3:]), axis=1)
    assert not inside.any()
    # The asset's own MaterialX looks: the scene index binds a textured material.
    from stb_hydra.scene.stage_scene_index import StageSceneIndex

    index = StageSceneIndex(stage)
    mesh = next(p for p in meshes if "/White/King/" in str(p.GetPath()))
    mpath = index.get_prim(str(mesh.GetPath())).data_source.material()
    mat = index.material_record(mpath)
    assert mat is not None and mat.source == "MaterialX" and "diffuseColor" in mat.textures
    index.close()
    # --fallback-materials: untextured looks that ComputeBoundMaterial finds.
    fb = tmp_path / "chess" / f"chess_{n}_fallback.usda"
    assert (
        gen_chess_lights.main([str(fb), "--lights", str(n), "--seed", "2", "--fallback-materials"])
        == 0
    )
    fstage = Usd.Stage.Open(str(fb))
    fmesh = fstage.GetPrimAtPath(mesh.GetPath())
    fmat, _ = UsdShade.MaterialBindingAPI(fmesh).ComputeBoundMaterial()
    assert fmat and fmat.GetPath() == Sdf.Path("/World/Looks/Ivory")
    if n == 50:
        text1 = out.read_text()
        assert gen_chess_lights.main([str(out), "--lights", str(n), "--seed", "2"]) == 0
        assert out.read_text() == text1


@pytest.mark.parametrize("n", [50, 200])
def test_gen_orbs_spawn_over_time(tmp_path: Path, n: int):
    from stb_hydra.scenegen import orbs as gen_orbs

    out = tmp_path / "orbs.usda"
    t = time.perf_counter()
    assert gen_orbs.main([str(out), "--orbs", str(n), "--frames", "240", "--seed", "4"]) == 0
    assert time.perf_counter() - t < GEN_SECONDS
    text = out.read_text()
    assert gen_orbs.orbs_scene_usda(n, 240, 4, anchor_dir=out.parent) == text
    stage = Usd.Stage.Open(str(out))
    assert stage.GetCompositionErrors() == []
    assert UsdUtils.ComputeAllDependencies(str(out))[2] == []
    orbs = stage.GetPrimAtPath("/World/Lights/Orbs").GetChildren()
    assert len(orbs) == n and all(p.IsInstance() for p in orbs)

    def alive(f: float) -> int:
        return sum(
            UsdGeom.Imageable(p).ComputeVisibility(Usd.TimeCode(f)) != "invisible" for p in orbs
        )

    counts = [alive(f) for f in (1, 60, 120, 180, 240)]
    assert counts == sorted(counts) and counts[0] < n / 4 and counts[-1] == n, counts
    orb_lights = [p for p in lights_of(stage) if "/Orbs/" in str(p.GetPath())]
    assert len(orb_lights) == n
    assert all(p.GetAttribute("stb:shadow:update").Get() == "dynamic" for p in orb_lights)
    assert sum(transform_varies(p, [120, 180, 240]) for p in orb_lights) >= n * 0.9
