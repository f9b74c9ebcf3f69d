"""``stb preview`` in a REAL window under Xvfb: a scripted run (orbit, method switch,
light toggle), real input through xdotool (the screenshot key, an Alt+drag tumble),
the window captured with ``xwd`` and compared with ``--snapshot``, and bad input.

Xvfb and xdotool come from ``tools/ensure_system_deps.sh`` (``make test``); without
them these tests fail under ``CI=true`` and are skipped (with the reason) elsewhere."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from test_preview import TWO_LIGHTS_USDA

W, H = 256, 144
TOOLS = ("Xvfb", "xdotool", "xwd")


def _need(what: str) -> None:
    msg = f"{what} (run tools/ensure_system_deps.sh, or apt-get install xvfb xdotool x11-apps)"
    if os.environ.get("CI", "").lower() == "true":
        pytest.fail(msg)
    pytest.skip(msg)


@pytest.fixture(scope="module")
def display():
    """A private X server (Xvfb) for this module; yields its DISPLAY."""
    missing = [t for t in TOOLS if shutil.which(t) is None]
    if missing:
        _need(f"the window tests need {', '.join(missing)}")
    try:
        import glfw  # noqa: F401
        import imgui_bundle  # noqa: F401
    except ImportError as exc:
        _need(f"the window tests need the preview extra ({exc})")
    r, w = os.pipe()
    proc = subprocess.Popen(
        ["Xvfb", "-displayfd", str(w), "-screen", "0", "640x480x24", "-nolisten", "tcp"],
        pass_fds=(w,),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    os.close(w)
    with os.fdopen(r) as f:
        num = f.readline().strip()
    if not num:
        proc.kill()
        pytest.fail("Xvfb did not start")
    yield f":{num}"
    proc.terminate()
    proc.wait(10)


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    p = tmp_path_factory.mktemp("preview") / "two_lights.usda"
    p.write_text(TWO_LIGHTS_USDA)
    return p


def _start(display, args, tmp: Path, events=None) -> subprocess.Popen:
    cmd = [sys.executable, "-m", "stb_hydra.apps.cli", "preview", *map(str, args)]
    if events is not None:
        script = tmp / f"events_{len(list(tmp.glob('events_*')))}.json"
        script.write_text(json.dumps(events))
        cmd += ["--script", str(script)]
    env = {**os.environ, "DISPLAY": display}
    return subprocess.Popen(
        cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp
    )


def _wait_line(proc: subprocess.Popen, prefix: str, timeout: float = 90.0) -> str:
    """Read the previewer's stdout up to a line starting with ``prefix`` (at most
    ``timeout`` s) and return it (the lines before it are dropped; the bytes after it
    are kept for the next call and :func:`_finish`). Reads the pipe's fd itself: a
    ``select`` on the fd then ``readline`` on the buffered file missed a line that came
    in the same read as the one before it (it sat in the file's buffer while ``select``
    waited for more: the 90 s timeouts of the xdotool test in loaded runs)."""
    import select

    assert proc.stdout is not None
    fd = proc.stdout.fileno()
    buf: bytes = getattr(proc, "_pending", b"")
    want = prefix.encode()
    seen: list[bytes] = []
    deadline = time.monotonic() + timeout
    while True:
        while b"\n" in buf:
            line, buf = buf.split(b"\n", 1)
            if line.startswith(want):
                proc._pending = buf  # type: ignore[attr-defined]
                return line.decode(errors="replace") + "\n"
            seen.append(line)
        left = deadline - time.monotonic()
        if left <= 0 or not select.select([fd], [], [], left)[0]:
            break
        chunk = os.read(fd, 65536)
        if not chunk:  # the previewer exited
            break
        buf += chunk
    proc.kill()
    out, err = proc.communicate(timeout=30)
    shown = b"\n".join([*seen[-20:], buf]).decode(errors="replace") + out
    raise AssertionError(
        f"no {prefix!r} from the previewer within {timeout} s; stdout: {shown[-3000:]!r}; "
        f"stderr: {err[-2000:]!r}"
    )


def test_wait_line_sees_a_line_that_came_with_the_one_before():
    """Two lines in one write, then silence: the second is found at once (the old
    select-then-readline read both into the file's buffer and waited out the timeout),
    and what follows is kept for the next read."""
    code = (
        "import sys, time; sys.stdout.write('one\\nstb preview: mark ready window=0x1 "
        "selected=-\\nthree\\n'); sys.stdout.flush(); time.sleep(3); print('four')"
    )
    proc = subprocess.Popen(
        [sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    t0 = time.monotonic()
    assert _wait_mark(proc, "ready", timeout=20) == (1, "-")
    assert time.monotonic() - t0 < 2.5
    assert _wait_line(proc, "three", timeout=1) == "three\n"
    _, out, _ = _finish(proc)
    assert out == "four\n"


def _wait_mark(proc: subprocess.Popen, name: str, timeout: float = 90.0) -> tuple[int, str]:
    """Read the previewer's stdout up to ``mark NAME`` (at most ``timeout`` s); returns
    the X window id and the selected prim path."""
    line = _wait_line(proc, f"stb preview: mark {name} ", timeout)
    fields = dict(f.split("=", 1) for f in line.split()[4:])
    return int(fields["window"], 16), fields["selected"]


def _finish(proc: subprocess.Popen, timeout: float = 90.0) -> tuple[int, str, str]:
    try:
        out, err = proc.communicate(timeout=timeout)
        out = getattr(proc, "_pending", b"").decode(errors="replace") + out
    except subprocess.TimeoutExpired:
        proc.kill()
        out, err = proc.communicate()
        raise AssertionError(f"the previewer did not exit within {timeout} s: {err}") from None
    return proc.returncode, out, err


def _png(path: Path) -> np.ndarray:
    from stb_hydra.io.images import read_image

    a, _ = read_image(path, pixel_type="uint8")
    return np.asarray(a)[..., :3].astype(np.int32)


def read_xwd(data: bytes) -> np.ndarray:
    """An XWD (X Window Dump) file of a TrueColor window as (h, w, 3) uint8."""
    hdr = np.frombuffer(data[:100], ">u4")
    header_size, width, height = int(hdr[0]), int(hdr[4]), int(hdr[5])
    byte_order, bpp, bpl = int(hdr[7]), int(hdr[11]), int(hdr[12])
    masks = [int(m) for m in hdr[14:17]]
    ncolors = int(hdr[19])
    assert bpp == 32, f"xwd: {bpp} bits per pixel"
    off = header_size + 12 * ncolors
    px = np.frombuffer(data[off : off + bpl * height], "<u4" if byte_order == 0 else ">u4")
    px = px.reshape(height, bpl // 4)[:, :width]
    out = []
    for m in masks:
        shift = (m & -m).bit_length() - 1
        out.append((px & m) >> shift)
    return np.stack(out, -1).astype(np.uint8)


def _xdo(display: str, *args: str) -> None:
    subprocess.run(["xdotool", *args], env={**os.environ, "DISPLAY": display}, check=True)


@pytest.mark.gl
@pytest.mark.slow
def test_scripted_window_orbit_method_light_and_snapshot_equals_window(display, scene, tmp_path):
    """One window: the converged view, a light switched off, an orbit, a method switch;
    then the window is captured with xwd while it rests and compared with the
    --snapshot file and with the screenshot key's file (sent with xdotool)."""
    events = [
        {"wait": "converged"},
        {"screenshot": "a.png"},
        {"light": "/Lights/Left", "enabled": False},
        {"wait": "converged"},
        {"screenshot": "b.png"},
        {"orbit": [120, 0]},
        {"wait": "converged"},
        {"screenshot": "c.png"},
        {"method": "sun"},
        {"wait": "converged"},
        {"screenshot": "d.png"},
        {"method": "stb"},
        {"wait": "converged"},
        {"mark": "ready"},
        {"wait_file": str(tmp_path / "captured")},  # until the test's xdotool and xwd ran
    ]
    snap = tmp_path / "snap.png"
    args = [scene, "--width", W, "--height", H, "--max-samples", 8, "--no-ui"]
    args += ["--snapshot", snap, "--after-frames", 2, "--screenshot-dir", tmp_path]
    proc = _start(display, args, tmp_path, events)
    win, _ = _wait_mark(proc, "ready")
    _xdo(display, "mousemove", "--window", str(win), "20", "20")
    _xdo(display, "key", "p")  # the screenshot key: stb_preview_0001.png
    time.sleep(0.5)
    xwd = subprocess.run(
        ["xwd", "-silent", "-id", str(win)],
        env={**os.environ, "DISPLAY": display},
        capture_output=True,
        check=True,
    ).stdout
    (tmp_path / "captured").touch()
    code, out, err = _finish(proc)
    assert code == 0, err
    assert "Traceback" not in err
    a, b, c, d = (_png(tmp_path / f"{n}.png") for n in "abcd")
    assert a.shape == (H, W, 3)
    left, right = slice(0, W // 3), slice(2 * W // 3, W)
    # the left light off: its side darkens, the other side stays
    assert b[:, left].mean() < 0.7 * a[:, left].mean()
    assert abs(b[:, right].mean() - a[:, right].mean()) < 0.1 * a[:, right].mean()
    # an orbit changes the pixels
    assert np.abs(c - b).mean() > 5.0
    # the sun method: no distant light, so the local light's pool goes dark
    assert d.mean() < 0.3 * c.mean()
    # the window's content (xwd) equals --snapshot and the P-key screenshot
    window = read_xwd(xwd).astype(np.int32)
    s = _png(snap)
    assert window.shape == s.shape == (H, W, 3)
    assert np.array_equal(window, s), f"max diff {np.abs(window - s).max()}"
    key_shot = tmp_path / "stb_preview_0001.png"
    assert key_shot.exists(), out
    assert np.array_equal(_png(key_shot), s)
    assert s.mean() > 10.0  # the stage, not an empty window


@pytest.mark.gl
@pytest.mark.slow
def test_click_picks_and_alt_drag_tumbles_with_xdotool(display, scene, tmp_path):
    """Real mouse input: a click on the box selects it (ID buffer); Alt + left drag
    orbits the camera."""
    go = tmp_path / "input_sent"
    events = [
        {"wait": "converged"},
        {"screenshot": "before.png"},
        {"mark": "ready"},
        # The window takes input until the test says it has sent it all (a fixed sleep
        # here raced the xdotool processes on a loaded machine: the window had closed).
        {"wait_file": str(go)},
        {"sleep": 0.5},  # the last X events reach the window
        {"wait": "converged"},
        {"screenshot": "after.png"},
        {"mark": "done"},
        {"quit": True},
    ]
    args = [scene, "--width", W, "--height", H, "--max-samples", 4, "--no-ui"]
    proc = _start(display, [*args, "--lighting", "reference"], tmp_path, events)
    win, selected = _wait_mark(proc, "ready")
    assert selected == "-"
    # the box's front face through /Cam (16:9 like the window): (0, 0.6, 0.5) projects
    # to NDC (0, 0.016) (USD's frustum, see test_preview.py's picking test)
    _xdo(display, "mousemove", "--window", str(win), str(W // 2), str(int(0.492 * H)))
    _xdo(display, "click", "1")
    _xdo(display, "mousemove", "--window", str(win), "60", "70")
    _xdo(display, "keydown", "alt", "mousedown", "1")
    for _ in range(4):
        _xdo(display, "mousemove_relative", "--", "20", "0")
    _xdo(display, "mouseup", "1", "keyup", "alt")
    go.touch()
    _, selected = _wait_mark(proc, "done")
    assert selected == "/Box"
    code, _, err = _finish(proc)
    assert code == 0, err
    before, after = _png(tmp_path / "before.png"), _png(tmp_path / "after.png")
    assert np.abs(after - before).mean() > 5.0


def test_missing_stage_shows_the_error_in_the_window(display, tmp_path):
    snap = tmp_path / "err.png"
    proc = _start(
        display, [tmp_path / "nope.usda", "--snapshot", snap, "--width", W, "--height", H], tmp_path
    )
    code, _, err = _finish(proc)
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "nope.usda" in lines[0] and "file not found" in lines[0]
    img = _png(snap)
    assert img.std() > 5.0  # the error panel is drawn, not a blank window


@pytest.mark.slow
def test_broken_stage_opens_once_fixed_on_disk(display, tmp_path):
    """A stage that does not parse: the error is shown, the file is watched, and writing
    a good stage to it opens it in the same window."""
    path = tmp_path / "later.usda"
    path.write_text("#usda 1.0\ndef Mesh (\n")
    go = tmp_path / "reopened"
    events = [
        {"mark": "broken"},
        {"wait_file": str(go)},  # until the test saw the stage reopened (no fixed sleep)
        {"wait": "converged"},
        {"screenshot": "fixed.png"},
        {"quit": True},
    ]
    args = [path, "--width", W, "--height", H, "--max-samples", 2, "--no-ui"]
    proc = _start(display, [*args, "--lighting", "reference"], tmp_path, events)
    _wait_mark(proc, "broken")
    path.write_text(TWO_LIGHTS_USDA)
    _wait_line(proc, f"stb preview: opened {path}")
    go.touch()
    code, _out, err = _finish(proc)
    assert code == 0, err
    assert "line 2, column 1" in err and len(err.strip().splitlines()) == 1
    assert _png(tmp_path / "fixed.png").mean() > 10.0  # the stage, not the error


def test_no_display_exits_2_with_one_line(tmp_path, scene):
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    r = subprocess.run(
        [sys.executable, "-m", "stb_hydra.apps.cli", "preview", str(scene)],
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "cannot open a window" in lines[0], r.stderr


def test_bad_script_exits_2_with_one_line(tmp_path, scene):
    bad = tmp_path / "bad.json"
    bad.write_text('[{"orbit": [1]}]')
    r = subprocess.run(
        [sys.executable, "-m", "stb_hydra.apps.cli", "preview", str(scene), "--script", str(bad)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "event 1" in lines[0] and "orbit" in lines[0], r.stderr


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["-o", "N=abc"], "stb option N: expected an integer"),
        (["--view", "Nope"], "unknown OCIO view 'Nope'"),
        (["--snapshot", "/nonexistent/dir/x.png"], "directory does not exist"),
        (["--width", "3"], "bad viewport 3x540"),
    ],
)
def test_bad_arguments_exit_2_with_one_line_before_any_window(tmp_path, scene, args, needle):
    env = {k: v for k, v in os.environ.items() if k != "DISPLAY"}  # no window needed
    r = subprocess.run(
        [sys.executable, "-m", "stb_hydra.apps.cli", "preview", str(scene), *args],
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and needle in lines[0], r.stderr
