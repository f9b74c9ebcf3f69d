"""Process CPU seconds of an engine's set-up: open the stage, build an ``Engine``, render
one small frame, release it -- N times in one process (the first pays the process's
one-time costs: imports, shader programs; the rest what every new engine on the same
stage pays: a reload, the next render of a script, a test).

    LP_NUM_THREADS=1 python tools/engine_setup_cost.py usd_scenes/default.usda -n 6
"""

from __future__ import annotations

import argparse
import statistics
import time

from stb_hydra.renderer.engine import Engine
from stb_hydra.renderer.frame import RenderSettings
from stb_hydra.scene.stage_io import open_stage


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("stage")
    ap.add_argument("--lighting", default="reference")
    ap.add_argument("-n", type=int, default=6, help="engines, one after another (>= 2)")
    ap.add_argument("--size", default="64x36", help="the frame, WxH pixels")
    a = ap.parse_args()
    w, h = (int(v) for v in a.size.split("x"))
    cpu: list[float] = []
    wall: list[float] = []
    for _ in range(max(2, a.n)):
        c0, w0 = time.process_time(), time.perf_counter()
        eng = Engine(open_stage(a.stage), RenderSettings(width=w, height=h, lighting=a.lighting))
        eng.render_frame()
        eng.ctx.finish()
        eng.release()
        cpu.append(time.process_time() - c0)
        wall.append(time.perf_counter() - w0)
    print(
        f"{a.stage} {a.lighting}: first {cpu[0]:.2f} s CPU; again (median of {len(cpu) - 1}) "
        f"{statistics.median(cpu[1:]):.3f} s CPU, {statistics.median(wall[1:]):.3f} s wall"
    )


if __name__ == "__main__":
    main()
