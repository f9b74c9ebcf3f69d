"""Packaging: the wheel built from this checkout installs into a fresh environment and
renders there, the shaders included (they live in the top-level ``shaders/`` and ship
as the package ``stb_hydra.shaders``).

The fresh environment is a venv without pip outside the checkout; the wheel is
installed into it with ``--no-deps``, then a ``.pth`` file puts this environment's
site-packages (numpy, usd-core, moderngl, ...) behind it, so nothing is downloaded.
A ``.pth`` path line does not run the ``.pth`` files of the directory it adds, so
the editable install of this checkout is not active there: ``stb_hydra`` can only
come from the wheel.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import zipfile
from importlib import metadata
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
SCENE = REPO / "usd_scenes" / "default.usda"
#: What a wheel is built from: the project's metadata and its two source trees.
SOURCES = ("pyproject.toml", "README.md", "stb_hydra", "shaders")
_IGNORE = shutil.ignore_patterns("__pycache__", "*.pyc", "*.egg-info")


def _setuptools_pyproject() -> dict:
    tomllib = pytest.importorskip("tomllib")  # Python 3.11+
    with open(REPO / "pyproject.toml", "rb") as f:
        return tomllib.load(f)["tool"]["setuptools"]


def _package_dirs() -> dict[str, Path]:
    """Every importable directory of the two source trees, by dotted package name
    (setuptools ships a directory's files only when its package is listed)."""
    roots = {"stb_hydra": REPO / "stb_hydra", "stb_hydra.shaders": REPO / "shaders"}
    out: dict[str, Path] = {}
    for name, root in roots.items():
        for d in [root, *sorted(p for p in root.rglob("*") if p.is_dir())]:
            rel = d.relative_to(root).parts
            if "__pycache__" in rel or not all(p.isidentifier() for p in rel):
                continue
            out[".".join((name, *rel))] = d
    return out


def test_package_list_covers_the_source_tree():
    cfg = _setuptools_pyproject()
    assert cfg["package-dir"] == {"stb_hydra.shaders": "shaders"}
    dirs = _package_dirs()
    listed = set(cfg["packages"])
    missing = sorted(set(dirs) - listed)
    assert not missing, f"add {missing} to [tool.setuptools] packages in pyproject.toml"
    assert not sorted(listed - set(dirs)), "pyproject.toml lists packages that do not exist"
    assert not (REPO / "stb_hydra" / "shaders").exists(), "shaders live in the top-level shaders/"


def _build_wheel(tmp: Path) -> Path:
    """Wheel of the working tree (copied, so no build/ or egg-info lands in the checkout
    and nothing stale of an earlier build can slip in)."""
    src = tmp / "src"
    src.mkdir()
    for name in SOURCES:
        p = REPO / name
        if p.is_dir():
            shutil.copytree(p, src / name, ignore=_IGNORE)
        else:
            shutil.copy2(p, src / name)
    cmd = [sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "-w", str(tmp / "dist")]
    try:
        setuptools_ok = int(metadata.version("setuptools").split(".")[0]) >= 77
    except metadata.PackageNotFoundError:
        setuptools_ok = False
    if setuptools_ok:  # build with this environment's setuptools: offline and fastest
        cmd += ["--no-build-isolation", "--no-index"]
    r = subprocess.run([*cmd, str(src)], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    (wheel,) = (tmp / "dist").glob("stb_hydra-*.whl")
    return wheel


def _venv_with_wheel(tmp: Path, wheel: Path) -> Path:
    venv = tmp / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    py = venv / "bin" / "python"
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "--python",
            str(py),
            "install",
            "-q",
            "--no-deps",
            "--no-index",
            "--no-compile",
            str(wheel),
        ],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stdout + r.stderr
    # Only now (so pip saw an empty environment) the dependencies of this environment.
    site = subprocess.run(
        [str(py), "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    Path(site, "_stb_test_deps.pth").write_text("".join(f"{p}\n" for p in _dependency_dirs()))
    return venv


def _dependency_dirs() -> list[str]:
    """This environment's site-packages directories (where the dependencies are)."""
    return [p for p in sys.path if Path(p).name in ("site-packages", "dist-packages")]


_CHILD = r"""
import json, sys
import numpy as np
import stb_hydra
from stb_hydra.renderer.gl import shader_root, shader_source
img = stb_hydra.render(sys.argv[1], width=64, height=36, lighting="stb")
print(json.dumps({
    "prefix": sys.prefix,
    "stb_hydra": stb_hydra.__file__,
    "shaders": str(shader_root()),
    "glsl": len(shader_source("common/lights.glsl")),
    "path": sys.path,
    "editable": sorted(m for m in sys.modules if "__editable__" in m)
                + [repr(f) for f in sys.meta_path if "Editable" in repr(f)],
    "shape": list(img.shape),
    "finite": bool(np.isfinite(img).all()),
    "max": float(img.max()),
    "mean": float(img.mean()),
}))
"""


def _inside(path: str | Path, root: Path) -> bool:
    return Path(path).resolve().is_relative_to(root.resolve())


@pytest.fixture(scope="module")
def wheel_env(tmp_path_factory):
    """(wheel, venv, run_dir, env): the wheel of this checkout installed into a fresh
    venv, a working folder outside the checkout and an environment without
    PYTHONPATH/PYTHONHOME (shared by this module's tests: one build, one install)."""
    tmp = tmp_path_factory.mktemp("wheel")
    wheel = _build_wheel(tmp)
    venv = _venv_with_wheel(tmp, wheel)
    run_dir = tmp / "run"
    run_dir.mkdir()
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    # Nothing of the checkout or the shared test data may be found by default.
    env.pop("STB_SHARED", None)
    env["STB_BAKE_CACHE"] = str(tmp / "bake_cache")
    return wheel, venv, run_dir, env


#: Package data a verb reads at run time: shaders, the schema, the validator plugin,
#: the LTC table, the STB patterns, the IES profiles and prefabs of the generators.
PACKAGE_DATA = (
    "shaders/__init__.py",
    "shaders/stb_bigtile.frag",
    "shaders/bake_light.frag",
    "shaders/common/lights.glsl",
    "data/quad_patterns.json",
    "data/ltc_ggx.npy",
    "data/ies/streetlamp_typeII.ies",
    "data/ies/downlight_narrow.ies",
    "data/ies/wallwash.ies",
    "data/ies/uplight.ies",
    "data/prefabs/enemy_orb.usda",
    "data/prefabs/wall_torch.usda",
    "scene/schema/plugInfo.json",
    "scene/schema/generatedSchema.usda",
    "validate/plugInfo.json",
)


@pytest.mark.slow
@pytest.mark.gl
def test_wheel_installs_and_renders_outside_the_checkout(wheel_env, gl_ctx):
    wheel, venv, run_dir, env = wheel_env
    names = set(zipfile.ZipFile(wheel).namelist())
    for f in PACKAGE_DATA:
        assert f"stb_hydra/{f}" in names, f

    r = subprocess.run(
        [str(venv / "bin" / "python"), "-c", _CHILD, str(SCENE)],
        cwd=run_dir,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stderr
    got = json.loads(r.stdout.strip().splitlines()[-1])
    assert _inside(got["prefix"], venv)
    assert _inside(got["stb_hydra"], venv) and not _inside(got["stb_hydra"], REPO)
    assert _inside(got["shaders"], venv) and got["glsl"] > 0
    assert got["editable"] == [], "the checkout's editable install is active"
    deps = {Path(p).resolve() for p in _dependency_dirs()}
    for p in got["path"]:
        if p and _inside(p, REPO):
            assert Path(p).resolve() in deps, f"the checkout is on sys.path: {p}"
    assert got["shape"] == [36, 64, 3] and got["finite"]
    assert got["max"] > 0.0 and got["mean"] > 0.0, "black image"

    # The console script of the new environment.
    out = run_dir / "default.png"
    r = subprocess.run(
        [
            str(venv / "bin" / "stb"),
            "render",
            str(SCENE),
            str(out),
            "--width",
            "64",
            "--height",
            "36",
            "--lighting",
            "stb",
        ],
        cwd=run_dir,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stdout + r.stderr
    from stb_hydra.io.images import read_image

    png, _ = read_image(out)
    assert png.shape[:2] == (36, 64)
    assert np.all(np.isfinite(png)) and float(png.max()) > 0.0, "black PNG"


#: A small static scene for the bake and preview examples: the Lambert floor, a
#: ``UsdGeom.Cube`` and one static sphere light.
_SMALL_LIGHT = """def Cube "Box"
{
    double size = 1
    double3 xformOp:translate = (0, 0.5, 0)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}
def SphereLight "L" (
    prepend apiSchemas = ["StbLightAPI"]
)
{
    float inputs:intensity = 3000
    float inputs:radius = 0.1
    uniform token stb:mobility = "static"
    double3 xformOp:translate = (1, 2, 0.5)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}
"""


def _stb(venv: Path, run_dir: Path, env: dict, *args: str, timeout: int = 300):
    r = subprocess.run(
        [str(venv / "bin" / "stb"), *args],
        cwd=run_dir,
        env=env,
        capture_output=True,
        text=True,
        timeout=timeout,
    )
    assert r.returncode == 0, f"stb {' '.join(args)}: {r.stdout[-2000:]}{r.stderr[-2000:]}"
    return r


@pytest.mark.slow
@pytest.mark.gl
def test_readme_examples_run_from_the_wheel(wheel_env, gl_ctx):
    """Every verb of the README, as its examples run it but at small sizes, from the
    wheel's console script outside the checkout: inspect, validate, bench with a
    generator (its IES profiles are package data: issue 35), tradeoff, bake (and a
    render of the baked layer), and preview --snapshot under Xvfb. ``render`` is the
    test above."""
    from stagegen import LAMBERT_FLOOR_USDA

    _wheel, venv, run, env = wheel_env
    scenes = REPO / "usd_scenes"

    r = _stb(venv, run, env, "inspect", str(SCENE), "--json")
    rep = json.loads(r.stdout)
    assert rep["lights"], "inspect found no lights"

    v = run / "validate.json"
    _stb(
        venv,
        run,
        env,
        "validate",
        str(scenes / "prefabs" / "street_lamp.usda"),
        "--library-root",
        str(scenes),
        "--json",
        str(v),
    )
    assert json.loads(v.read_text())

    b = run / "bench.json"
    _stb(
        venv,
        run,
        env,
        "bench",
        "gen:lights:20",
        "--methods",
        "stb,reference",
        "--size",
        "64x36",
        "--frames",
        "1",
        "--warmup",
        "0",
        "--json",
        str(b),
    )
    recs = json.loads(b.read_text())
    assert {r["method"] for r in recs} == {"stb", "reference"}

    tr = run / "tradeoff"
    _stb(
        venv,
        run,
        env,
        "tradeoff",
        "lights:20",
        "--quick",
        "--methods",
        "stb",
        "--width",
        "64",
        "--height",
        "36",
        "--frames",
        "1",
        "--warmup",
        "0",
        "--temporal-frames",
        "2",
        "--no-hdr-flip",
        "--mitsuba-spp",
        "0",
        "--out",
        str(tr),
    )
    assert (tr / "tradeoff.csv").is_file()

    small = run / "small.usda"
    small.write_text(LAMBERT_FLOOR_USDA.format(rho=0.5, light=_SMALL_LIGHT))
    baked = run / "small_baked.usda"
    r = _stb(venv, run, env, "bake", str(small), "-o", str(baked), "--texel-density", "2")
    said = r.stdout + r.stderr  # the per-mesh lines: size and achieved density
    assert "/Box: " in said and "/Ground: " in said and "texels/m (asked 2)" in said, said
    assert (run / "small_baked_lightmaps" / "Box.exr").is_file()
    png = run / "baked.png"
    _stb(venv, run, env, "render", str(baked), str(png), "--width", "64", "--height", "36")
    from stb_hydra.io.images import read_image

    img, _ = read_image(png)
    assert np.all(np.isfinite(img)) and float(img.max()) > 0.0

    if shutil.which("xvfb-run") is None:
        pytest.skip("preview --snapshot needs xvfb-run (tools/ensure_system_deps.sh)")
    pytest.importorskip("glfw")
    pytest.importorskip("imgui_bundle")
    snap = run / "snap.png"
    r = subprocess.run(
        [
            "xvfb-run",
            "-a",
            "-s",
            "-screen 0 640x480x24",
            str(venv / "bin" / "stb"),
            "preview",
            str(small),
            "--snapshot",
            str(snap),
            "--after-frames",
            "2",
            "--width",
            "160",
            "--height",
            "90",
        ],
        cwd=run,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    shot, _ = read_image(snap)
    assert shot.shape[:2] == (90, 160) and float(shot.max()) > 0.0
