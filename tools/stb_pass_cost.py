#!/usr/bin/env python3
"""STB pass times of several option sets, rendered frame by frame in turn.

One engine per configuration, all in one process; every round renders one frame of
each, so a shared machine's load falls on all of them alike (read the ratios). Per
pass: median wall ms with ``ctx.finish()`` after each pass (the engine's profile).

    python tools/stb_pass_cost.py usd_scenes/default.usda \\
        --config defaults: --config "ris:N=4,select=ris" --frames 8
"""

from __future__ import annotations

import argparse
import os
import sys

import numpy as np

PASSES = ("stb_bigtile", "stb_smalltile", "stb_terms", "stb_lighting")


def parse_config(text: str) -> tuple[str, dict[str, str]]:
    """``NAME:K=V,K=V`` -> (NAME, options); ``NAME:`` is the defaults."""
    name, _, rest = text.partition(":")
    opts = dict(kv.split("=", 1) for kv in rest.split(",") if kv)
    return name or "defaults", opts


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("stage")
    ap.add_argument("--config", action="append", default=[], help="NAME:K=V,... (repeatable)")
    ap.add_argument("--size", default="745x360")
    ap.add_argument("--frames", type=int, default=8)
    ap.add_argument("--warmup", type=int, default=2)
    a = ap.parse_args(argv)
    from stb_hydra.renderer.engine import Engine
    from stb_hydra.renderer.frame import RenderSettings

    w, h = (int(v) for v in a.size.split("x"))
    configs = [parse_config(c) for c in (a.config or ["defaults:", "ris:N=4,select=ris"])]
    engines = {
        name: Engine(
            a.stage,
            RenderSettings(width=w, height=h, lighting="stb", profile=True, method_options=o),
        )
        for name, o in configs
    }
    times: dict[str, list[list[float]]] = {name: [] for name in engines}
    try:
        for i in range(a.warmup + a.frames):
            for name, eng in engines.items():
                eng.render()
                tf = eng.timings.frames[-1]
                if i >= a.warmup:
                    times[name].append([tf.get(f"lighting.{p}", 0.0) for p in PASSES])
    finally:
        for eng in engines.values():
            eng.release()
    print(f"{a.stage} {w}x{h}, {a.frames} frames each (interleaved), load {os.getloadavg()[0]:.2f}")
    base = None
    for name, rows in times.items():
        arr = np.asarray(rows)
        med = np.median(arr, axis=0)
        total = float(np.median(arr.sum(axis=1)))
        base = base or total
        passes = " ".join(f"{p[4:]}={v:.1f}" for p, v in zip(PASSES, med, strict=True))
        print(f"  {name:12s} {passes}  STB passes {total:.1f} ms ({total / base:.2f}x)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
