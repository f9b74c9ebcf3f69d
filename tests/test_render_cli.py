"""`stb render`: files, AOVs, frames, stats and every bad-input path, through the CLI's
``main`` in this process; one test runs it as a process for the exit codes."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from stb_hydra.color.ocio import ColorPipeline
from stb_hydra.io.images import read_image

SCENE = """#usda 1.0
(
    metersPerUnit = 1
    upAxis = "Y"
    startTimeCode = 1
    endTimeCode = 3
)
def Camera "Cam"
{
    float focalLength = 20
    float horizontalAperture = 36
    float verticalAperture = 20.25
    double3 xformOp:translate = (0, 2, 6)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}
def Cube "Box"
{
    double size = 2
    color3f[] primvars:displayColor = [(0.6, 0.5, 0.4)]
}
def Mesh "Ground"
{
    int[] faceVertexCounts = [4]
    int[] faceVertexIndices = [0, 1, 2, 3]
    point3f[] points = [(-10, -1, -10), (-10, -1, 10), (10, -1, 10), (10, -1, -10)]
}
def SphereLight "Lamp"
{
    float inputs:intensity = 3000
    float inputs:radius = 0.1
    double3 xformOp:translate.timeSamples = {1: (2, 2, 2), 3: (-2, 2, 2)}
    uniform token[] xformOpOrder = ["xformOp:translate"]
}
def SphereLight "Broken"
{
    float inputs:intensity = nan
}
"""


def stb_process(*args: str) -> subprocess.CompletedProcess:
    """``stb ARGS`` as its own process (exit codes as the shell sees them)."""
    return subprocess.run(
        [sys.executable, "-m", "stb_hydra.apps.cli", *args],
        capture_output=True,
        text=True,
        timeout=300,
    )


@pytest.fixture
def stb(capfd):
    """``stb ARGS`` in this process (``cli.main``; its GL context and compiled programs
    shared with the other tests, issue 32), streams captured at the file descriptors
    (USD's and OCIO's C++ messages too): a CompletedProcess-like result."""
    from stb_hydra.apps import cli

    def run(*args: str) -> subprocess.CompletedProcess:
        capfd.readouterr()
        try:
            code = cli.main([str(a) for a in args])
        except SystemExit as exc:  # argparse: usage errors
            code = int(exc.code or 0)
        out, err = capfd.readouterr()
        return subprocess.CompletedProcess(list(args), code, out, err)

    return run


@pytest.fixture
def scene(tmp_path: Path) -> Path:
    p = tmp_path / "scene.usda"
    p.write_text(SCENE)
    return p


def test_exr_png_aovs_stats(stb, scene: Path, tmp_path: Path):
    out = tmp_path / "img.exr"
    stats = tmp_path / "stats.json"
    r = stb(
        "render",
        str(scene),
        str(out),
        "--width",
        "96",
        "--aov",
        "color,depth,normal,albedo",
        "--stats",
        str(stats),
        "--verbose",
    )
    assert r.returncode == 0, r.stderr
    assert "llvmpipe" in r.stderr or "OpenGL" in r.stderr  # --verbose prints the renderer
    assert any("Broken" in ln for ln in r.stderr.splitlines())  # the broken light is reported
    img, meta = read_image(out)
    assert img.shape == (54, 96, 4) and np.isfinite(img).all()
    assert meta["stb:camera"] == "/Cam"
    assert meta["stb:renderSettings"]["lighting"] == "reference"
    for aov, ch in (("depth", 1), ("normal", 3), ("albedo", 3)):
        a, _ = read_image(tmp_path / f"img.{aov}.exr")
        assert a.shape == (54, 96, ch)
    depth, _ = read_image(tmp_path / "img.depth.exr")
    # row 48 looks 0.4 rad-tan down: it hits the cube front face (z = 1) at y ~ 0
    assert depth[48, 48, 0] == pytest.approx(6.0 - 1.0, abs=0.05)
    s = json.loads(stats.read_text())
    assert s["frames"][0]["fov_lights"] == 1
    assert {"gbuffer", "lighting", "color_correction"} <= set(s["frames"][0]["timings_ms"])


def test_png_gpu_display_matches_cpu_ocio(stb, scene: Path, tmp_path: Path):
    assert stb("render", str(scene), str(tmp_path / "a.exr"), "--width", "64").returncode == 0
    assert stb("render", str(scene), str(tmp_path / "a.png"), "--width", "64").returncode == 0
    lin, _ = read_image(tmp_path / "a.exr")
    png, _ = read_image(tmp_path / "a.png", pixel_type="native")
    cpu = ColorPipeline().to_uint8(lin[..., :3])
    diff = np.abs(png[..., :3].astype(int) - cpu.astype(int))
    assert diff.max() <= 1  # GPU OCIO vs CPU OCIO within 1/255 (EXR is half-float)


def test_frames_and_skip_existing(stb, scene: Path, tmp_path: Path):
    pat = str(tmp_path / "f.####.exr")
    r = stb("render", str(scene), pat, "--width", "48", "--frames", "1:3")
    assert r.returncode == 0, r.stderr
    files = sorted(p.name for p in tmp_path.glob("f.*.exr"))
    assert files == ["f.0001.exr", "f.0002.exr", "f.0003.exr"]
    a, _ = read_image(tmp_path / "f.0001.exr")
    c, _ = read_image(tmp_path / "f.0003.exr")
    assert not np.allclose(a, c)  # the lamp moved
    mtime = (tmp_path / "f.0002.exr").stat().st_mtime_ns
    r = stb("render", str(scene), pat, "--width", "48", "--frames", "1:3", "--skip-existing")
    assert r.returncode == 0
    assert (tmp_path / "f.0002.exr").stat().st_mtime_ns == mtime


@pytest.mark.parametrize("temporal", ["accumulate", "taa"])
def test_skip_existing_resumes_like_a_full_run(scene: Path, tmp_path: Path, temporal: str):
    """A resumed run (frame 2 exists) writes frames 1 and 3 exactly as a full run does:
    the same seeds (the skipped frame's are counted) and, under taa, the same history
    (the existing frame is rendered again, not written). STB: every pixel depends on
    the seed."""
    from stb_hydra.apps import cli

    full, part = tmp_path / "full", tmp_path / "part"
    full.mkdir()
    part.mkdir()
    argv = ["--width", "48", "--frames", "1:3", "--lighting", "stb", "--temporal", temporal]
    argv += ["--accumulate", "2", "--quiet"]
    assert cli.main(["render", str(scene), str(full / "f.####.exr"), *argv]) == 0
    (part / "f.0002.exr").write_bytes((full / "f.0002.exr").read_bytes())
    mtime = (part / "f.0002.exr").stat().st_mtime_ns
    args = ["render", str(scene), str(part / "f.####.exr"), *argv, "--skip-existing"]
    assert cli.main(args) == 0
    assert (part / "f.0002.exr").stat().st_mtime_ns == mtime  # not rewritten
    for name in ("f.0001.exr", "f.0003.exr"):
        a, _ = read_image(full / name)
        b, _ = read_image(part / name)
        np.testing.assert_array_equal(b, a, err_msg=f"{temporal}: {name} differs")


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["--camera", "/Nope"], "camera"),
        (["--frames", "1:3"], "####"),
        (["--width", "0"], "width"),
        (["--view", "NoSuchView"], "NoSuchView"),
        (["--aov", "color,bogus"], "bogus"),
    ],
)
def test_bad_arguments_exit_2_without_files(stb, scene, tmp_path, args, needle):
    out = tmp_path / "x.exr"
    r = (
        stb("render", str(scene), str(out), "--width", "32", *args)
        if "--width" not in args
        else stb("render", str(scene), str(out), *args)
    )
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0]
    assert list(tmp_path.iterdir()) == [scene]


def test_unwritable_and_unsupported_outputs(stb, scene: Path, tmp_path: Path):
    r = stb("render", str(scene), str(tmp_path / "missing_dir" / "x.exr"), "--width", "32")
    assert r.returncode == 2 and "missing_dir" in r.stderr
    r = stb("render", str(scene), str(tmp_path / "x.bmpx"), "--width", "32")
    assert r.returncode == 2 and ".bmpx" in r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scene.usda"]


def test_empty_and_unreadable_stages(stb, tmp_path: Path):
    empty = tmp_path / "empty.usda"
    empty.write_text("#usda 1.0\n")
    r = stb("render", str(empty), str(tmp_path / "e.exr"), "--width", "32")
    assert r.returncode == 2 and "nothing to render" in r.stderr
    bad = tmp_path / "bad.usda"
    bad.write_text("garbage")
    r = stb("render", str(bad), str(tmp_path / "b.exr"), "--width", "32")
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "e.exr").exists() and not (tmp_path / "b.exr").exists()


def test_python_api_is_deterministic(scene: Path):
    import stb_hydra

    a = stb_hydra.render(str(scene), width=48)
    b = stb_hydra.render(str(scene), width=48)
    assert a.shape == (27, 48, 3)
    np.testing.assert_array_equal(a, b)


def test_method_options_and_no_weight_cap(stb, scene: Path, tmp_path: Path):
    out = tmp_path / "s.exr"
    r = stb(
        "render",
        str(scene),
        str(out),
        "--width",
        "48",
        "--lighting",
        "stb",
        "-o",
        "N=4,K=32",
        "--no-weight-cap",
        "--accumulate",
        "2",
    )
    assert r.returncode == 0, r.stderr
    assert out.exists()
    r = stb(
        "render",
        str(scene),
        str(tmp_path / "b.exr"),
        "--width",
        "48",
        "--lighting",
        "stb",
        "-o",
        "K=5",
    )
    assert r.returncode == 2 and "stb option K: expected one of" in r.stderr
    r = stb("render", str(scene), str(tmp_path / "c.exr"), "--width", "48", "--no-weight-cap")
    assert r.returncode == 2 and "stb" in r.stderr


def test_print_graph_describes_the_frame_and_renders_nothing(stb, scene: Path, tmp_path: Path):
    out = tmp_path / "g.png"
    r = stb(
        "render",
        str(scene),
        str(out),
        "--width",
        "64",
        "--lighting",
        "stb",
        "--aov",
        "reuse_m",
        "--print-graph",
    )
    assert r.returncode == 0, r.stderr
    text = r.stdout
    assert "lighting method: stb" in text and "passes (execution order):" in text
    order = [
        ln.split(".", 1)[1].split()[0]
        for ln in text.splitlines()
        if ln[:4].strip().isdigit() and ". " in ln
    ]
    assert order.index("gbuffer") < order.index("hiz") < order.index("lighting")
    assert "debug_reuse_m" in order and "debug_bigtile" not in order  # culled: not asked for
    assert not out.exists()


def test_exit_codes_as_a_process(scene: Path, tmp_path: Path):
    """The shell's view: 0 with the file written, 2 and one line for bad input."""
    r = stb_process("render", str(scene), str(tmp_path / "ok.exr"), "--width", "32")
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "ok.exr").exists()
    r = stb_process("render", str(scene), str(tmp_path / "x.exr"), "--width", "0")
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1
    assert not (tmp_path / "x.exr").exists()
