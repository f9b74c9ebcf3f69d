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


@pytest.mark.slow
@pytest.mark.gl
def test_wheel_installs_and_renders_outside_the_checkout(tmp_path, gl_ctx):
    wheel = _build_wheel(tmp_path)
    names = set(zipfile.ZipFile(wheel).namelist())
    for f in (
        "shaders/__init__.py",
        "shaders/stb_bigtile.frag",
        "shaders/common/lights.glsl",
        "data/quad_patterns.json",
        "scene/schema/plugInfo.json",
    ):
        assert f"stb_hydra/{f}" in names, f

    venv = _venv_with_wheel(tmp_path, wheel)
    run_dir = tmp_path / "run"
    run_dir.mkdir()
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}

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
