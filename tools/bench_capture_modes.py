"""Time one omni shadow capture per mode on the chess scene (issue 16): per-face with
range-only culling (the old path), per-face with per-face frustum culling (default),
and one geometry-shader submission for all six faces (``one_pass``).

    .venv/bin/python tools/bench_capture_modes.py --lights 500 --maps 12 --size 128

Each capture is followed by ``ctx.finish()`` and timed on the wall clock (llvmpipe's
timer queries are meaningless). Prints ms per capture (median, mean) and the triangles
submitted per capture per mode, and the largest atlas difference from the per-face path.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from stb_hydra.renderer.engine import Engine
from stb_hydra.renderer.frame import RenderSettings
from stb_hydra.scenegen.chess import build_chess_stage
from stb_hydra.shadows.atlas import AtlasRect
from stb_hydra.shadows.capture import capture_for_row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--lights", type=int, default=500)
    ap.add_argument("--maps", type=int, default=12, help="lights captured per mode")
    ap.add_argument("--size", type=int, default=128, help="map side (texels, incl. border)")
    args = ap.parse_args()
    stage = build_chess_stage(n_lights=args.lights)
    eng = Engine(stage, RenderSettings(width=64, height=32, lighting="sun", shadow_budget=1))
    try:
        eng.render_frame()
        task = eng.task("shadow_atlas")
        cap = task.capturer
        if cap is None:
            from stb_hydra.renderer.shadow_capture import ShadowCapturer

            cap = ShadowCapturer(eng.delegate.ctx, 4096)
        t = eng.delegate.light_table
        rows = np.nonzero(t.local_mask())[0]
        rows = rows[:: max(1, len(rows) // args.maps)][: args.maps]
        caps = [capture_for_row(t, r) for r in rows]
        rect = AtlasRect(0, 0, args.size)
        ctx = eng.delegate.ctx
        ref = None
        for label, mode, cull in (
            ("per_face, range only", "per_face", False),
            ("per_face, face culled", "per_face", True),
            ("one_pass (geometry shader)", "one_pass", True),
        ):
            cap.mode, cap.cull = mode, cull
            cap.capture(eng.delegate, "warm", caps[0], rect, False)
            ms, tris = [], []
            for c in caps:
                ctx.finish()
                t0 = time.perf_counter()
                w = cap.capture(eng.delegate, "x", c, rect, False)
                ctx.finish()
                ms.append((time.perf_counter() - t0) * 1e3)
                tris.append(w.triangles)
            img = np.frombuffer(cap.atlas.read(), np.uint16).reshape(cap.size, cap.size)
            img = img[: args.size, : args.size].astype(np.int64)
            ref = img if ref is None else ref
            print(
                f"{label:30s} {statistics.median(ms):8.1f} ms median {statistics.mean(ms):8.1f}"
                f" mean  {statistics.mean(tris) / 1e6:6.2f} Mtri/capture"
                f"  max |atlas - per_face| {int(np.abs(img - ref).max())} LSB"
            )
    finally:
        eng.release()


if __name__ == "__main__":
    main()
