#!/usr/bin/env python3
"""Textured-dome accuracy of every lighting method (issue 37), the figures of
docs/DOME.md:

1. the half-sky sphere (radiance 1 above the horizon, 0 below; Lambert albedo 0.5):
   median relative error against albedo (1 + n.y) / 2 over the lit sphere, and the
   largest error of the sky seen behind it (texels next to the horizon left out);
2. the floor + boxes under the sun-and-sky HDRI (``stb_hydra.scenegen.dome_scene``)
   against Mitsuba 3's ``envmap`` emitter: median and p95 relative error
   (``metrics.mitsuba_truth.compare``) and the median error in the boxes' umbra.

    .venv/bin/python tools/dome_accuracy.py [--size 128x72] [--accumulate 16]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
METHODS = ("reference", "stb", "tiled", "clustered", "lighttree", "sun")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="128x72")
    ap.add_argument("--accumulate", type=int, default=16, help="reference frames")
    a = ap.parse_args()
    w, _, h = a.size.partition("x")
    W, H = int(w), int(h)
    sys.path.insert(0, str(REPO / "tests"))
    import test_dome as T  # the tests' closed forms and scenes
    from stagegen import usda_stage

    import stb_hydra
    from stb_hydra.metrics.mitsuba_truth import compare, render_mitsuba

    T.W, T.H = W, H
    tmp = Path(tempfile.mkdtemp(prefix="dome_acc_"))
    tex = T.write_exr(tmp / "halfsky.exr", T.half_sky())
    stage = usda_stage(T.SPHERE_USDA.format(up="Y", albedo=T.ALBEDO, dome=T.dome_usda(tex)))
    print(f"half-sky sphere {W}x{H}: median relative error, max sky error")
    for m in METHODS:
        acc = a.accumulate if m == "reference" else 1
        img = stb_hydra.render(stage, width=W, height=H, lighting=m, accumulate=acc)
        med, sky = T.check_half_sky(img, stage, np.array([0.0, 1.0, 0.0]))
        print(f"  {m:10s} x{acc:<3d} {med * 100:6.2f} %  {sky * 100:6.2f} %")
    sun = T.write_exr(tmp / "sunsky.exr", T.sun_and_sky())
    stage = usda_stage(T.BOXES_USDA.format(tex=sun, intensity=0.5))
    ref, hit, light, normals = render_mitsuba(stage, W, H, spp=64, emitter_samples=16)
    print(f"sun-and-sky vs Mitsuba {W}x{H} (64 spp x 16 emitter samples): median, p95, umbra")
    for m in METHODS:
        acc = a.accumulate if m == "reference" else 1
        ours = stb_hydra.render(stage, width=W, height=H, lighting=m, accumulate=acc)
        errs, mask, _ = compare(ours, ref, hit, light, normals)
        umbra = T.shadow_error(ours, ref, hit, mask)
        print(
            f"  {m:10s} x{acc:<3d} {np.median(errs) * 100:6.2f} % "
            f"{np.percentile(errs, 95) * 100:6.2f} %  {umbra * 100:6.2f} %"
        )


if __name__ == "__main__":
    main()
