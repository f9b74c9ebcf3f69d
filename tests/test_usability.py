"""What a new user tripped over (issue 19), one test group per item, and the README's
``stb ...`` command lines run on small sizes.

Most checks call ``stb_hydra.apps.cli.main`` in this process with ``capfd`` (file-
descriptor capture: USD's C++ output is seen too; a Python traceback would fail the
test as an exception); the progress bar needs a terminal (a pty) and the README lines
run as real ``stb`` processes.
"""

from __future__ import annotations

import json
import os
import pty
import re
import select
import shlex
import stat
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from stb_hydra.apps import cli
from stb_hydra.io.images import read_image

REPO = Path(__file__).resolve().parents[1]

HEADER = """#usda 1.0
(
    metersPerUnit = 1
    upAxis = "Y"
{extra})
"""
CAMERA = """
def Camera "Cam"
{{
    float focalLength = 20
    float horizontalAperture = 36
    float verticalAperture = 20.25
{attrs}    double3 xformOp:translate = (0, 2, 6)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}}
"""
BOX = """
def Cube "Box"
{
    double size = 2
}
"""
LAMP = """
def SphereLight "Lamp"
{
    float inputs:intensity = 3000
    float inputs:radius = 0.1
    double3 xformOp:translate = (2, 2, 2)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}
"""
#: One light per problem of item 1, each disabled or changed.
BAD_LIGHTS = """
def SphereLight "NaN"
{
    float inputs:intensity = nan
}
def SphereLight "Negative"
{
    float inputs:intensity = -5
}
def SphereLight "Huge"
{
    float inputs:intensity = 1e38
}
def SphereLight "Stops"
{
    float inputs:intensity = 1
    float inputs:exposure = 200
}
def RectLight "Flat"
{
    float inputs:intensity = 10
    float inputs:width = 0
}
def SphereLight "Ies"
{
    float inputs:intensity = 10
    asset inputs:shaping:ies:file = @missing.ies@
}
"""


def stage_file(
    tmp_path: Path, body: str, name: str = "s.usda", extra: str = "", camera_attrs: str = ""
) -> Path:
    p = tmp_path / name
    p.write_text(HEADER.format(extra=extra) + CAMERA.format(attrs=camera_attrs) + body)
    return p


def stb(capfd, *args: object) -> tuple[int, str, str]:
    """``stb ARGS`` in this process: (exit code, stdout, stderr)."""
    capfd.readouterr()
    try:
        code = cli.main([str(a) for a in args])
    except SystemExit as exc:  # argparse: --version, usage errors
        code = int(exc.code or 0)
    out, err = capfd.readouterr()
    return code, out, err


def one_error(code: int, err: str, needle: str) -> str:
    assert code == 2, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("stb: error: ") and needle in lines[0], lines[0]
    assert "Traceback" not in err and "pxrInternal" not in err
    return lines[0]


def warnings_of(err: str) -> list[str]:
    return [ln[len("warning: ") :] for ln in err.splitlines() if ln.startswith("warning: ")]


# --- 1. warnings on stderr by default, one line each, deduplicated, counted; --quiet ---------


@pytest.mark.gl
def test_scene_warnings_are_shown_once_each_with_a_count(tmp_path, capfd):
    scene = stage_file(
        tmp_path,
        BOX + LAMP + BAD_LIGHTS,
        extra="    startTimeCode = 1\n",
        camera_attrs="    float exposure = 200\n",
    )
    code, _, err = stb(
        capfd, "render", scene, tmp_path / "f.####.png", "--width", 32, "--frames", "1:2"
    )
    assert code == 0, err
    w = warnings_of(err)
    expect = {
        "</NaN>": "intensity nan",
        "</Negative>": "intensity -5",
        "</Huge>": "exceeds",
        "</Stops>": "exposure 200",
        "</Cam>": "exposure scale",
        "</Flat>": "zero-area",
        "</Ies>": "IES file 'missing.ies' not found",
    }
    for prim, what in expect.items():
        hits = [x for x in w if prim in x and what in x]
        assert len(hits) == 1, (prim, what, w)  # once, though two frames were rendered
    assert len(w) == len(set(w))
    last = err.strip().splitlines()[-1]
    assert last == f"stb render: {len(w)} warnings"
    assert "RuntimeWarning" not in err and "Traceback" not in err

    code, _, err = stb(capfd, "render", scene, tmp_path / "q.png", "--width", 32, "--quiet")
    assert code == 0 and err == "" and (tmp_path / "q.png").exists()


# --- 2. USD's own diagnostics: trapped, one line per cause, no internal namespaces -----------


def _missing_refs_stage(tmp_path: Path, n: int) -> Path:
    """``n`` references to missing layers: one USD composition error each. (Not
    ``.mtlx``: the scene index reads MaterialX references itself, see
    tests/test_materialx.py.)"""
    refs = "".join(
        f'def Scope "M{i}" (\n    references = @./looks/m{i}.usda@</Materials>\n)\n{{\n}}\n'
        for i in range(n)
    )
    return stage_file(tmp_path, BOX + LAMP + refs)


@pytest.mark.gl
def test_usd_diagnostics_collapse_into_one_line_per_cause(tmp_path, capfd):
    scene = _missing_refs_stage(tmp_path, 3)
    code, _, err = stb(capfd, "render", scene, tmp_path / "m.png", "--width", 32)
    assert code == 0, err
    assert "_ReportErrors" not in err and "Warning: in" not in err and "pxrInternal" not in err
    usd = [x for x in warnings_of(err) if x.startswith("usd: ")]
    assert len(usd) == 1, err
    assert ".usda" in usd[0] and "(+2 more like this)" in usd[0]
    assert re.search(r"@looks/m\d.usda@", usd[0])  # relative to the stage directory
    assert err.strip().splitlines()[-1] == "stb render: 1 warning"
    code, _, err = stb(capfd, "render", scene, tmp_path / "q.png", "--width", 32, "-q")
    assert code == 0 and err == ""


def test_chess_set_diagnostics_in_inspect(testdata, capfd):
    # The 19 ".mtlx: Cannot determine file format" composition errors are gone: the
    # scene index reads the MaterialX references itself (tests/test_materialx.py).
    chess = testdata / "scenes" / "OpenChessSet" / "chess_set.usda"
    code, out, err = stb(capfd, "inspect", chess, "--json")
    assert code == 0
    assert err == ""  # no raw `Warning: in _ReportErrors ...` lines
    assert json.loads(out)["warnings"] == []


def test_truncated_usda_is_one_clean_line(tmp_path, capfd):
    bad = tmp_path / "trunc.usda"
    bad.write_text((REPO / "usd_scenes" / "default.usda").read_text()[:300])
    for verb in (("render", bad, tmp_path / "x.png", "--width", 16), ("inspect", bad)):
        code, _, err = stb(capfd, *verb)
        line = one_error(code, err, "cannot open stage")
        assert re.search(r"line \d+, column \d+: parse error", line), line
    assert not (tmp_path / "x.png").exists()


def test_clean_text_and_causes():
    from stb_hydra.scene.usd_diagnostics import Diagnostic, clean_text, summarize

    ns = "pxrInternal_v0_26_11__pxrReserved__"
    assert clean_text(f"{ns}::UsdStage::_ReportErrors") == "UsdStage::_ReportErrors"
    raw = (
        f"/a/s.usda:4:1: parse error matching {ns}::Sdf_TextFileFormatParser::"
        "TupleValueClose at '' in </A.x>"
    )
    assert clean_text(raw, stage_file="/a/s.usda") == (
        "line 4, column 1: parse error at end of file (expected TupleValueClose)"
    )
    d = [
        Diagnostic(
            "warning",
            clean_text(
                f"Could not open asset @/lib/a/{n}.mtlx:SDF_FORMAT_ARGS:target=usd@ "
                "(instantiating stage on stage @/lib/s.usda@ <0x55aa>)",
                "/lib",
            ),
            "f",
        )
        for n in "xyz"
    ]
    assert d[0].text == "Could not open asset @a/x.mtlx@"
    seen: set[str] = set()
    assert summarize(d, seen) == ["usd: Could not open asset @a/x.mtlx@ (+2 more like this)"]
    assert summarize(d, seen) == []  # a cause is reported once per run


# --- 3. limits: checked before rendering, one line, exit 2; stats file mode and values ------


@pytest.fixture
def scene(tmp_path: Path) -> Path:
    return stage_file(tmp_path, BOX + LAMP)


@pytest.mark.gl
@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["--width", "100000"], "--width 100000 exceeds this OpenGL context's largest image"),
        (["--width", "64", "--height", "100000"], "--height 100000 exceeds"),
        (["--width", "64", "--height", "0"], "--height must be a positive number of pixels"),
        (["--width", "0"], "--width must be a positive number of pixels"),
        (
            ["--width", "64", "--lighting", "stb", "-o", "N=abc"],
            "stb option N: expected an integer, got 'abc'",
        ),
        (["--width", "64", "--stats", "missing_dir/s.json"], "missing_dir"),
    ],
)
def test_limits_exit_2_with_one_line_and_no_files(
    scene, tmp_path, capfd, monkeypatch, args, needle
):
    monkeypatch.chdir(tmp_path)
    code, _, err = stb(capfd, "render", scene, tmp_path / "x.png", *args)
    one_error(code, err, needle)
    assert sorted(p.name for p in tmp_path.iterdir()) == [scene.name]


@pytest.mark.gl
def test_stats_file_mode_and_values(scene, tmp_path, capfd):
    old = os.umask(0o022)
    try:
        stats = tmp_path / "s.json"
        code, _, err = stb(
            capfd, "render", scene, tmp_path / "i.png", "--width", 32, "--stats", stats
        )
        assert code == 0, err
        img_mode = stat.S_IMODE((tmp_path / "i.png").stat().st_mode)
        assert stat.S_IMODE(stats.stat().st_mode) == img_mode == 0o644
        doc = json.loads(stats.read_text())
        fr = doc["frames"][0]
        assert fr["shadow_budget_texels"] is None  # unlimited (offline), not 2**62
        assert doc["settings"]["shadow_budget"] is None
        assert fr["frame"] == "default"  # a still of a stage without a time range
        code, _, err = stb(
            capfd,
            "render",
            scene,
            tmp_path / "b.png",
            "--width",
            32,
            "--stats",
            stats,
            "--shadow-budget",
            200000,
            "--frames",
            3,
        )
        assert code == 0, err
        fr = json.loads(stats.read_text())["frames"][0]
        assert fr["shadow_budget_texels"] == 200000 and fr["frame"] == 3.0
    finally:
        os.umask(old)


# --- 4. feedback: progress bar on a terminal only, --skip-existing, --version ----------------


def _run_on_pty(args: list[str]) -> str:
    """Run ``stb ARGS`` with stderr on a pseudo-terminal (80 columns); its output."""
    import fcntl
    import struct
    import termios

    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))
    proc = subprocess.Popen(
        [sys.executable, "-m", "stb_hydra.apps.cli", *args],
        stdout=subprocess.DEVNULL,
        stderr=slave,
        stdin=subprocess.DEVNULL,
    )
    os.close(slave)
    chunks = []
    while True:
        r, _, _ = select.select([master], [], [], 0.2)
        if r:
            try:
                data = os.read(master, 65536)
            except OSError:  # EIO: the child closed the terminal
                break
            if not data:
                break
            chunks.append(data)
        elif proc.poll() is not None:
            break
    proc.wait(timeout=120)
    os.close(master)
    assert proc.returncode == 0
    return b"".join(chunks).decode("utf-8", "replace")


@pytest.mark.gl
def test_progress_bar_on_a_terminal_only(scene, tmp_path, capfd):
    args = [
        "render",
        str(scene),
        str(tmp_path / "p.####.exr"),
        "--width",
        "32",
        "--frames",
        "1:2",
        "--accumulate",
        "2",
    ]
    tty = _run_on_pty(args)
    assert "stb render" in tty and "4/4" in tty and "sample" in tty, tty
    assert "frame 2/2" in tty and "shadow maps" in tty, tty
    code, _, err = stb(capfd, *args)  # stderr captured (not a terminal): no bar
    assert code == 0 and "sample" not in err and "\r" not in err


@pytest.mark.gl
def test_skip_existing_says_what_it_skipped(scene, tmp_path, capfd):
    pat = tmp_path / "f.####.exr"
    assert stb(capfd, "render", scene, pat, "--width", 16, "--frames", "1:2")[0] == 0
    code, _, err = stb(
        capfd, "render", scene, pat, "--width", 16, "--frames", "1:3", "--skip-existing"
    )
    assert code == 0
    line = [ln for ln in err.splitlines() if "skip" in ln]
    assert line == [
        "stb render: --skip-existing skipped 2 of 3 frames (files exist: f.0001.exr, f.0002.exr)"
    ]
    code, _, err = stb(
        capfd, "render", scene, pat, "--width", 16, "--frames", "1:3", "--skip-existing", "--quiet"
    )
    assert code == 0 and err == ""


def test_version(capfd):
    import stb_hydra

    code, out, _ = stb(capfd, "--version")
    assert code == 0 and out.startswith(f"stb {stb_hydra.__version__} (usd-core ")


# --- 5. empty results: no lights, a camera that sees nothing, a stage without time ----------


@pytest.mark.gl
def test_no_lights_and_nothing_in_view_warn_once(tmp_path, capfd):
    dark = stage_file(tmp_path, BOX, "dark.usda")
    code, _, err = stb(capfd, "render", dark, tmp_path / "d.png", "--width", 16)
    assert code == 0 and warnings_of(err) == [
        "the stage has no lights: the image shows unlit (black) geometry; add a light or --ambient"
    ]
    away = stage_file(
        tmp_path,
        LAMP
        + BOX.replace(
            "double size = 2",
            "double size = 2\n"
            "    double3 xformOp:translate = (0, 0, 20)\n"
            '    uniform token[] xformOpOrder = ["xformOp:translate"]',
        ),
        "away.usda",
    )
    code, _, err = stb(
        capfd, "render", away, tmp_path / "a.####.png", "--width", 16, "--frames", "1:2"
    )
    assert code == 0
    assert warnings_of(err) == ["camera /Cam sees no geometry: the image is background only"]


def test_inspect_prints_default_time(tmp_path, capfd):
    p = stage_file(tmp_path, BOX + LAMP)
    code, out, _ = stb(capfd, "inspect", p)
    assert code == 0 and "time=default" in out and "e+308" not in out
    code, out, _ = stb(capfd, "inspect", p, "--json")
    assert json.loads(out)["time"] == "default"
    timed = stage_file(
        tmp_path, BOX + LAMP, "t.usda", extra="    startTimeCode = 5\n    endTimeCode = 9\n"
    )
    assert json.loads(stb(capfd, "inspect", timed, "--json")[1])["time"] == 5.0


# --- 6. validate: the library root -------------------------------------------------------------


def test_validate_library_root(tmp_path, capfd, monkeypatch):
    monkeypatch.chdir(REPO)
    report = tmp_path / "v.json"
    code, _, err = stb(
        capfd, "validate", "usd_scenes/prefabs", "--jobs", "0", "--quiet", "--json", report
    )
    assert code == 1  # each PATH its own root: ../ies escapes it
    rules = [f["rule"] for a in json.loads(report.read_text())["assets"] for f in a["findings"]]
    assert rules.count("asset_path_unsafe") == 4
    code, _, err = stb(
        capfd,
        "validate",
        "usd_scenes/prefabs",
        "--library-root",
        "usd_scenes",
        "--jobs",
        "0",
        "--quiet",
    )
    assert code == 0, err
    code, _, err = stb(capfd, "validate", "usd_scenes/prefabs", "--library-root", "usd_scenes/ies")
    one_error(code, err, "is outside --library-root")


# --- 7. debug views carry a colour scale with min/max labels ----------------------------------


@pytest.mark.parametrize("name", ["lightcount", "shadowterms", "bigtile", "smalltile"])
def test_debug_view_pngs_have_a_labelled_scale(tmp_path, name):
    from stb_hydra.io.debug_views import LEGEND_ROWS, _legend_spec, debug_aov_image, write_debug_aov

    rng = np.random.default_rng(1)
    px = (
        (rng.random((40, 160)) * 300).astype(np.float32)
        if name == "lightcount"
        else rng.random((40, 160, 3)).astype(np.float32)
    )
    png_path = write_debug_aov(tmp_path / "x.png", name, px)[0]
    png, meta = read_image(png_path, pixel_type="native")
    assert png.shape[:2] == (40 + LEGEND_ROWS, 160) and meta["stb:legendRows"] == LEGEND_ROWS
    view = np.rint(np.clip(debug_aov_image(name, px), 0, 1) * 255)
    assert np.abs(png[:40, :, :3].astype(int) - view.astype(int)).max() <= 1  # view unchanged
    strip = png[40:, :, :3].astype(int)
    colors, lo, hi, _ = _legend_spec(name)
    for x, c in ((0, colors[0]), (159, colors[-1])):  # the bar runs from min to max
        assert np.abs(strip[6, x] - np.rint(c * 255)).max() <= 2, (x, strip[6, x], c)
    labels = strip[11:].max(-1)
    assert labels[:, :20].max() > 128 and labels[:, -20:].max() > 128  # min and max labels
    assert lo and hi


# --- 8. API docs ------------------------------------------------------------------------------


def test_help_shows_the_real_signature_and_runnable_package_docs():
    import pydoc

    import stb_hydra
    from stb_hydra import api

    text = pydoc.render_doc(stb_hydra.render, renderer=pydoc.plaintext)
    assert "*args" not in text and "width" in text and "lighting" in text
    pkg = pydoc.render_doc(stb_hydra, renderer=pydoc.plaintext)
    assert "render(stage" in pkg  # help(stb_hydra) documents the lazy render()
    for doc in (stb_hydra.__doc__, api.__doc__):
        assert "usd_scenes/default.usda" in doc and '"scene.usda"' not in doc


# --- the README's `stb ...` lines, on small sizes ---------------------------------------------


def readme_commands() -> list[str]:
    text = (REPO / "README.md").read_text()
    lines = []
    for block in re.findall(r"```sh\n(.*?)```", text, re.S):
        lines += [
            ln.split("  # ")[0].strip()
            for ln in block.splitlines()
            if ln.strip().startswith("stb ")
        ]
    return lines


def shrink(cmd: str, out: Path) -> list[str]:
    """The README line with small sizes and ``out/`` under ``out``."""
    small = {"--width": "64", "--height": "36", "--accumulate": "2", "--size": "64x36"}
    toks = shlex.split(cmd)
    res: list[str] = []
    it = iter(range(len(toks)))
    for i in it:
        t = toks[i]
        if t in small and i + 1 < len(toks):
            res += [t, small[t]]
            next(it)
        elif t == "--frames" and i + 1 < len(toks):
            res += [t, "1:2" if ":" in toks[i + 1] else "2"]
            next(it)
        elif t.startswith("gen:lights:"):
            res.append("gen:lights:" + ",".join(t.split(":")[2].split(",")[:2]))
        else:
            res.append(str(out / t[4:]) if t.startswith("out/") else t)
    if len(res) > 1 and res[1] == "render" and "--width" not in res:
        res += ["--width", "64"]
    return res[1:]


#: README verbs whose examples tests/test_wheel_install.py runs instead, at small sizes
#: from the installed wheel: tradeoff (--quick at 64x36), bake (a small static scene,
#: the README's SCENE.usda placeholder) and preview --snapshot (under Xvfb).
WHEEL_TESTED_VERBS = {"tradeoff", "bake", "preview"}


@pytest.mark.slow
def test_readme_commands_run(tmp_path):
    cmds = readme_commands()
    verbs = {shlex.split(c)[1] for c in cmds}
    assert {"render", "inspect", "validate", "bench", "--version"} <= verbs, cmds
    out = tmp_path / "out"
    out.mkdir()
    for cmd in cmds:
        if shlex.split(cmd)[1] in WHEEL_TESTED_VERBS:
            continue
        args = shrink(cmd, out)
        r = subprocess.run(
            [sys.executable, "-m", "stb_hydra.apps.cli", *args],
            cwd=REPO,
            capture_output=True,
            text=True,
            timeout=300,
        )
        assert r.returncode == 0, (cmd, args, r.stderr[-2000:])
        assert "Traceback" not in r.stderr, (cmd, r.stderr[-2000:])
    assert (out / "court.png").exists() and (out / "frame.0002.exr").exists()
    assert (out / "validate.json").exists() and (out / "bench.json").exists()
