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

Scenes may also be ``stb bench``'s generators (``gen:lights:500``). ``--variant
LABEL=METHOD[:K=V...]`` adds a method with options as one more interleaved row (issue 31:
``--methods stb --variant reuse=stb:reuse=on:N=4:reuse_k=0``); ``--shadow-budget``
renders with ``stb bench``'s real-time shadow budget instead of the offline one,
``--shadow-budget-ms MS`` with a budget in milliseconds of captures (``stb bench
--shadow-budget-ms``); ``--warmup N`` interleaved warm-up frames (default 1; 0: the
first frames themselves, e.g. issue 31's frame 50 -> 5,000 lights, ``--warmup 0
--frames 12`` and ``--warmup 40 --frames 10``).
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
    ap.add_argument("--variant", action="append", default=[], metavar="LABEL=METHOD[:K=V...]")
    ap.add_argument("--shadow-budget", action="store_true", help="stb bench's texel budget")
    ap.add_argument("--shadow-budget-ms", type=float, default=None, help="capture ms per frame")
    ap.add_argument("--warmup", type=int, default=1, help="interleaved warm-up frames")
    a = ap.parse_args(argv)
    from stb_hydra import limits
    from stb_hydra.apps.bench import parse_scene
    from stb_hydra.renderer.engine import Engine
    from stb_hydra.renderer.frame import RenderSettings
    from stb_hydra.renderer.gl import get_context

    w, h = (int(v) for v in a.size.lower().split("x"))
    specs: dict[str, tuple[str, dict[str, str]]] = {m: (m, {}) for m in a.methods.split(",") if m}
    for v in a.variant:
        label, _, rest = v.partition("=")
        method, *kvs = rest.split(":")
        specs[label] = (method, dict(kv.split("=", 1) for kv in kvs))
    methods = list(specs)
    budget = limits.SHADOW_UPDATE_BUDGET_TEXELS_DEFAULT if a.shadow_budget else None
    ctx = get_context()
    out: dict[str, dict[str, float]] = {}
    for case in [c for sc in a.scenes for c in parse_scene(sc)]:
        scene = case.label
        stage = case.build()
        engs = {
            m: Engine(
                stage,
                RenderSettings(
                    width=w,
                    height=h,
                    lighting=specs[m][0],
                    method_options=dict(specs[m][1]),
                    shadow_budget=budget,
                    shadow_budget_ms=a.shadow_budget_ms,
                ),
                ctx=ctx,
            )
            for m in methods
        }
        cpu: dict[str, list[float]] = {m: [] for m in methods}
        try:
            for _ in range(a.warmup):
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
        first = methods[0]
        rel = " ".join(f"{m}/{first}={v / med[first]:.3f}" for m, v in med.items() if m != first)
        print(f"{scene}: CPU ms/frame {line}  net of sun: {net}  {rel}", flush=True)
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
