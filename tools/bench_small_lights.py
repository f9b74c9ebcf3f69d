#!/usr/bin/env python3
"""Shading cost of the exact many-light methods when lights are small.

5,000 lights of 1-5 lm (``stb_hydra.scenegen.lights``, ranges ~1-3 m), so most
lights do not reach a given pixel: the case where culling, clusters and light
trees pay off. For ``clustered``, the ``lighttree`` modes (hybrid, all trees,
tree-only with 2D tiles, lists only), uncapped ``tiled`` and ``reference``:
renders 3 frames at 745x360 with shadow maps unbudgeted (steady state) and
prints the per-pass medians of the last two, the cell statistics, and the
relMSE of each image against the first method's (they are exact: ~0).

    .venv/bin/python tools/bench_small_lights.py [--lights 5000] [--no-reference]
"""

from __future__ import annotations

import argparse
import os

import numpy as np

CONFIGS = [
    ("clustered", {}),
    ("lighttree", {}),
    ("lighttree", {"mode": "tree"}),
    ("lighttree", {"mode": "tree", "slices": 0}),
    ("lighttree", {"mode": "list"}),
    ("tiled", {"tile_cap": None}),
    ("reference", {}),
]
STATS = ("fov_lights", "list_entries", "max_cell_lights", "tree_cells", "list_cells", "tree_nodes")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--lights", type=int, default=5000)
    ap.add_argument("--size", default="745x360")
    ap.add_argument("--no-reference", action="store_true", help="skip the (slow) reference")
    a = ap.parse_args(argv)

    import stb_hydra  # noqa: F401
    from stb_hydra.metrics import relmse
    from stb_hydra.renderer.engine import Engine
    from stb_hydra.renderer.frame import RenderSettings
    from stb_hydra.scenegen.lights import build_lights_stage

    w, h = (int(x) for x in a.size.split("x"))
    print("load", os.getloadavg()[0], flush=True)
    stage = build_lights_stage(a.lights, seed=0, lumens=(1.0, 5.0))
    ref = None
    for method, opts in CONFIGS:
        if method == "reference" and a.no_reference:
            continue
        eng = Engine(
            stage,
            RenderSettings(
                width=w,
                height=h,
                lighting=method,
                profile=True,
                method_options=dict(opts),
                shadow_budget=1 << 40,
            ),
        )
        try:
            eng.request_aovs({"color"})
            frame = [eng.render_frame() for _ in range(3)][-1]
            img = eng.aovs["color"][..., :3].copy()
            ref = img if ref is None else ref
            rows = eng.timings.frames[-2:]
            keys = sorted(
                k for k in rows[-1] if k.startswith("lighting.") or k == "prepare.lighting"
            )
            med = {k: round(float(np.median([r.get(k, 0.0) for r in rows])), 1) for k in keys}
            stats = {k: frame.stats.get(k) for k in STATS if k in frame.stats}
            print(method, opts, med, stats, f"relMSE vs first {relmse(img, ref):.2g}", flush=True)
        finally:
            eng.release()
    print("load", os.getloadavg()[0])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
