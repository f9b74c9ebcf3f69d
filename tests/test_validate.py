"""``stb validate``: our UsdValidation validators on a planted prefab library, on the
real scenes of ../shared/testdata/usd, through a plain ValidationContext, and the CLI
(exit codes, JSON schema, --jobs parity, crash isolation)."""

from __future__ import annotations

import importlib.util
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from pxr import Sdf, Usd, UsdValidation
from validate_fixtures import build_library

import stb_hydra.validate  # registers the stb validators
from stb_hydra.apps import cli
from stb_hydra.validate.asset_paths import LIBRARY_ROOT_ENV
from stb_hydra.validate.common import CRASH_HOOK_ENV
from stb_hydra.validate.findings import PLUGIN_NAME, RULES, SEVERITIES
from stb_hydra.validate.runner import Selection, validate_in_process
from stb_hydra.validate.synth import clean_prefab

HAS_API = importlib.util.find_spec("stb_hydra.api") is not None


def _stb(rep) -> set[tuple[str, str]]:
    """(rule, prim) of the stb and runner findings (built-in ids contain a ':')."""
    return {(f.rule, f.prim) for f in rep.findings if ":" not in f.rule}


def _builtin(rep) -> list[str]:
    return [f.rule for f in rep.findings if ":" in f.rule]


@pytest.fixture(scope="module")
def library(tmp_path_factory, testdata):
    root = tmp_path_factory.mktemp("validate")
    lib = root / "lib"
    expected = build_library(lib, testdata / "ies")
    # Real content just outside the library root: an escaping reference must not open it.
    (root / "outside.usda").write_text('#usda 1.0\ndef Xform "Outside"\n{\n}\n')
    return lib, expected


@pytest.fixture(scope="module")
def selection():
    return Selection.parse(None)


# --- planted library, in process ------------------------------------------------------


def test_planted_library_each_rule_fires_where_planted(library, selection):
    lib, expected = library
    problems = []
    for rel, exp in sorted(expected.items()):
        rep = validate_in_process(str(lib / rel), str(lib), selection, False)
        got = _stb(rep)
        if got != exp.stb:
            problems.append(f"{rel}: stb findings {sorted(got)} != expected {sorted(exp.stb)}")
        stray = [b for b in _builtin(rep) if not b.startswith(exp.builtin or ("\0",))]
        missing = [p for p in exp.builtin if not any(b.startswith(p) for b in _builtin(rep))]
        if stray or missing:
            problems.append(f"{rel}: built-in findings {stray} unexpected, {missing} missing")
        if rep.opened != exp.opened:
            problems.append(f"{rel}: opened={rep.opened}, expected {exp.opened}")
        for f in rep.findings:
            if f.rule in RULES and not (f.message and f.hint and f.severity in SEVERITIES):
                problems.append(f"{rel}: incomplete finding {f}")
    assert not problems, "\n".join(problems)


def test_every_stb_rule_has_a_planted_case(library):
    _, expected = library
    planted = {rule for exp in expected.values() for rule, _ in exp.stb}
    assert set(RULES) <= planted, f"rules never planted: {sorted(set(RULES) - planted)}"


def test_clean_prefab_gives_no_findings_at_all(library, selection):
    lib, _ = library
    rep = validate_in_process(str(lib / "prefabs" / "clean.usda"), str(lib), selection, False)
    assert rep.findings == [] and rep.status == "ok" and rep.opened
    assert rep.stats == {"lights": 4, "meshes": 2}


def test_unsafe_asset_is_not_opened(library, selection):
    lib, _ = library
    outside = str((lib.parent / "outside.usda").resolve())
    assert Sdf.Layer.Find(outside) is None
    rep = validate_in_process(
        str(lib / "prefabs" / "unsafe_escape.usda"), str(lib), selection, False
    )
    assert not rep.opened
    assert [f.rule for f in rep.findings] == ["asset_path_unsafe"]
    assert "escapes the library root" in rep.findings[0].message
    assert Sdf.Layer.Find(outside) is None, "a layer outside the library root was opened"
    # The same file is fine when the library root includes the outside file.
    rep2 = validate_in_process(
        str(lib / "prefabs" / "unsafe_escape.usda"), str(lib.parent), selection, False
    )
    assert rep2.opened and ("intensity_invalid", "/Prefab/Lights/L1") in _stb(rep2)


def test_rule_selection(library):
    lib, _ = library
    path = str(lib / "prefabs" / "stb_overlap.usda")
    only = validate_in_process(path, str(lib), Selection.parse(["stb_overlap"]), False)
    assert {f.rule for f in only.findings} == {"stb_overlap"}
    usd = validate_in_process(
        str(lib / "prefabs" / "ies_missing.usda"), str(lib), Selection.parse(["usd"]), False
    )
    assert usd.findings and all(":" in f.rule for f in usd.findings)
    assert Selection.parse(["LightValues"]).validators == [f"{PLUGIN_NAME}:LightValues"]


# --- real scenes (MANIFEST predictions) -----------------------------------------------


def _validate_real(testdata, rel: str, root: str | None = None):
    path = testdata / "usd" / rel
    return validate_in_process(
        str(path), str(testdata / "usd" / (root or "")), Selection.parse(None), False
    )


def test_real_missing_time_sampled_ies(testdata):
    rep = _validate_real(
        testdata, "arnold-usd/test_2477.1/data/test.usda", "arnold-usd/test_2477.1"
    )
    f = [x for x in rep.findings if x.rule == "ies_missing"]
    assert [x.prim for x in f] == ["/lights/sphere_light"]
    # Found through the time samples: the default value is @@ and frame 59 resolves.
    assert "bega_omni002_4777lm.ies" in f[0].message and "times 46-58, 60-63" in f[0].message
    assert any(r.startswith("usdUtilsValidators:MissingReferenceValidator") for r in _builtin(rep))


def test_real_legacy_attribute_names(testdata):
    rel = "usd-wg/test_assets/NormalsTextureBiasAndScale/NormalsTextureBiasAndScale.usda"
    rep = _validate_real(testdata, rel, "usd-wg")
    legacy = {x.prim: x.message for x in rep.findings if x.rule == "legacy_attribute"}
    base = "/NormalsTextureBiasAndScale/Lights/"
    assert set(legacy) == {
        base + n for n in ("LightFromAbove", "LightFromLeft", "LightFromRight", "AngledLight")
    }
    assert all("'shaping:cone:angle' -> 'inputs:shaping:cone:angle'" in m for m in legacy.values())


def test_real_unresolvable_mtlx_reference(testdata):
    rel = "openusd/usdImaging/usdImagingGL/testenv/testUsdImagingGLMaterialXBasic/mxLights.usda"
    rep = _validate_real(testdata, rel, "openusd")
    comp = [x for x in rep.findings if x.rule.startswith("usdValidation:CompositionErrorTest")]
    assert comp and comp[0].prim == "/Materials/MaterialX" and ".mtlx" in comp[0].message
    assert rep.status == "error"


def test_real_lights_inside_instances(testdata):
    base = "openusd/usd/usdLux/testenv/testUsdLuxLightListAPI/"
    plain = _validate_real(testdata, base + "root.usda", "openusd")
    inst = _validate_real(testdata, base + "root_with_instances.usda", "openusd")
    torches = {"/World/Geo/torch_1/light", "/World/Geo/torch_2/light"}
    for rep in (plain, inst):
        assert {p for r, p in _stb(rep) if r == "legacy_attribute"} == torches
        assert {p for r, p in _stb(rep) if r == "units_mismatch"} == {
            "/World/Geo/torch_1",
            "/World/Geo/torch_2",
        }  # torch.usda is Z-up
    stage = Usd.Stage.Open(str(testdata / "usd" / base / "root_with_instances.usda"))
    assert all(stage.GetPrimAtPath(p).IsInstanceProxy() for p in torches)
    assert _stb(plain) == _stb(inst)


def test_real_angle_scale_sweep_and_time_sampled_ies(testdata):
    rep = _validate_real(testdata, "luxtest/usd/ies_scale.usda", "luxtest")
    f = [x for x in rep.findings if x.rule == "ies_angle_scale"]
    assert [x.prim for x in f] == ["/lights/ies_scale_light"] and "times 6-9" in f[0].message
    sphere = _validate_real(testdata, "luxtest/usd/sphere.usda", "luxtest")
    assert not [x for x in sphere.findings if x.rule.startswith("ies_")]  # @@ is not missing


def test_real_scenes_never_crash(testdata):
    sel = Selection.parse(None)
    for path in sorted((testdata / "usd").rglob("*.usda")):
        rep = validate_in_process(str(path), str(testdata / "usd"), sel, False)
        assert rep.status != "crash", (path, rep.findings)


# --- UsdValidation integration --------------------------------------------------------


def test_validators_registered_under_keyword_stb():
    reg = UsdValidation.ValidationRegistry()
    names = sorted(m.name for m in reg.GetValidatorMetadataForKeyword("stb"))
    assert names == sorted(
        f"{PLUGIN_NAME}:{v}"
        for v in (
            "LightValues",
            "IesProfile",
            "Photometry",
            "ShadowBudget",
            "StbNoiseRisk",
            "StageUnits",
            "AssetPaths",
            "StaticBake",
            "LightLinks",
        )
    )
    md = reg.GetValidatorMetadata(f"{PLUGIN_NAME}:LightValues")
    assert md.doc and list(md.GetSchemaTypes()) == ["UsdLuxLightAPI"]
    assert all(reg.HasValidator(n) for n in names)


def test_plain_validation_context_runs_our_validators(library, monkeypatch):
    lib, _ = library
    monkeypatch.setenv(LIBRARY_ROOT_ENV, str(lib))  # default: the root layer's directory
    stage = Usd.Stage.Open(str(lib / "scenes" / "instanced.usda"))
    errors = UsdValidation.ValidationContext(["stb"], True).Validate(stage)
    got = {(e.GetName(), str(e.GetSites()[0].GetPrim().GetPath()), e.GetType()) for e in errors}
    err = UsdValidation.ValidationErrorType.Error
    assert got == {
        ("intensity_invalid", "/Scene/TorchA/Light", err),
        ("intensity_invalid", "/Scene/TorchB/Light", err),
    }
    assert all(e.GetValidator().GetMetadata().name == f"{PLUGIN_NAME}:LightValues" for e in errors)


def test_plugin_loads_in_a_fresh_usd_process(library, repo):
    """A UsdValidation client that never imports stb_hydra finds the validators through
    plugInfo.json (PXR_PLUGINPATH_NAME) and Plug imports our module on demand."""
    lib, _ = library
    plugdir = Path(stb_hydra.validate.__file__).parent
    code = (
        "import sys\n"
        "from pxr import Usd, UsdValidation\n"
        "reg = UsdValidation.ValidationRegistry()\n"
        "assert 'stb_hydra' not in sys.modules\n"
        "names = [m.name for m in reg.GetValidatorMetadataForKeyword('stb')]\n"
        "stage = Usd.Stage.Open(sys.argv[1])\n"
        "errs = UsdValidation.ValidationContext(['stb'], True).Validate(stage)\n"
        "print(len(names), sorted({e.GetName() for e in errs}), 'stb_hydra' in sys.modules)\n"
    )
    env = dict(os.environ, PXR_PLUGINPATH_NAME=str(plugdir), PYTHONPATH=str(repo))
    out = subprocess.run(
        [sys.executable, "-c", code, str(lib / "prefabs" / "exposure.usda")],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "9 ['exposure_invalid'] True"


# --- CLI ------------------------------------------------------------------------------


def _cli(*argv: str) -> int:
    return cli.main(["validate", "--quiet", *argv])


def test_cli_exit_codes(tmp_path, library, capsys):
    lib, _ = library
    clean = clean_prefab(3).write(tmp_path / "clean" / "a.usda")
    assert _cli(str(clean), "--jobs", "0") == 0
    assert _cli(str(lib / "prefabs" / "exposure.usda"), "--jobs", "0") == 1
    # A warning-only asset: clean under --fail-on error, a failure under warning.
    warn = str(lib / "prefabs" / "focus.usda")
    assert _cli(warn, "--jobs", "0") == 0
    assert _cli(warn, "--jobs", "0", "--fail-on", "warning") == 1
    (tmp_path / "empty").mkdir()
    assert _cli(str(tmp_path / "empty")) == 2
    assert _cli(str(tmp_path / "nope.usda")) == 2
    assert _cli(str(clean), "--rules", "no_such_rule") == 2
    assert _cli(str(clean), "--jobs", "-1") == 2
    assert _cli(str(clean), "--json", str(tmp_path / "missing_dir" / "r.json")) == 2
    with pytest.raises(SystemExit) as exc:
        _cli(str(clean), "--fail-on", "info")
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "no USD files" in err and "unknown rule 'no_such_rule'" in err


def _json_run(tmp_path: Path, name: str, *argv: str) -> dict:
    out = tmp_path / f"{name}.json"
    code = _cli(*argv, "--json", str(out))
    doc = json.loads(out.read_text())
    doc["_exit"] = code
    return doc


def _findings_by_asset(doc: dict) -> dict:
    return {
        a["path"]: (
            a["status"],
            sorted((f["rule"], f["prim"], f["message"]) for f in a["findings"]),
        )
        for a in doc["assets"]
    }


def test_cli_json_schema_and_jobs_parity(tmp_path, library):
    lib, expected = library
    one = _json_run(tmp_path, "one", str(lib), "--jobs", "1")
    two = _json_run(tmp_path, "two", str(lib), "--jobs", "2")
    assert one["_exit"] == two["_exit"] == 1
    assert set(one) == {
        "schema",
        "tool",
        "stb_hydra",
        "usd",
        "fail_on",
        "rules",
        "summary",
        "assets",
        "_exit",
    }
    assert one["schema"] == 1 and one["fail_on"] == "error"
    assert len(one["assets"]) == len(expected)
    for a in one["assets"]:
        assert set(a) == {"path", "root", "status", "opened", "findings", "timings", "stats"}
        assert a["status"] in ("ok", "warning", "error", "crash")
        assert a["root"] == str(lib.resolve()) and a["timings"]["total"] >= 0
        for f in a["findings"]:
            assert set(f) == {"rule", "severity", "prim", "message", "hint", "validator"}
            assert f["severity"] in SEVERITIES
        rel = os.path.relpath(a["path"], a["root"])
        stb = {(f["rule"], f["prim"]) for f in a["findings"] if ":" not in f["rule"]}
        assert stb == expected[rel].stb, rel
    assert one["summary"]["assets"] == len(expected)
    assert _findings_by_asset(one) == _findings_by_asset(two)


def test_cli_crashing_assets_do_not_stop_the_run(tmp_path, monkeypatch):
    lib = tmp_path / "lib"
    for name in ("a_ok", "b_segv_me", "c_raise_me", "d_ok"):
        clean_prefab(2).write(lib / f"{name}.usda")
    monkeypatch.setenv(CRASH_HOOK_ENV, "segv:segv_me")
    doc = _json_run(tmp_path, "segv", str(lib), "--jobs", "2")
    by = {Path(a["path"]).stem: a for a in doc["assets"]}
    assert [f["rule"] for f in by["b_segv_me"]["findings"]] == ["crash"]
    assert "SIGSEGV" in by["b_segv_me"]["findings"][0]["message"]
    assert by["b_segv_me"]["status"] == "crash" and doc["_exit"] == 1
    assert all(by[n]["status"] == "ok" for n in ("a_ok", "c_raise_me", "d_ok"))
    monkeypatch.setenv(CRASH_HOOK_ENV, "raise:raise_me")
    doc = _json_run(tmp_path, "raise", str(lib), "--jobs", "1")
    by = {Path(a["path"]).stem: a for a in doc["assets"]}
    msgs = [f["message"] for f in by["c_raise_me"]["findings"] if f["rule"] == "crash"]
    assert msgs and all("RuntimeError: test crash hook" in m for m in msgs)
    assert all(by[n]["status"] == "ok" for n in ("a_ok", "b_segv_me", "d_ok"))


def test_cli_hanging_asset_times_out(tmp_path, monkeypatch):
    lib = tmp_path / "lib"
    for name in ("a_hang_me", "b_ok"):
        clean_prefab(2).write(lib / f"{name}.usda")
    monkeypatch.setenv(CRASH_HOOK_ENV, "hang:hang_me")
    doc = _json_run(tmp_path, "hang", str(lib), "--jobs", "1", "--timeout", "3")
    by = {Path(a["path"]).stem: a for a in doc["assets"]}
    assert by["a_hang_me"]["status"] == "crash"
    assert "timed out after 3 s" in by["a_hang_me"]["findings"][0]["message"]
    assert by["b_ok"]["status"] == "ok"


def test_cli_html_report(tmp_path, library):
    lib, _ = library
    sub = tmp_path / "lib"
    shutil.copytree(lib / "prefabs", sub)
    html = tmp_path / "report.html"
    assert _cli(str(sub), "--jobs", "0", "--html", str(html)) == 1
    text = html.read_text()
    assert text.count("<code>intensity_invalid</code>") == 2
    assert text.count("<tr><td><code>") == len(list(sub.glob("*.usda")))


@pytest.mark.skipif(not HAS_API, reason="stb_hydra.api (the render API) is not written yet")
def test_cli_html_thumbnails(tmp_path):
    lib = tmp_path / "lib"
    clean_prefab(3).write(lib / "a.usda")
    html = tmp_path / "thumbs.html"
    assert _cli(str(lib), "--jobs", "1", "--html", str(html), "--thumbnails") == 0
    assert html.read_text().count('src="data:image/png;base64,iVBORw0KGgo') == 1
