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

PASSES = ("stb_bigtile", "stb_smalltile", "stb_terms", "stb_reuse_cur", "stb_lighting")


def render_in_turn(stage: str, settings: dict, frames: int) -> dict:
    """One engine per ``settings`` entry (name -> RenderSettings with ``profile``); each
    round renders one frame of every engine, so a shared machine's changing load falls
    on all alike. Returns name -> the engine's ``Timings`` (``frames``: one dict of
    per-pass wall ms per frame). ``tools/taa_cost.py`` uses it too."""
    from stb_hydra.renderer.engine import Engine

    engines = {name: Engine(stage, s) for name, s in settings.items()}
    try:
        for _ in range(frames):
            for eng in engines.values():
                eng.render()
    finally:
        for eng in engines.values():
            eng.release()
    return {name: eng.timings for name, eng in engines.items()}


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
    from stb_hydra.renderer.frame import RenderSettings

    w, h = (int(v) for v in a.size.split("x"))
    configs = [parse_config(c) for c in (a.config or ["defaults:", "ris:N=4,select=ris"])]
    settings = {
        name: RenderSettings(width=w, height=h, lighting="stb", profile=True, method_options=o)
        for name, o in configs
    }
    timings = render_in_turn(a.stage, settings, a.warmup + a.frames)
    times = {
        name: [[tf.get(f"lighting.{p}", 0.0) for p in PASSES] for tf in t.frames[a.warmup :]]
        for name, t in timings.items()
    }
    # The whole frame: every top-level phase and pass (names without a dot).
    frame_ms = {
        name: float(
            np.median(
                [sum(v for k, v in tf.items() if "." not in k) for tf in t.frames[a.warmup :]]
            )
        )
        for name, t in timings.items()
    }
    print(f"{a.stage} {w}x{h}, {a.frames} frames each (interleaved), load {os.getloadavg()[0]:.2f}")
    base = base_frame = None
    for name, rows in times.items():
        arr = np.asarray(rows)
        med = np.median(arr, axis=0)
        total = float(np.median(arr.sum(axis=1)))
        base = base or total
        base_frame = base_frame or frame_ms[name]
        passes = " ".join(f"{p[4:]}={v:.1f}" for p, v in zip(PASSES, med, strict=True))
        print(
            f"  {name:12s} {passes}  STB passes {total:.1f} ms ({total / base:.2f}x), "
            f"frame {frame_ms[name]:.1f} ms ({frame_ms[name] / base_frame:.2f}x)"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
