"""``stb render --ray`` and ``stb validate --ray`` on a local Ray instance (one per
module: ``ray.init(num_cpus=2)``): byte-identical frames, a worker killed mid-run,
frames failing for a reason of the scene, the same validation findings as a local
run, and the one-line errors (unreachable address, missing extra)."""

from __future__ import annotations

import json
import re
import shutil
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from stagegen import BOX_USDA, camera_usda, ground_usda, usda_header

ray = pytest.importorskip("ray", reason="the ray extra (make test installs it)")

from stb_hydra.apps.cli import main as stb_main  # noqa: E402
from stb_hydra.distributed import cluster  # noqa: E402
from stb_hydra.distributed import render as dist_render  # noqa: E402

pytestmark = pytest.mark.slow

# 64x36, 8 frames; two lights move (time samples) so every frame differs.
SCENE = (
    usda_header(1, 8)
    + camera_usda((0, 6, 14), -22)
    + ground_usda(20)
    + BOX_USDA
    + """\
def SphereLight "Lamp"
{
    float inputs:intensity = 300
    float inputs:radius = 0.1
    double3 xformOp:translate.timeSamples = {1: (-4, 3, 2), 8: (4, 3, 2)}
    uniform token[] xformOpOrder = ["xformOp:translate"]
}
def SphereLight "Lamp2"
{
    float inputs:intensity = 100
    float inputs:radius = 0.1
    double3 xformOp:translate.timeSamples = {1: (3, 2, -3), 8: (-3, 4, 3)}
    uniform token[] xformOpOrder = ["xformOp:translate"]
}
"""
)

# stochastic lighting with two samples per frame: the seeds must follow the frame
RENDER = ["--frames", "1:8", "--width", "64", "--height", "36", "--lighting", "stb"]
RENDER += ["--accumulate", "2", "--quiet"]

# OIIO stamps every EXR with the time it was written (capDate "YYYY:MM:DD HH:MM:SS").
_DATETIME = re.compile(rb"capDate\x00string\x00\x13\x00\x00\x00[0-9: ]{19}")


def _bytes(path: Path) -> bytes:
    """The file's bytes with the capDate value blanked (two local renders differ
    there and nowhere else)."""
    data = path.read_bytes()
    blanked, n = _DATETIME.subn(b"capDate\x00string\x00\x13\x00\x00\x00" + b"-" * 19, data)
    assert n == 1, f"{path}: capDate attribute not found"
    return blanked


@pytest.fixture(scope="module")
def local_ray():
    ray.init(address="local", num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield ray
    ray.shutdown()


@pytest.fixture(scope="module")
def scene(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("ray_scene")
    p = d / "anim.usda"
    p.write_text(SCENE)
    return p


@pytest.fixture(scope="module")
def local_frames(scene: Path, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("local_frames")
    assert stb_main(["render", str(scene), str(out / "f.####.exr"), *RENDER]) == 0
    assert len(list(out.glob("f.*.exr"))) == 8
    return out


def _same_frames(a: Path, b: Path) -> None:
    names = sorted(p.name for p in a.glob("f.*.exr"))
    assert names == sorted(p.name for p in b.glob("f.*.exr")) and len(names) == 8
    for n in names:
        assert _bytes(a / n) == _bytes(b / n), n


def test_two_workers_render_byte_identical_frames(local_ray, scene, local_frames, tmp_path):
    stats = tmp_path / "stats.json"
    out = tmp_path / "f.####.exr"
    rc = stb_main(["render", str(scene), str(out), *RENDER, "--ray", "--stats", str(stats)])
    assert rc == 0
    _same_frames(local_frames, tmp_path)
    doc = json.loads(stats.read_text())
    assert doc["ray"]["workers"] == 2
    assert doc["ray"]["frames_done"] == 8 and doc["ray"]["retried"] == 0
    assert [f["frame"] for f in doc["frames"]] == [float(i) for i in range(1, 9)]
    # (which worker renders which frame depends on which is free: not asserted)
    assert doc["settings"]["lighting"] == "stb" and doc["renderer"]


def test_a_worker_renders_frames_in_any_order_like_the_local_render(repo, tmp_path):
    """In process (no Ray), the courtyard at 745x360 (its shadow atlas keeps state
    between frames: without the worker rendering --frames' first frame first, frames
    2 and 4 differ): a worker whose first frame is not the first of --frames, and an
    earlier frame after a later one (a retry: the engine is rebuilt), still writes the
    local render's files."""
    from stb_hydra.apps.cli import build_parser

    scene = str(repo / "usd_scenes" / "default.usda")
    flags = ["--frames", "1:4", "--width", "745", "--height", "360", "--lighting", "stb"]
    local, dist = tmp_path / "local", tmp_path / "ray"
    local.mkdir()
    dist.mkdir()
    assert stb_main(["render", scene, str(local / "f.####.exr"), *flags, "--quiet"]) == 0
    args = build_parser().parse_args(["render", scene, str(dist / "f.####.exr"), *flags])
    args.ray = ""
    w = dist_render.RenderWorker(dist_render._job(args, 1.0, 1))
    order = (1, 3, 0)
    try:
        assert w.ready()["error"] is None
        for i in order:
            res = w.render(i, float(i + 1), str(dist / f"f.{i + 1:04d}.exr"))
            assert "record" in res, res
    finally:
        w.close()
    for i in order:
        n = f"f.{i + 1:04d}.exr"
        assert _bytes(local / n) == _bytes(dist / n), n


def test_a_worker_killed_mid_run_loses_no_frame(
    local_ray, scene, local_frames, tmp_path, monkeypatch
):
    killed: list[int] = []

    def kill_on_second_frame(pool, slot, index):
        if not killed and slot.frames >= 1:  # it has rendered one: kill it in its next
            killed.append(index)
            ray.kill(slot.actor, no_restart=True)

    monkeypatch.setattr(dist_render, "on_dispatch", kill_on_second_frame)
    stats = tmp_path / "stats.json"
    out = tmp_path / "f.####.exr"
    rc = stb_main(["render", str(scene), str(out), *RENDER, "--ray", "--stats", str(stats)])
    assert rc == 0 and killed
    _same_frames(local_frames, tmp_path)
    doc = json.loads(stats.read_text())["ray"]
    assert doc["frames_done"] == 8 and doc["frames_failed"] == 0
    assert doc["workers_lost"] == 1
    # killed within ms of the call: its frame is lost (retried) unless it was done first
    assert doc["retried"] in (0, 1)


def test_a_worker_exiting_mid_frame_has_its_frame_rerun(
    local_ray, scene, local_frames, tmp_path, monkeypatch
):
    """A worker process that exits after rendering frame 4 and before writing it (the
    test hook; as a crash would): frame 4 is rendered again by another worker."""
    marker = tmp_path / "exited"
    monkeypatch.setattr(dist_render, "exit_mid_frame", {"index": 3, "marker": str(marker)})
    stats = tmp_path / "stats.json"
    out = tmp_path / "f.####.exr"
    rc = stb_main(["render", str(scene), str(out), *RENDER, "--ray", "--stats", str(stats)])
    assert rc == 0 and marker.exists()
    _same_frames(local_frames, tmp_path)
    doc = json.loads(stats.read_text())["ray"]
    assert doc["frames_done"] == 8 and doc["frames_failed"] == 0
    assert doc["retried"] == 1 and doc["workers_lost"] == 1


def test_scene_failures_are_reported_not_retried(local_ray, scene, tmp_path, capsys):
    (tmp_path / "f.0005.exr").mkdir()  # frame 5 cannot be written: a directory is there
    stats = tmp_path / "stats.json"
    out = tmp_path / "f.####.exr"
    rc = stb_main(["render", str(scene), str(out), *RENDER[:-1], "--ray", "--stats", str(stats)])
    assert rc == 2
    doc = json.loads(stats.read_text())["ray"]
    assert doc["frames_done"] == 7 and doc["frames_failed"] == 1 and doc["retried"] == 0
    assert doc["failures"][0]["frame"] == 5.0
    assert "directory" in doc["failures"][0]["error"]
    err = capsys.readouterr().err
    assert "frame 5 failed" in err and "7 frames done, 1 failed, 0 retried" in err

    # --skip-existing resumes: only the missing frame is rendered
    (tmp_path / "f.0005.exr").rmdir()
    rc = stb_main(
        ["render", str(scene), str(out), *RENDER, "--ray", "--skip-existing", "--stats", str(stats)]
    )
    assert rc == 0
    doc = json.loads(stats.read_text())["ray"]
    assert doc["frames_done"] == 1 and doc["frames_skipped"] == 7


def test_a_worker_that_cannot_set_up_says_why(local_ray, scene, tmp_path, capsys):
    out = tmp_path / "f.####.exr"
    rc = stb_main(["render", str(scene), str(out), *RENDER, "--ray", "--camera", "/Nope"])
    assert rc == 2
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("stb: error:")]
    assert len(err) == 1 and "/Nope" in err[0] and "Ray worker on" in err[0]
    assert not list(tmp_path.glob("f.*.exr"))


def _library(root: Path, testdata: Path) -> Path:
    """The validate test library (every planted problem, references, instancers)
    plus copies of its prefabs: about 40 assets."""
    sys.path.insert(0, str(Path(__file__).parent))
    from validate_fixtures import build_library

    build_library(root, testdata / "ies")
    copies = root / "copies"
    copies.mkdir()
    for p in sorted((root / "prefabs").glob("*.usda")):
        shutil.copy(p, copies / p.name)
    return root


def _findings(doc: dict) -> list:
    return [
        (a["path"], sorted(json.dumps(f, sort_keys=True) for f in a["findings"]))
        for a in doc["assets"]
    ]


def test_validate_on_ray_gives_the_local_findings(local_ray, testdata, tmp_path):
    lib = _library(tmp_path / "lib", testdata)
    loc, dist = tmp_path / "local.json", tmp_path / "ray.json"
    common = ["validate", str(lib), "--library-root", str(lib), "--quiet"]
    rc_local = stb_main([*common, "--jobs", "0", "--json", str(loc)])
    rc_ray = stb_main([*common, "--ray", "--json", str(dist)])
    assert rc_local == rc_ray == 1  # the planted problems are errors
    a, b = json.loads(loc.read_text()), json.loads(dist.read_text())
    assert len(a["assets"]) >= 40
    assert _findings(a) == _findings(b)
    assert sum(len(x["findings"]) for x in b["assets"]) > 40


def test_validate_on_ray_a_crashing_asset_is_a_crash_finding(local_ray, tmp_path, monkeypatch):
    from stb_hydra.validate.common import CRASH_HOOK_ENV
    from stb_hydra.validate.synth import clean_prefab

    lib = tmp_path / "lib"
    for name in ("a_ok", "b_segv_me", "c_ok"):
        clean_prefab(2).write(lib / f"{name}.usda")
    monkeypatch.setenv(CRASH_HOOK_ENV, "segv:segv_me")
    out = tmp_path / "r.json"
    rc = stb_main(["validate", str(lib), "--ray", "--quiet", "--json", str(out)])
    assert rc == 1
    by = {Path(a["path"]).stem: a for a in json.loads(out.read_text())["assets"]}
    assert by["b_segv_me"]["status"] == "crash"
    assert [f["rule"] for f in by["b_segv_me"]["findings"]] == ["crash"]
    assert "Ray worker died" in by["b_segv_me"]["findings"][0]["message"]
    assert by["a_ok"]["status"] == by["c_ok"]["status"] == "ok"


def test_unreachable_address_fails_fast_with_one_line(scene, tmp_path):
    with socket.socket() as s:  # a free port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    t0 = time.monotonic()
    res = subprocess.run(
        [sys.executable, "-m", "stb_hydra.apps.cli", "render", str(scene),
         str(tmp_path / "f.####.exr"), *RENDER, "--ray", f"127.0.0.1:{port}"],
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    took = time.monotonic() - t0
    assert res.returncode == 2
    lines = res.stderr.strip().splitlines()
    assert lines == [
        f"stb: error: cannot reach Ray cluster at 127.0.0.1:{port}: connection refused"
    ]
    assert took < 15


def test_an_address_that_is_not_ray_times_out_in_seconds(monkeypatch):
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen()
    conns = []
    threading.Thread(target=lambda: conns.append(srv.accept()), daemon=True).start()
    monkeypatch.setattr(cluster, "PROBE_TIMEOUT_S", 2.0)
    t0 = time.monotonic()
    with pytest.raises(cluster.CliError, match="no Ray GCS answered within 2 s"):
        cluster.probe(f"127.0.0.1:{srv.getsockname()[1]}")
    assert time.monotonic() - t0 < 8
    srv.close()


def test_without_the_extra_one_line(scene, tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "ray", None)  # import ray -> ImportError
    rc = stb_main(["render", str(scene), str(tmp_path / "f.####.exr"), *RENDER, "--ray"])
    assert rc == 2
    assert capsys.readouterr().err.strip() == (
        "stb: error: --ray needs the ray extra: pip install 'stb_hydra[ray]'"
    )


def test_moving_camera_on_ray_gives_the_local_frames(local_ray, tmp_path, monkeypatch):
    """Issue 36: an orbit with a sliding box (8 frames, 64x36, 2 workers, default
    options: --temporal auto -> taa as locally): every frame within HDR-FLIP 0.01 of
    the local render's (with the default warm-up, from the first frame: the same
    bytes), also when a worker is killed in its run; ``ray.temporal`` says how."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tools"))
    from ray_taa import compare, moving_scene

    scene = tmp_path / "moving.usda"
    scene.write_text(moving_scene(8, lights=16))
    flags = ["--frames", "1:8", "--width", "64", "--height", "36", "--lighting", "stb", "-q"]
    local = tmp_path / "local"
    local.mkdir()
    assert stb_main(["render", str(scene), str(local / "f.####.exr"), *flags]) == 0
    killed: list[int] = []

    def kill_once(pool, slot, index):
        if not killed and index == 4:
            killed.append(index)
            ray.kill(slot.actor, no_restart=True)

    monkeypatch.setattr(dist_render, "on_dispatch", kill_once)
    for name in ("ray", "ray_killed"):
        if name == "ray":
            monkeypatch.setattr(dist_render, "on_dispatch", None)
        else:
            monkeypatch.setattr(dist_render, "on_dispatch", kill_once)
        d = tmp_path / name
        d.mkdir()
        stats = d / "stats.json"
        argv = ["render", str(scene), str(d / "f.####.exr"), *flags, "--ray", "--workers", "2"]
        assert stb_main([*argv, "--stats", str(stats)]) == 0
        rows = compare(local, d, 8)
        assert all(r["flip"] <= 0.01 for r in rows), rows
        assert all(r["identical"] for r in rows), rows  # exact warm-up: same bytes
        doc = json.loads(stats.read_text())["ray"]
        assert doc["temporal"]["mode"] == "taa" and doc["temporal"]["exact"]
        assert doc["frames_done"] == 8 and doc["frames_failed"] == 0
    assert killed


def test_moving_camera_with_accumulate_on_ray_gives_the_local_frames(local_ray, tmp_path):
    """Issue 36 item 3: ``--accumulate 3`` on a moving camera (``--temporal auto`` ->
    taa, each frame accumulating its samples into the history): the Ray frames are the
    local render's bytes, and ``ray.temporal`` records taa."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tools"))
    from ray_taa import compare, moving_scene

    scene = tmp_path / "moving.usda"
    scene.write_text(moving_scene(4, lights=8))
    flags = ["--frames", "1:4", "--width", "48", "--height", "27", "--lighting", "stb"]
    flags += ["--accumulate", "3", "-q"]
    for name in ("local", "ray"):
        (tmp_path / name).mkdir()
    assert stb_main(["render", str(scene), str(tmp_path / "local" / "f.####.exr"), *flags]) == 0
    stats = tmp_path / "ray" / "stats.json"
    argv = ["render", str(scene), str(tmp_path / "ray" / "f.####.exr"), *flags]
    assert stb_main([*argv, "--ray", "--workers", "2", "--stats", str(stats)]) == 0
    rows = compare(tmp_path / "local", tmp_path / "ray", 4)
    assert all(r["identical"] for r in rows), rows
    assert json.loads(stats.read_text())["ray"]["temporal"]["mode"] == "taa"
