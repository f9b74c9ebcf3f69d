#!/usr/bin/env python3
"""Benchmark ``stb validate`` on a generated 1,000-prefab library.

Writes N prefab layers (default 1000) into a temp dir -- each a small .usda with a
ground quad, a box and 1-20 sphere lights (``stb_hydra.validate.synth``), about 60 %
clean and 40 % with one planted problem drawn from ``synth.PLANTS`` -- then times

    python -m stb_hydra.apps.cli validate DIR --jobs J --json DIR/report.json --quiet

(no thumbnails) in a subprocess, and checks that every planted problem was found
(and nothing on the clean prefabs). Prints the wall time, per-asset throughput, the
1-minute load average before and after (the machine may be shared), and the findings
per rule. Target: <= 60 s for 1000 prefabs with --jobs 2 on 2 cores.

    .venv/bin/python tools/bench_validate.py [--n 1000] [--jobs 2] [--repeat 2] [--keep DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import random
import shutil
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SHARED = Path(os.environ.get("STB_SHARED", REPO.parent / "shared")).resolve()


def generate(lib: Path, n: int, seed: int, clean_share: float = 0.6) -> dict[str, set]:
    """Write ``n`` prefabs under ``lib/prefabs``; returns file name -> expected stb
    (rule, prim) set."""
    from stb_hydra.validate.synth import PLANTS, clean_prefab

    rng = random.Random(seed)
    ies_src = SHARED / "testdata" / "ies"
    names = list(PLANTS)
    expected: dict[str, set] = {}
    for i in range(n):
        if rng.random() < clean_share:
            k = rng.randint(1, 20)
            p = clean_prefab(k, shadowed=min(2, k))
            kind = "clean"
            exp: set = set()
        else:
            kind = rng.choice(names)
            k = rng.randint(4, 20)
            p = clean_prefab(k, shadowed=2)
            PLANTS[kind].plant(p, lib, ies_src)
            exp = set(PLANTS[kind].expect)
        fname = f"p{i:04d}_{kind}.usda"
        p.write(lib / "prefabs" / fname)
        expected[fname] = exp
    return expected


def run_once(lib: Path, jobs: int) -> tuple[float, int, dict, tuple[float, float]]:
    report = lib / "report.json"
    cmd = [
        sys.executable,
        "-m",
        "stb_hydra.apps.cli",
        "validate",
        str(lib),
        "--jobs",
        str(jobs),
        "--json",
        str(report),
        "--quiet",
    ]
    load0 = os.getloadavg()[0]
    t = time.perf_counter()
    proc = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True)
    wall = time.perf_counter() - t
    load1 = os.getloadavg()[0]
    if proc.returncode not in (0, 1):
        sys.exit(f"stb validate failed ({proc.returncode}): {proc.stderr.strip()[-2000:]}")
    return wall, proc.returncode, json.loads(report.read_text()), (load0, load1)


def check(doc: dict, expected: dict[str, set]) -> list[str]:
    bad = []
    for a in doc["assets"]:
        name = Path(a["path"]).name
        if name not in expected:
            continue
        got = {(f["rule"], f["prim"]) for f in a["findings"] if ":" not in f["rule"]}
        if got != expected[name]:
            bad.append(f"{name}: {sorted(got)} != {sorted(expected[name])}")
    return bad


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--n", type=int, default=1000, help="prefabs (default 1000)")
    ap.add_argument("--jobs", type=int, default=2, help="stb validate --jobs (default 2)")
    ap.add_argument("--repeat", type=int, default=1, help="timed runs (default 1)")
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--keep", metavar="DIR", help="generate into DIR and keep it")
    args = ap.parse_args(argv)

    tmp = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="stb-bench-val-"))
    lib = tmp / "lib"
    if lib.exists():
        shutil.rmtree(lib)
    try:
        t = time.perf_counter()
        expected = generate(lib, args.n, args.seed)
        gen_s = time.perf_counter() - t
        planted = sum(1 for e in expected.values() if e)
        print(
            f"generated {args.n} prefabs ({planted} with a planted problem, "
            f"{args.n - planted} clean) in {gen_s:.1f} s under {lib}"
        )
        print(
            f"cpus: {os.cpu_count()}; command: stb validate {lib} --jobs {args.jobs} "
            "--json report.json --quiet"
        )
        doc = None
        for r in range(args.repeat):
            wall, code, doc, (l0, l1) = run_once(lib, args.jobs)
            print(
                f"run {r + 1}: {wall:.1f} s wall ({wall / args.n * 1000:.1f} ms/asset), "
                f"exit {code}, load average (1 min) {l0:.2f} before, {l1:.2f} after"
            )
        assert doc is not None
        bad = check(doc, expected)
        rules = Counter(f["rule"] for a in doc["assets"] for f in a["findings"])
        status = Counter(a["status"] for a in doc["assets"])
        per_asset = sorted(a["timings"].get("total", 0.0) for a in doc["assets"])
        print(
            f"status: {dict(status)}; per-asset in-worker time median "
            f"{per_asset[len(per_asset) // 2] * 1000:.1f} ms, max {per_asset[-1] * 1000:.0f} ms"
        )
        print("findings per rule: " + ", ".join(f"{k} {v}" for k, v in rules.most_common()))
        if bad:
            print(f"MISMATCH on {len(bad)} prefabs:\n  " + "\n  ".join(bad[:20]))
            return 1
        print("every planted problem found where planted; clean prefabs clean")
        return 0
    finally:
        if not args.keep:
            shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
