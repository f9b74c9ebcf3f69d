#!/usr/bin/env python3
"""STB's big-tile pass against the light count, interleaved in one process (issue 16).

Renders the generated lights scene at each light count in turn, frame by frame (so
machine-load drift hits every count alike), with ``ctx.finish()`` around every pass,
and prints the median ``lighting.stb_bigtile`` ms per count and mode and the ratio to
the first count:

    .venv/bin/python tools/bench_bigtile.py --lights 5000,50000 --size 745x360 \\
        --frames 15 --modes clusters,stream
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np


def main(argv: list[str] | None = None) -> int:
    from stb_hydra.renderer.engine import Engine
    from stb_hydra.renderer.frame import RenderSettings
    from stb_hydra.scenegen.lights import build_lights_stage

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--lights", default="5000,50000")
    ap.add_argument("--size", default="745x360")
    ap.add_argument("--frames", type=int, default=15)
    ap.add_argument("--modes", default="clusters,stream")
    ap.add_argument("--K", type=int, default=64)
    a = ap.parse_args(argv)
    w, h = (int(v) for v in a.size.lower().split("x"))
    counts = [int(c) for c in a.lights.split(",")]
    modes = a.modes.split(",")
    tmp = Path(tempfile.mkdtemp())
    engines = {}
    for n in counts:
        path = tmp / f"lights{n}.usda"
        build_lights_stage(n, seed=1, path=path)
        for m in modes:
            s = RenderSettings(
                width=w,
                height=h,
                lighting="stb",
                profile=True,
                method_options={"bigtile": m, "K": a.K},
            )
            engines[(n, m)] = Engine(str(path), s)
    ms: dict[tuple[int, str], list[float]] = {k: [] for k in engines}
    cpu: dict[tuple[int, str], list[float]] = {k: [] for k in engines}
    rebuilt: dict[tuple[int, str], int] = {k: 0 for k in engines}
    try:
        for i in range(a.frames + 2):
            for k, eng in engines.items():
                frame = eng.render_frame()
                if i >= 2:  # compile and first upload excluded
                    t = eng.timings.frames[-1]
                    ms[k].append(t.get("lighting.stb_bigtile", 0.0))
                    cpu[k].append(t.get("lighting.stb_clusters", 0.0))
                    rebuilt[k] += int(frame.stats.get("stb_clusters_rebuilt", 0))
    finally:
        for eng in engines.values():
            eng.release()
    for m in modes:
        base = float(np.median(ms[(counts[0], m)]))
        for n in counts:
            med = float(np.median(ms[(n, m)]))
            c = float(np.median(cpu[(n, m)]))
            print(
                f"{m:9s} {n:7d} lights: big-tile pass {med:8.2f} ms (x{med / base:.2f}); "
                f"cluster build (CPU) {c:.2f} ms, rebuilt in {rebuilt[(n, m)]} of {a.frames} frames"
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
