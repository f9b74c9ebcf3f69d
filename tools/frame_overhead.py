"""The engine's per-frame CPU on small frames (issue 32, docs/TESTING.md "Engine frame
overhead (frame9)"): 64x36, STB + taa, one of three scenes --

* ``soak``: tools/soak.py's scene and loop (12 orbs spawning, flying and dying over a
  24-frame range, dynamic shadows under the real-time texel budget, the camera orbiting
  through USD edits, the atlas invariants checked every frame);
* ``still``: the courtyard (usd_scenes/default.usda) at one time, offline shadows;
* ``orbit``: the courtyard with ``stb tradeoff --moving``'s camera orbit (1 degree a
  frame; the courtyard's own animated meshes move with the time).

Prints the process CPU time (every thread) per measured frame after ``--warm`` frames;
``--out F.npz`` keeps every frame's display image, ``--same A.npz B.npz`` says whether
two runs' images are bit-identical. For the phase split, sample it with py-spy and
pass the raw file to ``--split`` (the sampled main thread's time per frame by phase:
sync, commit, each pass's prepare, each pass's execute as GL calls and Python)::

    LP_NUM_THREADS=1 python tools/frame_overhead.py soak --frames 216 --out /tmp/a.npz
    py-spy record -r 250 -f raw -o /tmp/s.txt -- python tools/frame_overhead.py soak
    python tools/frame_overhead.py --split /tmp/s.txt --frames 216
    python tools/frame_overhead.py --same /tmp/a.npz /tmp/b.npz
"""

from __future__ import annotations

import argparse
import collections
import math
import sys
import time

import numpy as np

W, H = 64, 36
#: The measured loop's frame call (``_measured``), what ``--split`` keeps of the samples.
_LOOP = "_measured (tools/frame_overhead.py"


def _engine(mode: str, frames: int):
    """(engine, per-frame step(i)) for ``mode``."""
    from pxr import Gf, Usd, UsdGeom

    from stb_hydra import Engine, RenderSettings, limits

    if mode == "soak":
        from stb_hydra.scenegen.orbs import build_orbs_stage

        stage = build_orbs_stage(12, 24)
        cam = UsdGeom.Xformable(next(p for p in stage.Traverse() if p.IsA(UsdGeom.Camera)))
        ops = cam.GetOrderedXformOps()
        if len(ops) == 1 and ops[0].GetOpType() == UsdGeom.XformOp.TypeTransform:
            op = ops[0]
        else:
            cam.ClearXformOpOrder()
            op = cam.AddTransformOp()
        eye0 = np.array(cam.ComputeLocalToWorldTransform(0).ExtractTranslation())
        radius, height = float(np.hypot(eye0[0], eye0[2])), float(eye0[1])
        budget = limits.SHADOW_UPDATE_BUDGET_TEXELS_DEFAULT
    else:
        stage = Usd.Stage.Open("usd_scenes/default.usda")
        if mode == "orbit":
            from stb_hydra.apps.tradeoff_moving import orbit_copy

            orbit_copy(stage, frames, 1.0, 12.0, None)
        budget = None
    eng = Engine(
        stage,
        RenderSettings(width=W, height=H, lighting="stb", temporal="taa", shadow_budget=budget),
    )
    task = eng.task("shadow_atlas")
    atlas = task.scheduler.atlas if task is not None else None  # type: ignore[attr-defined]

    def step(i: int) -> np.ndarray:
        if mode == "soak":  # tools/soak.py's loop
            a = 2 * math.pi * i / 720.0
            eye = Gf.Vec3d(radius * math.sin(a), height, radius * math.cos(a))
            m = Gf.Matrix4d().SetLookAt(eye, Gf.Vec3d(0, 0.5, 0), Gf.Vec3d(0, 1, 0))
            op.Set(m.GetInverse())
            eng.render_frame(float(1 + i % 24))
        else:
            eng.render_frame(float(i) if mode == "orbit" else 1.0)
        img = np.array(eng.aovs["color"])
        if atlas is not None:
            atlas.check_invariants()
        return img

    return eng, step


def _measured(step, i: int) -> np.ndarray:
    return step(i)


def split(path: str, frames: int, rate: float) -> dict[str, float]:
    """ms per frame by phase from py-spy's raw samples (``-f raw``) of the measured loop."""
    out: collections.Counter[str] = collections.Counter()
    for line in open(path):
        stack, _, n = line.rstrip().rpartition(" ")
        if _LOOP not in stack:
            continue
        frames_ = stack.split(";")
        names = [f.split(" (")[0] for f in frames_]
        gl = "moderngl" in frames_[-1]

        def has(s: str, names: list[str] = names) -> bool:
            return any(x == s or x.endswith("." + s) for x in names)

        if has("check_invariants"):
            cat = "soak check: atlas.check_invariants"
        elif has("commit_resources"):
            cat = "commit (draw batches, light table)"
        elif has("_sync"):
            cat = "sync (scene index: USD reads; render prims)"
        elif any(x.endswith((".prepare", "Task.sync")) for x in names):
            p = next(x for x in names if x.endswith((".prepare", "Task.sync")))
            cat = "prepare: " + p.split(".")[0]
        elif any(x.endswith(".execute") for x in names):
            p = next(x for x in names if x.endswith(".execute"))
            cat = "execute: " + p.split(".")[0] + (" [GL calls]" if gl else " [Python]")
        else:
            cat = "other (engine, loop, read-back)"
        out[cat] += int(n)
    return {k: 1000.0 * v / rate / frames for k, v in out.most_common()}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("mode", nargs="?", choices=["soak", "still", "orbit"], default="soak")
    ap.add_argument("--frames", type=int, default=216, help="measured frames")
    ap.add_argument("--warm", type=int, default=24, help="frames before the measured ones")
    ap.add_argument("--out", default="", help="every frame's display image (.npz)")
    ap.add_argument("--same", nargs=2, metavar="NPZ", help="are two runs' images identical")
    ap.add_argument("--split", default="", metavar="RAW", help="py-spy raw samples")
    ap.add_argument("--rate", type=float, default=250.0, help="py-spy's sampling rate")
    a = ap.parse_args(argv)
    if a.same:
        x, y = (np.load(p)["imgs"] for p in a.same)
        same = x.shape == y.shape and x.tobytes() == y.tobytes()
        print(f"{x.shape} vs {y.shape}: {'bit-identical' if same else 'DIFFERENT'}")
        return 0 if same else 1
    if a.split:
        rows = split(a.split, a.frames, a.rate)
        print(f"{sum(rows.values()):.2f} ms/frame sampled")
        for k, v in rows.items():
            print(f"  {k:55s} {v:6.2f}")
        return 0
    eng, step = _engine(a.mode, a.warm + a.frames)
    imgs = [step(i) for i in range(a.warm)]
    c0, t0 = time.process_time(), time.perf_counter()
    imgs += [_measured(step, i) for i in range(a.warm, a.warm + a.frames)]
    c1, t1 = time.process_time(), time.perf_counter()
    print(
        f"{a.mode}: {a.frames} frames, process CPU {1000 * (c1 - c0) / a.frames:.2f} ms/frame "
        f"(wall {1000 * (t1 - t0) / a.frames:.2f})"
    )
    if a.out:
        np.savez_compressed(a.out, imgs=np.stack(imgs))
    eng.release()
    return 0


if __name__ == "__main__":
    sys.exit(main())
