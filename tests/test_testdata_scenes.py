"""The real UsdLux scenes in ../shared/testdata/usd open and inspect without
exceptions, with the lights their MANIFEST.md says they hold."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from stb_hydra.apps.common import open_stage
from stb_hydra.apps.inspect import inspect_stage

# (file under testdata/usd, expected light counts by type) from usd/MANIFEST.md
EXPECTED = [
    ("luxtest/usd/sphere.usda", {"sphereLight": 1}),
    ("luxtest/usd/disk.usda", {"diskLight": 1}),
    ("luxtest/usd/rect.usda", {"rectLight": 1}),
    ("luxtest/usd/cylinder.usda", {"cylinderLight": 1}),
    ("luxtest/usd/distant.usda", {"distantLight": 1}),
    ("luxtest/usd/dome.usda", {"domeLight": 1}),
    ("luxtest/usd/visibleRect.usda", {"rectLight": 1}),
    ("luxtest/usd/iesTest.usda", {"sphereLight": 1}),
    ("luxtest/usd/ies_scale.usda", {"sphereLight": 1}),
    ("luxtest/usd/test/embree_test_01.usda", {"cylinderLight": 1}),
    ("arnold-usd/test_0139/data/test.usda", {"sphereLight": 1}),
    ("arnold-usd/test_0140/data/test.usda", {"sphereLight": 1}),
    ("arnold-usd/test_1316/data/test.usda", {"sphereLight": 1}),
    ("arnold-usd/test_2477.1/data/test.usda", {"sphereLight": 1}),
    ("arnold-usd/test_0193/data/scene.usda", {"sphereLight": 2}),
    ("arnold-usd/test_0047/data/scene.usda", {"sphereLight": 4, "domeLight": 1}),
    (
        "arnold-usd/test_1939/data/scene.usda",
        {
            "domeLight": 1,
            "distantLight": 1,
            "diskLight": 1,
            "cylinderLight": 1,
            "rectLight": 1,
            "sphereLight": 1,
        },
    ),
    ("arnold-usd/test_2439.13/data/test.usda", {"meshLight": 1}),
    ("openusd/usd/usdLux/testenv/testUsdLuxLinkingAPI/linking_example.usda", {"sphereLight": 8}),
    (
        "openusd/usd/usdLux/testenv/testUsdLuxLightListAPI/root.usda",
        {"domeLight": 1, "sphereLight": 2},
    ),
    (
        "openusd/usd/usdLux/testenv/testUsdLuxLightListAPI/root_with_instances.usda",
        {"domeLight": 1, "sphereLight": 2},
    ),
    (
        "openusd/usdImaging/usdImagingGL/testenv/testUsdImagingGLMaterialXBasic/mxLights.usda",
        {"distantLight": 2, "diskLight": 1},
    ),
    (
        "usd-wg/test_assets/NormalsTextureBiasAndScale/NormalsTextureBiasAndScale.usda",
        {"distantLight": 4},
    ),
    (
        "usd-wg/test_assets/RelationshipEncapsulationTests/utils/Environment.usda",
        {"sphereLight": 3},
    ),
]


@pytest.mark.parametrize(("rel", "expected"), EXPECTED, ids=[e[0] for e in EXPECTED])
def test_scene_lights_match_manifest(testdata, rel, expected):
    rep = inspect_stage(open_stage(testdata / "usd" / rel))
    got: dict[str, int] = {}
    for lr in rep["lights"]:
        got[lr["type"]] = got.get(lr["type"], 0) + 1
    assert got == expected
    json.dumps(rep, allow_nan=False)  # JSON-clean: no NaN/Inf anywhere


def test_instanced_torches_are_found_through_instance_proxies(testdata):
    rep = inspect_stage(
        open_stage(
            testdata
            / "usd/openusd/usd/usdLux/testenv/testUsdLuxLightListAPI/root_with_instances.usda"
        )
    )
    paths = {lr["path"] for lr in rep["lights"]}
    assert "/World/Geo/torch_1/light" in paths and "/World/Geo/torch_2/light" in paths


def test_legacy_attributes_warned(testdata):
    rep = inspect_stage(
        open_stage(
            testdata
            / "usd/usd-wg/test_assets/NormalsTextureBiasAndScale/NormalsTextureBiasAndScale.usda"
        )
    )
    assert any("legacy" in w for w in rep["warnings"])


def test_shadow_schema_attributes(testdata):
    rep = inspect_stage(open_stage(testdata / "usd/arnold-usd/test_0193/data/scene.usda"))
    shadows = sorted((lr["shadow"]["enable"], tuple(lr["shadow"]["color"])) for lr in rep["lights"])
    assert shadows == [(False, (0.0, 0.0, 0.0)), (True, (1.0, 0.0, 0.0))]


def test_missing_ies_file_is_a_warning_not_an_error(testdata):
    # test_2477.1 at frame 50 references ../ies/bega_omni002_4777lm.ies, which does not exist there
    rep = inspect_stage(open_stage(testdata / "usd/arnold-usd/test_2477.1/data/test.usda"), 50.0)
    (lr,) = rep["lights"]
    assert lr["ies"] is not None and not lr["ies"]["resolved"]
    assert any("not found" in w and "bega_omni002" in w for w in rep["warnings"])


def test_inspect_cli_json(testdata, tmp_path):
    scene = testdata / "usd/arnold-usd/test_1939/data/scene.usda"
    out = subprocess.run(
        [sys.executable, "-m", "stb_hydra.apps.cli", "inspect", str(scene), "--json"],
        capture_output=True,
        text=True,
        check=True,
    )
    rep = json.loads(out.stdout)
    assert set(rep) >= {"prims", "lights", "warnings"}
    for lr in rep["lights"]:
        assert set(lr) >= {"path", "type", "position", "direction", "intensity", "flux"}
        assert len(lr["position"]) == 3 and len(lr["intensity"]) == 3


def test_inspect_cli_bad_stage_exit_code(tmp_path):
    bad = tmp_path / "bad.usda"
    bad.write_text("this is not usd")
    out = subprocess.run(
        [sys.executable, "-m", "stb_hydra.apps.cli", "inspect", str(bad)],
        capture_output=True,
        text=True,
    )
    assert out.returncode == 2
    err = out.stderr.strip().splitlines()
    assert len(err) == 1 and "bad.usda" in err[0]
