"""CPU cost of the taa pass's draw alone, for A/B runs of shader changes on llvmpipe:
the courtyard (or any stage) rendered with STB + taa for ``--after`` frames, then the
next frame's temporal draw executed ``--repeats`` times on the same inputs, each timed
in process CPU (``time.process_time()`` around the draw and ``ctx.finish()``); the
median in ms. Run it with ``LP_NUM_THREADS=0`` (llvmpipe draws on the calling thread,
so process CPU is the draw's work and other processes' load changes it less than wall
time), one process per tree, trees alternating (``PYTHONPATH=TREE``):

    LP_NUM_THREADS=0 .venv/bin/python tools/taa_pass_cpu.py usd_scenes/default.usda \\
        --after 6 --after 34   # 6: young histories after a start; 34: steady state
    ... tools/taa_pass_cpu.py usd_scenes/default.usda -o reuse=on,N=4   # STB's options

Pass times from ``tools/taa_cost.py`` (wall, every pass of the frame) vary by +-25 %
between runs minutes apart on the shared 2-core VM; this measures only the draw, many
times, and still needs several alternating rounds to resolve 10 % (docs/STB_NOTES.md,
"the young estimate's cost").
"""

from __future__ import annotations

import argparse
import statistics
import time

import moderngl

import stb_hydra.renderer.tasks.temporal as temporal
from stb_hydra.apps.common import parse_options
from stb_hydra.renderer.engine import Engine
from stb_hydra.renderer.frame import RenderSettings


def pass_cpu_ms(
    stage: str, width: int, height: int, after: int, repeats: int, options: dict | None = None
) -> float:
    """Median process-CPU ms of the temporal draw of frame ``after`` (0-based) of a
    still camera, executed ``repeats`` times."""
    draw = temporal.draw_fullscreen
    times: list[float] = []
    measuring = False

    def timed(
        ctx: moderngl.Context,
        prog: moderngl.Program,
        fbo: moderngl.Framebuffer,
        size: tuple[int, int],
    ) -> None:
        if not measuring:
            draw(ctx, prog, fbo, size)
            return
        for _ in range(repeats):
            ctx.finish()
            t = time.process_time()
            draw(ctx, prog, fbo, size)
            ctx.finish()
            times.append((time.process_time() - t) * 1e3)

    temporal.draw_fullscreen = timed
    try:
        settings = RenderSettings(
            width=width, height=height, lighting="stb", temporal="taa", method_options=options or {}
        )
        eng = Engine(stage, settings)
        try:
            for _ in range(after):
                eng.render()
            measuring = True
            eng.render()
        finally:
            eng.release()
    finally:
        temporal.draw_fullscreen = draw
    return statistics.median(times)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("stage")
    ap.add_argument("--width", type=int, default=745)
    ap.add_argument("--height", type=int, default=360)
    ap.add_argument("--after", type=int, action="append", help="frames rendered first (repeatable)")
    ap.add_argument("--repeats", type=int, default=25)
    ap.add_argument("-o", "--options", default="", help="STB's options, KEY=VALUE[,...]")
    args = ap.parse_args(argv)
    options = parse_options(args.options, "-o")
    for after in args.after or [6, 34]:
        ms = pass_cpu_ms(args.stage, args.width, args.height, after, args.repeats, options)
        print(f"after {after}: {ms:.1f} ms", flush=True)


if __name__ == "__main__":
    main()
