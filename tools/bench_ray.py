"""``--ray`` on this machine, 1 -> 2 workers (docs/PERFORMANCE.md, "Ray").

Starts one private Ray instance (``ray.init(address="local", num_cpus=2)``; its start is
not counted), then:

* render: the courtyard, ``--frames 1:F`` at 745x360, STB, ``--accumulate 4``: locally,
  and on Ray with 1 worker, 1 worker x 2 CPUs and 2 workers (the driver's ``ray.wall_s``,
  the mean frame ``wall_ms``, the median per-frame scheduling overhead); each Ray run's
  files compared with the local run's (bytes, but the EXR ``capDate`` stamp);
* validate: the test library (``tests/validate_fixtures.py``) plus 7 copies of its
  prefabs (190 assets), with and without thumbnails: the local pool with 1 and 2
  workers and Ray with 1 and 2 assets in flight (after an untimed Ray pass over 8
  assets, so that Ray's worker processes have imported USD); findings of Ray == local.

    .venv/bin/python tools/bench_ray.py [--frames 24] [--out DIR]
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared"
_CAPDATE = re.compile(rb"capDate\x00string\x00\x13\x00\x00\x00[0-9: ]{19}")


def _same(a: Path, b: Path) -> list[str]:
    """Names of a's EXR files whose bytes (but capDate) differ in b."""
    return [
        p.name
        for p in sorted(a.glob("*.exr"))
        if _CAPDATE.sub(b"", p.read_bytes()) != _CAPDATE.sub(b"", (b / p.name).read_bytes())
    ]


def bench_render(out: Path, frames: int) -> list[dict]:
    from stb_hydra.apps.cli import main as stb

    scene = str(REPO / "usd_scenes" / "default.usda")
    flags = ["--frames", f"1:{frames}", "--width", "745", "--height", "360"]
    flags += ["--lighting", "stb", "--accumulate", "4", "--quiet"]
    runs = [
        ("local", []),
        ("ray 1 worker", ["--ray", "--workers", "1"]),
        ("ray 1 worker x 2 CPUs", ["--ray", "--workers", "1", "--worker-cpus", "2"]),
        ("ray 2 workers", ["--ray", "--workers", "2"]),
    ]
    rows = []
    for name, extra in runs:
        d = out / name.replace(" ", "_")
        d.mkdir(parents=True)
        stats = d / "stats.json"
        t0 = time.perf_counter()
        rc = stb(["render", scene, str(d / "f.####.exr"), *flags, *extra, "--stats", str(stats)])
        wall = time.perf_counter() - t0
        doc = json.loads(stats.read_text())
        ms = [f["wall_ms"] for f in doc["frames"]]
        ray = doc.get("ray", {})
        row = {
            "run": name,
            "rc": rc,
            "wall_s": ray.get("wall_s", round(wall, 2)),
            "frame_ms_mean": round(sum(ms) / len(ms), 1),
            "overhead_ms_median": (ray.get("scheduling_overhead_ms") or {}).get("median"),
        }
        if extra:
            row["differ_from_local"] = _same(out / "local", d)
        rows.append(row)
        print(json.dumps(row), flush=True)
    return rows


def bench_validate(out: Path) -> list[dict]:
    sys.path.insert(0, str(REPO / "tests"))
    from validate_fixtures import build_library

    from stb_hydra.apps.validate import collect_inputs
    from stb_hydra.distributed.validate import run_on_ray
    from stb_hydra.validate.parallel import run_parallel

    lib = out / "lib"
    build_library(lib, SHARED / "testdata" / "ies")
    prefabs = sorted((lib / "prefabs").glob("*.usda"))
    for k in range(7):
        (lib / f"copies{k}").mkdir()
        for p in prefabs:
            shutil.copy(p, lib / f"copies{k}" / p.name)
    tasks = collect_inputs([str(lib)], str(lib))

    def key(reps):
        return [
            (r.path, sorted(json.dumps(f, sort_keys=True) for f in r.to_dict()["findings"]))
            for r in reps
        ]

    run_on_ray(None, tasks[:8], in_flight=2)  # untimed: Ray's worker processes import once
    rows = []
    for thumbs in (False, True):
        ref = None
        for name, n in (("local", 1), ("local", 2), ("ray", 1), ("ray", 2)):
            t0 = time.perf_counter()
            if name == "local":
                reps = run_parallel(tasks, n, thumbnails=thumbs)
            else:
                reps, _ = run_on_ray(None, tasks, thumbnails=thumbs, in_flight=n)
            wall = time.perf_counter() - t0
            ref = ref or key(reps)
            row = {
                "validate": name,
                "workers": n,
                "thumbnails": thumbs,
                "assets": len(tasks),
                "findings": sum(len(r.findings) for r in reps),
                "same_findings": key(reps) == ref,
                "wall_s": round(wall, 2),
            }
            rows.append(row)
            print(json.dumps(row), flush=True)
    return rows


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=24)
    ap.add_argument("--out", help="keep the files here (default: a temporary directory)")
    a = ap.parse_args()
    import ray

    out = Path(a.out or tempfile.mkdtemp(prefix="stb-bench-ray-"))
    ray.init(address="local", num_cpus=2, include_dashboard=False, log_to_driver=False)
    try:
        bench_render(out / "render", a.frames)
        bench_validate(out / "validate")
    finally:
        ray.shutdown()
        if not a.out:
            shutil.rmtree(out, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
