"""Process CPU time per frame of several methods on one stage, interleaved (issue 34).

Wall-clock frame times on a machine shared with other jobs swing 2x between runs;
the process's CPU time (``time.process_time()``: every thread, llvmpipe's included)
around ``render()`` + ``ctx.finish()`` does not. One ``Engine`` per method on the same
stage, a warm-up frame each, then ``--frames`` rounds rendering each method once in
turn; printed per scene: the median CPU ms per frame of each method, and for each
method other than ``sun`` and ``bare`` its light-loop cost as a multiple of the bare
loop's, net of the frame without local lights: (method - sun) / (bare - sun). Run it
with ``LP_NUM_THREADS=1`` for the figures of docs/PERFORMANCE.md.

    LP_NUM_THREADS=1 python tools/frame_cpu.py /tmp/tap500.usda --methods sun,bare,reference
"""

from __future__ import annotations

import argparse
import json
import statistics
import time


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scenes", nargs="+")
    ap.add_argument("--methods", default="sun,bare,reference,tiled,clustered")
    ap.add_argument("--frames", type=int, default=3)
    ap.add_argument("--size", default="160x90", help="WxH (default 160x90)")
    a = ap.parse_args(argv)
    from pxr import Usd

    from stb_hydra.renderer.engine import Engine
    from stb_hydra.renderer.frame import RenderSettings
    from stb_hydra.renderer.gl import get_context

    w, h = (int(v) for v in a.size.lower().split("x"))
    methods = a.methods.split(",")
    ctx = get_context()
    out: dict[str, dict[str, float]] = {}
    for scene in a.scenes:
        stage = Usd.Stage.Open(scene)
        engs = {
            m: Engine(stage, RenderSettings(width=w, height=h, lighting=m), ctx=ctx)
            for m in methods
        }
        cpu: dict[str, list[float]] = {m: [] for m in methods}
        try:
            for e in engs.values():
                e.render()
                ctx.finish()
            for _ in range(a.frames):
                for m, e in engs.items():
                    c = time.process_time()
                    e.render()
                    ctx.finish()
                    cpu[m].append(time.process_time() - c)
        finally:
            for e in engs.values():
                e.release()
        med = {m: statistics.median(v) * 1e3 for m, v in cpu.items()}
        out[scene] = med
        line = " ".join(f"{m}={v:.1f}" for m, v in med.items())
        sun, bare = med.get("sun", 0.0), med.get("bare")
        net = " ".join(
            f"{m}/bare={(v - sun) / (bare - sun):.2f}"
            for m, v in med.items()
            if bare is not None and m not in ("sun", "bare")
        )
        print(f"{scene}: CPU ms/frame {line}  net of sun: {net}", flush=True)
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
