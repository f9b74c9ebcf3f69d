"""Per-frame shadow-capture trace of an ``stb bench`` run (issue 16, face-granular
captures): runs the bench with the given arguments and prints, over the measured frames
that rendered any capture (some faces of a split map included), the capture pass time
(median / p95 / max, fraction within budget + 20 %) against the scheduler's *planned*
milliseconds, and when every map was first fresh.

    PYTHONPATH=$PWD python tools/trace_shadow_budget.py OUT_TRACE.json gen:chess:500 \\
        --methods stb --size 745x360 --shadow-budget-ms 300 --frames 170 --warmup 0 \\
        --json OUT.json

(``bench`` is implied; the trace, one row per measured frame, goes to OUT_TRACE.json.)
"""

from __future__ import annotations

import json
import sys
from typing import Any

import numpy as np

from stb_hydra.apps import bench_core, cli


def main(argv: list[str]) -> int:
    out, bench_args = argv[0], argv[1:]
    runs: list[dict[str, Any]] = []
    measure = bench_core.measure_engine

    def traced(*a: Any, **k: Any) -> bench_core.Measurement:
        m = measure(*a, **k)
        rows = [
            {
                "capture_ms": p.get("shadow_atlas", 0.0),
                "planned_ms": st.get("shadow_ms_planned", 0.0),
                "maps": st.get("shadow_maps_updated", 0),
                "texels": st.get("shadow_texels_rendered", 0),
                "stale": st.get("shadow_stale_maps", -1),
                "partial": st.get("shadow_partial_maps", 0),
                "budget_ms": st.get("shadow_budget_ms"),
            }
            for p, st in zip(m.passes, m.frame_stats)
        ]
        runs.append({"frames": rows, "all_fresh": [m.all_fresh_frame, m.all_fresh_s]})
        return m

    bench_core.measure_engine = traced  # the bench looks it up at call time
    rc = cli.main(["bench", *bench_args])
    with open(out, "w") as f:
        json.dump(runs, f)
    for run in runs:
        cap = [r for r in run["frames"] if r["maps"] or r["texels"]]
        if not cap:
            continue
        a = np.array([r["capture_ms"] for r in cap])
        p = np.array([r["planned_ms"] for r in cap])
        b = cap[0]["budget_ms"]
        within = f"{np.mean(a <= 1.2 * b):.1%}" if b else "-"
        print(
            f"capturing frames {len(cap)} ({sum(1 for r in cap if r['partial'])} with a split"
            f" map in progress); capture ms median / p95 / max {np.median(a):.0f} /"
            f" {np.percentile(a, 95):.0f} / {a.max():.0f}; within budget + 20 % {within};"
            f" planned ms max {p.max():.1f}; measured / planned median"
            f" {np.median(a / np.maximum(p, 1e-9)):.2f}; every map fresh (frame, s)"
            f" {run['all_fresh']}"
        )
    return rc


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
