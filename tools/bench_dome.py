#!/usr/bin/env python3
"""What a textured dome costs (issue 37): frame time of each lighting method on the
floor + boxes scene of ``stb_hydra.scenegen.dome_scene`` lit by its sun-and-sky HDRI
(512 x 256), against the same scene with an untextured dome of the same mean, frame
by frame in turn (machine load falls on both alike). Wall clock around
``Engine.render_frame`` + ``ctx.finish()``; medians over ``--frames`` after
``--warmup``; also the first frame (texture read, resample, SH, upload, programs).

    .venv/bin/python tools/bench_dome.py [--size 745x360] [--frames 8] [--methods ...]
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import tempfile
import time
from pathlib import Path


def _engine(path: Path, size: tuple[int, int], method: str):
    from stb_hydra.renderer.engine import Engine
    from stb_hydra.renderer.frame import RenderSettings

    return Engine(path, RenderSettings(width=size[0], height=size[1], lighting=method))


def _frame(eng) -> float:
    t0 = time.perf_counter()
    eng.render_frame()
    eng.ctx.finish()
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="745x360")
    ap.add_argument("--frames", type=int, default=8)
    ap.add_argument("--warmup", type=int, default=2)
    ap.add_argument("--methods", nargs="+", default=["reference", "stb", "tiled", "sun"])
    a = ap.parse_args()
    w, _, h = a.size.partition("x")
    size = (int(w), int(h))
    from stb_hydra.scene.dome import solid_angle_mean
    from stb_hydra.scenegen import dome_scene

    folder = Path(tempfile.mkdtemp(prefix="bench_dome_"))
    textured = dome_scene.write_scene(folder)
    mean = float(solid_angle_mean(dome_scene.sun_and_sky())[1]) * 0.5
    plain = folder / "plain.usda"
    text = textured.read_text()
    start = text.index('def DomeLight "Sky"')
    plain.write_text(
        text[:start] + f'def DomeLight "Sky"\n{{\n    float inputs:intensity = {mean:g}\n}}\n'
    )
    # The same uniform dome plus a DistantLight where the HDRI's sun is: what the
    # real-time methods light the HDRI with (its sun split off, shadowed).
    from stb_hydra.scene.dome import split_sun

    sun = split_sun(dome_scene.sun_and_sky())
    assert sun is not None
    rest, d, e = sun
    rmean = float(solid_angle_mean(rest)[1]) * 0.5
    pitch = math.degrees(math.asin(-d[1]))
    yaw = math.degrees(math.atan2(d[0], d[2]))
    sunny = folder / "plain_sun.usda"
    sunny.write_text(
        text[:start]
        + f'def DomeLight "Sky"\n{{\n    float inputs:intensity = {rmean:g}\n}}\n'
        + f'def DistantLight "Sun"\n{{\n    float inputs:intensity = {e[1] * 0.5:g}\n'
        + "    float inputs:angle = 0\n"
        + f"    float3 xformOp:rotateXYZ = ({pitch:g}, {yaw:g}, 0)\n"
        + '    uniform token[] xformOpOrder = ["xformOp:rotateXYZ"]\n}\n'
    )
    print(f"{size[0]}x{size[1]}, {a.frames} frames after {a.warmup}; load {os.getloadavg()[0]:.2f}")
    print("method      first(s)  textured(ms)  uniform(ms)  ratio  uniform+sun(ms)  ratio")
    for m in a.methods:
        t0 = time.perf_counter()
        et = _engine(textured, size, m)
        _frame(et)
        first = time.perf_counter() - t0
        eu = _engine(plain, size, m)
        es = _engine(sunny, size, m)
        for _ in range(a.warmup + 1):
            _frame(et)
            _frame(eu)
            _frame(es)
        tt, tu, ts = [], [], []
        for _ in range(a.frames):
            tt.append(_frame(et))
            tu.append(_frame(eu))
            ts.append(_frame(es))
        mt, mu, ms = (statistics.median(x) * 1e3 for x in (tt, tu, ts))
        print(
            f"{m:10s} {first:8.2f} {mt:12.1f} {mu:12.1f} {mt / mu:6.2f} {ms:16.1f} {mt / ms:6.2f}"
        )
        for e_ in (et, eu, es):
            e_.release()


if __name__ == "__main__":
    main()
