#!/usr/bin/env python3
"""Benchmark the renderer's per-frame CPU overhead and per-task wall times.

1. CPU overhead with ``--lights`` (10,000) lights, scene unchanged between frames
   (``stb_hydra.scenegen.lights``, no animation): medians over
   ``--overhead-frames`` (30) frames after ``--warmup`` of the engine's CPU
   phases -- ``sync``, ``commit``, ``prepare``, ``prepare.light_cull`` (frustum
   culling) and ``prepare.light_upload`` (light buffer upload, where the engine has it)
   -- and of the whole CPU part of the frame (frame wall time minus the finished
   GPU tasks). Steady frames (no upload) and frames that re-upload the whole
   light buffer (e.g. while shadow maps get assigned) are reported apart.
   Target: cull + upload <= 2 ms (both kinds of frame). Rendered small
   (``--overhead-size``, 256x144) with ``--overhead-method`` (sun) so the GPU
   part stays out of the way.
2. Per-task wall times (``RenderSettings(profile=True)``: ``ctx.finish()`` after
   every task) for ``--methods`` (reference, sun) at ``--size`` (745x360) with
   ``--counts`` (50 and 500) lights: medians over ``--frames`` after ``--warmup``.

Timing loop: ``stb_hydra.apps.bench_core.measure_engine`` (the one ``stb bench``
uses). Prints tables and the 1-minute load average (the machine may be shared),
optionally ``--json FILE``.

    .venv/bin/python tools/bench_render_overhead.py [--lights 10000] [--frames 10] [--json f]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

CULL_UPLOAD_TARGET_MS = 2.0


def _size(text: str) -> tuple[int, int]:
    w, _, h = text.lower().partition("x")
    return int(w), int(h)


def _engine(stage, method: str, size: tuple[int, int]):
    from stb_hydra import limits
    from stb_hydra.renderer.engine import Engine
    from stb_hydra.renderer.frame import RenderSettings

    return Engine(
        stage,
        RenderSettings(
            width=size[0],
            height=size[1],
            lighting=method,
            profile=True,
            shadow_budget=limits.SHADOW_UPDATE_BUDGET_TEXELS_DEFAULT,  # real time
        ),
    )


def overhead(args) -> dict:
    """Part 1: CPU phases with many lights, nothing changing. Frames that re-upload
    the light buffer (the shadow atlas assigning maps during the first frames) are
    reported apart from the steady state."""
    from stb_hydra.apps.bench_core import load_average, measure_engine, median, median_dict
    from stb_hydra.scenegen.lights import build_lights_stage

    stage = build_lights_stage(n_lights=args.lights, seed=args.seed, animated=0)
    eng = _engine(stage, args.overhead_method, _size(args.overhead_size))
    try:
        load = load_average()
        m = measure_engine(eng, frames=args.overhead_frames, warmup=args.warmup)
        scene_lights = int(eng.delegate.light_table.local_mask().sum())
    finally:
        eng.release()
    s = m.summary()
    up = [bool(f.get("light_upload")) for f in m.frame_stats]
    steady = median_dict([t for t, u in zip(m.timings, up) if not u] or m.timings)
    upload = [t for t, u in zip(m.timings, up) if u]

    def cull_upload(t: dict) -> float:
        return t.get("prepare.light_cull", 0.0) + t.get("prepare.light_upload", 0.0)

    with_upload = median([cull_upload(t) for t in upload]) if upload else None
    worst = max(cull_upload(steady), with_upload or 0.0)
    return {
        "lights": scene_lights,
        "fov_lights": int(m.stats.get("fov_lights", 0)),
        "method": args.overhead_method,
        "size": args.overhead_size,
        "frames": len(up),
        "light_uploads": sum(up),
        "sync_ms": steady.get("sync", 0.0),
        "commit_ms": steady.get("commit", 0.0),
        "prepare_ms": steady.get("prepare", 0.0),
        "cull_ms": steady.get("prepare.light_cull", 0.0),
        "upload_ms": steady.get("prepare.light_upload"),
        "cull_upload_ms": cull_upload(steady),
        "cull_full_upload_ms": with_upload,
        "cpu_frame_ms": s["cpu_ms"],
        "target_cull_upload_ms": CULL_UPLOAD_TARGET_MS,
        "target_met": worst <= CULL_UPLOAD_TARGET_MS,
        "timings": steady,
        "load_avg": load,
    }


def task_times(args) -> list[dict]:
    """Part 2: per-task medians for each method x light count."""
    from stb_hydra.apps.bench_core import load_average, measure_engine
    from stb_hydra.scenegen.lights import build_lights_stage

    out = []
    size = _size(args.size)
    for n in (int(c) for c in args.counts.split(",") if c.strip()):
        stage = build_lights_stage(n_lights=n, seed=args.seed, animated=0)
        for method in (m.strip() for m in args.methods.split(",") if m.strip()):
            print(f"... {method}, {n} lights, {args.size}", file=sys.stderr, flush=True)
            eng = _engine(stage, method, size)
            try:
                load = load_average()
                m = measure_engine(eng, frames=args.frames, warmup=args.warmup)
            finally:
                eng.release()
            s = m.summary()
            out.append(
                {
                    "method": method,
                    "lights": n,
                    "fov_lights": m.stats.get("fov_lights"),
                    "size": args.size,
                    "frame_ms": s["frame_ms"],
                    "cpu_ms": s["cpu_ms"],
                    "passes": s["passes"],
                    "load_avg": load,
                }
            )
    return out


def print_overhead(r: dict) -> None:
    up = "n/a (inside cull)" if r["upload_ms"] is None else f"{r['upload_ms']:.3f}"
    full = r["cull_full_upload_ms"]
    print(
        f"CPU overhead, {r['lights']} lights ({r['fov_lights']} in view), unchanged scene, "
        f"{r['method']} @ {r['size']} (medians, ms):"
    )
    print(
        f"  steady ({r['frames'] - r['light_uploads']} of {r['frames']} frames, no light "
        f"upload): sync {r['sync_ms']:.3f}  commit {r['commit_ms']:.3f}  prepare "
        f"{r['prepare_ms']:.3f}  (cull {r['cull_ms']:.3f}, upload check {up})"
    )
    print(
        f"  cull + upload: steady {r['cull_upload_ms']:.3f}, frames that upload light "
        f"records ({r['light_uploads']}): "
        + ("-" if full is None else f"{full:.3f}")
        + f" (target <= {CULL_UPLOAD_TARGET_MS:g}: {'ok' if r['target_met'] else 'MISSED'})"
    )
    print(f"  whole CPU part of the frame {r['cpu_frame_ms']:.3f} ms; load {r['load_avg']}")
    subs = sorted(
        ((k, v) for k, v in r["timings"].items() if k.startswith("prepare.")), key=lambda kv: -kv[1]
    )[:4]
    print("  largest prepare steps: " + ", ".join(f"{k} {v:.3f}" for k, v in subs))


def print_tasks(rows: list[dict]) -> None:
    keys = list(dict.fromkeys(k for r in rows for k in r["passes"]))
    head = ["method", "lights", "frame", "cpu", *keys]
    print("Per-task wall times (medians, ms, ctx.finish() after every task):")
    print(" ".join(f"{h:>12}" for h in head))
    for r in rows:
        vals = [r["method"], f"{r['lights']}", f"{r['frame_ms']:.2f}", f"{r['cpu_ms']:.2f}"]
        vals += [f"{r['passes'].get(k, 0.0):.2f}" for k in keys]
        print(" ".join(f"{v:>12}" for v in vals))
    print("load average (1 min) per run: " + ", ".join(str(r["load_avg"]) for r in rows))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--lights", type=int, default=10_000, help="lights for the CPU overhead")
    ap.add_argument("--overhead-method", default="sun")
    ap.add_argument("--overhead-size", default="256x144")
    ap.add_argument("--overhead-frames", type=int, default=30, help="frames for part 1")
    ap.add_argument("--methods", default="reference,sun", help="methods for per-task times")
    ap.add_argument("--counts", default="50,500", help="light counts for per-task times")
    ap.add_argument("--size", default="745x360", help="resolution for per-task times")
    ap.add_argument("--frames", type=int, default=10, help="measured frames (median)")
    ap.add_argument("--warmup", type=int, default=2, help="warm-up frames")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--skip-overhead", action="store_true")
    ap.add_argument("--skip-tasks", action="store_true")
    ap.add_argument("--json", help="write the results here")
    args = ap.parse_args(argv)
    result: dict = {}
    if not args.skip_overhead:
        result["overhead"] = overhead(args)
        print_overhead(result["overhead"])
    if not args.skip_tasks:
        result["tasks"] = task_times(args)
        print_tasks(result["tasks"])
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
