#!/usr/bin/env python3
"""Light sync from stage open to the first frame, and a one-light edit (issue 34 item 4).

For each light count (default 10,000 and 50,000; ``stb_hydra.scenegen.lights`` scenes,
mixed types with cones, IES profiles, colour temperatures and shadows, written to a
temp .usda first -- generation is not timed), in a fresh process each:

* ``open``: ``Usd.Stage.Open``;
* ``engine``: ``Engine(stage)`` -- scene index population, the first sync of every
  light (bulk read, ``scene/lights_bulk.py``) and the light table -- with the GL
  context already made (context creation is timed apart as ``gl``);
* ``first_frame``: the first ``render()`` at ``--size`` (sun-only lighting by default:
  the frame's light work is the light buffer, not a light loop), ``ctx.finish()``;
* ``stage_to_frame``: open + engine + first frame;
* ``cpu_open_engine``: the process's CPU time over open + engine (less sensitive than
  wall clock to other jobs on a shared machine; the sync is single-threaded Python);
* ``edit``: median over ``--edits`` lights of an ``inputs:intensity`` edit through
  ``apply_pending_updates()`` + ``sync_all()``, and how many light-table rows it rewrote
  (must be 1).

    .venv/bin/python tools/bench_light_sync.py [--counts 10000,50000] [--lighting sun]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

_CHILD = r"""
import json, statistics, sys, time
import numpy as np
from pxr import Usd
import stb_hydra
from stb_hydra.renderer.engine import Engine
from stb_hydra.renderer.gl import get_context
from stb_hydra.renderer.frame import RenderSettings

path, lighting = sys.argv[1], sys.argv[2]
w, h, edits = int(sys.argv[3]), int(sys.argv[4]), int(sys.argv[5])
if sys.argv[6] == "single":  # the light-by-light reader (the bulk path never runs)
    import stb_hydra.renderer.render_index as _ri
    _ri.MIN_BULK_LIGHTS = 10**12
t0 = time.perf_counter(); ctx = get_context(); ctx.finish(); t_gl = time.perf_counter() - t0
c0 = time.process_time()
t0 = time.perf_counter(); stage = Usd.Stage.Open(path); t_open = time.perf_counter() - t0
t0 = time.perf_counter()
eng = Engine(stage, RenderSettings(width=w, height=h, lighting=lighting, shadows=False), ctx=ctx)
t_engine = time.perf_counter() - t0
cpu_engine = time.process_time() - c0  # open + engine, CPU seconds of this process
t0 = time.perf_counter(); eng.render(); ctx.finish(); t_frame = time.perf_counter() - t0
table = eng.delegate.light_table
si, ri = eng.scene_index, eng.render_index
lights = sorted(table.rows)[:: max(1, len(table.rows) // edits)][:edits]
times, rows = [], []
for p in lights:
    attr = stage.GetPrimAtPath(p).GetAttribute("inputs:intensity")
    v0 = table.cols["version"][: table.n_rows].copy()
    t0 = time.perf_counter()
    attr.Set(float(attr.Get() or 1.0) * 1.5)
    si.apply_pending_updates()
    ri.sync_all()
    times.append(time.perf_counter() - t0)
    rows.append(int(np.count_nonzero(table.cols["version"][: table.n_rows] != v0)))
print(json.dumps({"lights": len(table.rows), "gl": t_gl, "open": t_open, "engine": t_engine,
                  "first_frame": t_frame, "stage_to_frame": t_open + t_engine + t_frame,
                  "cpu_open_engine": cpu_engine,
                  "edit_ms": statistics.median(times) * 1e3, "edit_rows": max(rows)}))
"""


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--counts", default="10000,50000")
    ap.add_argument("--lighting", default="sun")
    ap.add_argument("--size", default="160x90")
    ap.add_argument("--edits", type=int, default=20)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--json", type=Path, default=None)
    ap.add_argument(
        "--single", action="store_true", help="also time the light-by-light reader (before)"
    )
    args = ap.parse_args(argv)
    from stb_hydra.scenegen.lights import build_lights_stage

    w, h = (int(v) for v in args.size.split("x"))
    results = []
    with tempfile.TemporaryDirectory() as tmp:
        for n in (int(c) for c in args.counts.split(",")):
            path = Path(tmp) / f"lights_{n}.usda"
            build_lights_stage(n_lights=n, seed=args.seed, path=path)
            cmd = [sys.executable, "-c", _CHILD, str(path), args.lighting, str(w), str(h)]
            for reader in ("single", "bulk") if args.single else ("bulk",):
                out = subprocess.run(
                    [*cmd, str(args.edits), reader], check=True, capture_output=True, text=True
                ).stdout
                r = json.loads(out.strip().splitlines()[-1])
                r["load"] = round(os.getloadavg()[0], 2)
                r["reader"] = reader
                results.append(r)
                _report(n, r)
    if args.json:
        args.json.write_text(json.dumps(results, indent=1) + "\n")
    return 0


def _report(n: int, r: dict) -> None:
    print(
        f"{n:>7} lights, {r['reader']}: open {r['open']:.2f} s, engine (populate + sync) "
        f"{r['engine']:.2f} s, first frame {r['first_frame']:.2f} s -> stage to frame "
        f"{r['stage_to_frame']:.2f} s; edit {r['edit_ms']:.2f} ms "
        f"({r['edit_rows']} row); GL context {r['gl']:.2f} s; CPU time of open + engine "
        f"{r['cpu_open_engine']:.2f} s; load {r['load']}",
        flush=True,
    )


if __name__ == "__main__":
    t = time.perf_counter()
    rc = main()
    print(f"({time.perf_counter() - t:.0f} s)", file=sys.stderr)
    sys.exit(rc)
