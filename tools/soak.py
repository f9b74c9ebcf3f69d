"""Soak: render a dynamic scene for many frames and watch memory, time and the shadow
atlas (issue 21, item 5). Outside CI.

The scene is the enemy-orbs arena (``stb_hydra.scenegen.orbs``): orbs spawn over the
scene's frame range (time-sampled visibility), fly and bob, with dynamic shadows;
the soak cycles through that range, so at every wrap the orbs die (invisible again)
and respawn. The camera orbits the arena (its transform edited through USD every
frame: the scene index's edit path), STB lighting with ``--temporal taa`` by default
and the real-time shadow budget (maps refresh over frames, the atlas allocates and
frees). Every frame: the atlas invariants (``ShadowAtlas.check_invariants``);
per block of frames: mean and p95 frame time, host RSS, GPU memory where the driver
reports it (``GL_NVX_gpu_memory_info``; llvmpipe does not).

    .venv/bin/python tools/soak.py --frames 10000 --json out/soak.json
    .venv/bin/python tools/soak.py --frames 500 --block 100      # the short variant

Exit status 1 when an invariant breaks, RSS grows by more than ``--max-growth``
(default 1 %) from the end of the second block to the end, or the last block's mean
frame time is more than ``--max-slowdown`` (default 5 %) above the second block's
(the first two are warm-up: program compiles, first captures, the engine's window
of per-frame timings filling up).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import sys
import time
from pathlib import Path


def rss_mib() -> float:
    with open("/proc/self/statm") as f:
        pages = int(f.read().split()[1])
    return pages * os.sysconf("SC_PAGE_SIZE") / 2**20


def gpu_used_mib(ctx) -> float | None:
    """Dedicated GPU memory in use (MiB) via GL_NVX_gpu_memory_info, else None."""
    if "GL_NVX_gpu_memory_info" not in getattr(ctx, "extensions", set()):
        return None
    try:
        from OpenGL import GL

        total = GL.glGetIntegerv(0x9047)  # GPU_MEMORY_INFO_DEDICATED_VIDMEM_NVX (KiB)
        avail = GL.glGetIntegerv(0x9049)  # GPU_MEMORY_INFO_CURRENT_AVAILABLE_VIDMEM_NVX
        return (int(total) - int(avail)) / 1024.0
    except Exception:  # noqa: BLE001 - optional figure
        return None


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=10_000)
    ap.add_argument("--block", type=int, default=1000, help="frames per reported block")
    ap.add_argument("--orbs", type=int, default=64)
    ap.add_argument("--scene-frames", type=int, default=240, help="the scene's time range")
    ap.add_argument("--size", default="160x90")
    ap.add_argument("--lighting", default="stb")
    ap.add_argument("--temporal", default="taa")
    ap.add_argument("--max-growth", type=float, default=0.01)
    ap.add_argument("--max-slowdown", type=float, default=0.05)
    ap.add_argument("--json", default="")
    args = ap.parse_args(argv)

    import numpy as np
    from pxr import Gf, UsdGeom

    from stb_hydra import Engine, RenderSettings, limits
    from stb_hydra.scenegen.orbs import build_orbs_stage

    w, h = (int(v) for v in args.size.split("x"))
    stage = build_orbs_stage(args.orbs, args.scene_frames)
    cam_prim = next(p for p in stage.Traverse() if p.IsA(UsdGeom.Camera))
    xf = UsdGeom.Xformable(cam_prim)
    ops = xf.GetOrderedXformOps()
    if len(ops) == 1 and ops[0].GetOpType() == UsdGeom.XformOp.TypeTransform:
        cam_op = ops[0]
    else:
        xf.ClearXformOpOrder()
        cam_op = xf.AddTransformOp()
    eye0 = np.array(xf.ComputeLocalToWorldTransform(0).ExtractTranslation())
    radius, height = float(np.hypot(eye0[0], eye0[2])), float(eye0[1])

    settings = RenderSettings(
        width=w,
        height=h,
        lighting=args.lighting,
        temporal=args.temporal,
        shadow_budget=limits.SHADOW_UPDATE_BUDGET_TEXELS_DEFAULT,
    )
    eng = Engine(stage, settings)
    atlas_pass = eng.task("shadow_atlas")
    atlas = atlas_pass.scheduler.atlas if atlas_pass is not None else None
    from stb_hydra.renderer.gl import get_context

    ctx = get_context()

    blocks: list[dict] = []
    times: list[float] = []
    violations: list[str] = []
    t_all = time.perf_counter()
    for i in range(args.frames):
        a = 2 * math.pi * i / 720.0  # one orbit every 720 frames
        eye = Gf.Vec3d(radius * math.sin(a), height, radius * math.cos(a))
        m = Gf.Matrix4d().SetLookAt(eye, Gf.Vec3d(0, 0.5, 0), Gf.Vec3d(0, 1, 0)).GetInverse()
        cam_op.Set(m)
        t0 = time.perf_counter()
        eng.render_frame(float(1 + i % args.scene_frames))
        _ = eng.aovs["color"]  # read back: the GPU work is done
        times.append(time.perf_counter() - t0)
        if atlas is not None:
            try:
                atlas.check_invariants()
            except AssertionError as exc:
                violations.append(f"frame {i}: {exc}")
        if (i + 1) % args.block == 0 or i + 1 == args.frames:
            blk = times[-((i % args.block) + 1) :]
            row = {
                "frames": i + 1,
                "mean_ms": 1000 * statistics.fmean(blk),
                "p95_ms": 1000 * float(np.percentile(blk, 95)),
                "rss_mib": rss_mib(),
                "gpu_mib": gpu_used_mib(ctx),
            }
            blocks.append(row)
            gpu = "n/a" if row["gpu_mib"] is None else f"{row['gpu_mib']:.1f}"
            print(
                f"frames {row['frames']:6d}  mean {row['mean_ms']:7.2f} ms  "
                f"p95 {row['p95_ms']:7.2f} ms  rss {row['rss_mib']:8.1f} MiB  gpu {gpu} MiB",
                flush=True,
            )
    eng.release()

    # Warm-up: the first two blocks (program compiles, first captures, and the engine's
    # timing window of 1-2x limits.TIMINGS_KEPT_FRAMES frames filling up).
    ref = blocks[1] if len(blocks) > 2 else blocks[0]
    growth = (blocks[-1]["rss_mib"] - ref["rss_mib"]) / ref["rss_mib"]
    slowdown = blocks[-1]["mean_ms"] / ref["mean_ms"] - 1
    ok = not violations and growth <= args.max_growth and slowdown <= args.max_slowdown
    print(
        f"{args.frames} frames in {time.perf_counter() - t_all:.0f} s: RSS growth after "
        f"block 2 {100 * growth:+.2f} %, last block {100 * slowdown:+.1f} % vs block 2, "
        f"{len(violations)} atlas invariant violations -> {'ok' if ok else 'FAIL'}"
    )
    for v in violations[:10]:
        print("  " + v)
    if args.json:
        Path(args.json).write_text(
            json.dumps(
                {
                    "args": vars(args),
                    "blocks": blocks,
                    "rss_growth": growth,
                    "slowdown": slowdown,
                    "violations": violations,
                    "ok": ok,
                },
                indent=2,
            )
            + "\n"
        )
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
