#!/usr/bin/env python3
"""Benchmark the scene index + render index (CPU, no GL) on many-light stages.

For each light count (default 10,000 and 100,000; ``stb_hydra.scenegen.lights``
scenes with 100 animated lights, written to a temp .usda first -- generation is
not timed):

* open: ``Usd.Stage.Open`` of the file;
* first sync: ``StageSceneIndex(stage)`` (traverse + extract) +
  ``RenderIndex(si, RenderDelegate()).sync_all()``;
* one-light edit, median of ``--repeat`` (20) edits of different static lights:
  ``inputs:intensity`` edit, and a move (``xformOp:translate``), each timed
  from the USD ``Set`` through ``apply_pending_updates()`` + ``sync_all()``
  (the sync alone is reported too); every edit must sync exactly one prim;
* per-frame ``set_time`` + ``sync_all()`` over ``--frames`` (40) distinct times,
  median; with 100 animated lights exactly 100 prims must sync per frame.

Targets (10,000 lights): open + first sync <= 3 s, one edit <= 5 ms, per-frame
set_time <= 5 ms. Prints a table and the 1-minute load average (the machine may
be shared; timings are wall clock), optionally ``--json FILE``.

    .venv/bin/python tools/bench_scene_index.py [--counts 10000,100000] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

TARGETS_10K_MS = {
    "open_first_sync": 3000.0,
    "edit_intensity": 5.0,
    "edit_move": 5.0,
    "set_time": 5.0,
}


def _ms(t0: float) -> float:
    return (time.perf_counter() - t0) * 1e3


def _load() -> float:
    return round(os.getloadavg()[0], 2)


def first_sync(path: Path) -> tuple[dict[str, float], object, object, object]:
    """Open + index + first sync; returns (times ms, stage, scene index, render index)."""
    from pxr import Usd

    import stb_hydra  # noqa: F401  (schema registration before the stage opens)
    from stb_hydra.renderer.delegate import RenderDelegate
    from stb_hydra.renderer.render_index import RenderIndex
    from stb_hydra.scene.stage_scene_index import StageSceneIndex

    t0 = time.perf_counter()
    stage = Usd.Stage.Open(str(path))
    t_open = _ms(t0)
    t0 = time.perf_counter()
    si = StageSceneIndex(stage, 1.0)
    t_index = _ms(t0)
    t0 = time.perf_counter()
    ri = RenderIndex(si, RenderDelegate())
    n = ri.sync_all()
    t_sync = _ms(t0)
    times = {
        "open": t_open,
        "index": t_index,
        "sync": t_sync,
        "open_first_sync": t_open + t_index + t_sync,
        "synced_prims": n,
    }
    return times, stage, si, ri


def _static_lights(si, k: int) -> list[str]:
    tv = si.time_varying_paths()
    lights = [p for p in si.light_paths() if p not in tv]
    step = max(1, len(lights) // k)
    return lights[::step][:k]


def edit_sync(stage, si, ri, kind: str, repeat: int) -> dict[str, float]:
    """Median ms of ``repeat`` one-light edits: total (Set -> synced) and sync only."""
    from pxr import Gf

    total, sync_only = [], []
    for i, path in enumerate(_static_lights(si, repeat)):
        prim = stage.GetPrimAtPath(path)
        if kind == "intensity":
            attr = prim.GetAttribute("inputs:intensity")
            value = float(attr.Get()) * (1.5 if i % 2 == 0 else 0.75)
        else:
            attr = prim.GetAttribute("xformOp:translate")
            p = attr.Get()
            value = Gf.Vec3d(p[0] + 0.25, p[1], p[2] - 0.25)
        t0 = time.perf_counter()
        attr.Set(value)
        t1 = time.perf_counter()
        si.apply_pending_updates()
        n = ri.sync_all()
        t2 = time.perf_counter()
        if n != 1:
            raise RuntimeError(f"{kind} edit of {path} synced {n} prims, expected 1")
        total.append((t2 - t0) * 1e3)
        sync_only.append((t2 - t1) * 1e3)
    return {"total": statistics.median(total), "sync": statistics.median(sync_only)}


def set_time_sync(si, ri, frames: int, animated: int) -> dict[str, float]:
    """Median ms of set_time(t) + sync_all() over ``frames`` distinct times."""
    times, counts = [], []
    for f in range(frames):
        t0 = time.perf_counter()
        si.set_time(2.0 + f)
        n = ri.sync_all()
        times.append(_ms(t0))
        counts.append(n)
    if animated and set(counts) != {animated}:
        raise RuntimeError(f"set_time synced {sorted(set(counts))} prims, expected {animated}")
    return {"median": statistics.median(times), "max": max(times)}


def bench_count(n: int, tmp: Path, args) -> dict:
    from stb_hydra.scenegen.lights import build_lights_stage

    path = tmp / f"lights_{n}.usda"
    t0 = time.perf_counter()
    build_lights_stage(n_lights=n, seed=args.seed, animated=args.animated, path=path)
    gen_ms = _ms(t0)
    load_before = _load()
    times, stage, si, ri = first_sync(path)
    rec = {"lights": n, "animated": args.animated, "generate_ms": gen_ms, **times}
    for kind in ("intensity", "move"):
        e = edit_sync(stage, si, ri, kind, args.repeat)
        rec[f"edit_{kind}"] = e["total"]
        rec[f"edit_{kind}_sync"] = e["sync"]
    st = set_time_sync(si, ri, args.frames, args.animated)
    rec["set_time"] = st["median"]
    rec["set_time_max"] = st["max"]
    rec["load_avg"] = [load_before, _load()]
    si.close()
    return rec


def _verdict(rec: dict) -> dict[str, bool]:
    if rec["lights"] != 10_000:
        return {}
    return {k: rec[k] <= v for k, v in TARGETS_10K_MS.items()}


def print_table(records: list[dict]) -> None:
    cols = [
        ("lights", "{:>8}"),
        ("open", "{:>9.1f}"),
        ("index", "{:>9.1f}"),
        ("sync", "{:>9.1f}"),
        ("open_first_sync", "{:>11.1f}"),
        ("edit_intensity", "{:>9.3f}"),
        ("edit_move", "{:>9.3f}"),
        ("set_time", "{:>9.3f}"),
    ]
    heads = [
        "lights",
        "open ms",
        "index ms",
        "sync ms",
        "open+sync",
        "edit I ms",
        "move ms",
        "set_time",
    ]
    print("  ".join(f"{h:>{9 if h != 'lights' else 8}}" for h in heads))
    for r in records:
        print("  ".join(fmt.format(r[k]) for k, fmt in cols))
        v = _verdict(r)
        if v:
            print(
                "  targets (10k): "
                + ", ".join(
                    f"{k} <= {TARGETS_10K_MS[k]:g} ms: {'ok' if ok else 'MISSED'}"
                    for k, ok in v.items()
                )
            )
    print(
        "(edits: median of Set + apply_pending_updates + sync_all; sync alone: "
        + ", ".join(f"{r['edit_intensity_sync']:.3f}/{r['edit_move_sync']:.3f} ms" for r in records)
        + ")"
    )
    print(
        "load average (1 min) before/after: "
        + "; ".join(f"{r['lights']}: {r['load_avg'][0]}/{r['load_avg'][1]}" for r in records)
    )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--counts", default="10000,100000", help="light counts (comma list)")
    ap.add_argument("--animated", type=int, default=100, help="animated lights per stage")
    ap.add_argument("--repeat", type=int, default=20, help="edits per kind (median)")
    ap.add_argument("--frames", type=int, default=40, help="set_time frames (median)")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--json", help="write the records here")
    args = ap.parse_args(argv)
    counts = [int(c) for c in args.counts.split(",") if c.strip()]
    records = []
    with tempfile.TemporaryDirectory(prefix="stb_bench_si_") as tmp:
        for n in counts:
            print(f"... {n} lights", file=sys.stderr, flush=True)
            records.append(bench_count(n, Path(tmp), args))
    for r in records:
        r["targets_met"] = _verdict(r)
        for k, v in list(r.items()):
            if isinstance(v, float):
                r[k] = round(v, 4)
    print_table(records)
    if args.json:
        Path(args.json).write_text(json.dumps(records, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
