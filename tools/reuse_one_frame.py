"""One frame of STB with reservoir reuse (issue 31) beside the defaults' and the
reference: HDR-FLIP (mid grey) of a single frame, no averaging, after ``--frames``
frames of history (``--temporal off``: the reuse keeps its reservoirs between frames).

    .venv/bin/python tools/reuse_one_frame.py usd_scenes/default.usda --size 320x180 \\
        --frames 8 --out docs/stb_quality/reuse_one_frame.png -o reuse=on -o N=4 \\
        -o reuse_mis=pairwise

Writes defaults | reuse | reference (display-referred, tone-mapped at mid grey).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np


def last_frame(scene: str, size: tuple[int, int], method: str, opts: dict, n: int) -> np.ndarray:
    """The ``n``-th single frame of one engine (history carried over)."""
    from stb_hydra.renderer.engine import Engine
    from stb_hydra.renderer.frame import RenderSettings

    settings = RenderSettings(
        width=size[0], height=size[1], lighting=method, temporal="off", method_options=opts
    )
    eng = Engine(scene, settings)
    try:
        for _ in range(n):
            eng.render()
        return eng.aovs["color"][..., :3].astype(np.float64)
    finally:
        eng.release()


def main(argv: list[str] | None = None) -> int:
    sys.path.insert(0, str(Path(__file__).parent))
    from quality_report import tonemap, write_png

    from stb_hydra.metrics import flip_hdr_midgrey

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scene")
    ap.add_argument("--size", default="320x180")
    ap.add_argument("--frames", type=int, default=8)
    ap.add_argument("--out", type=Path)
    ap.add_argument("--option", "-o", action="append", default=[], metavar="K=V")
    a = ap.parse_args(argv)
    w, h = (int(v) for v in a.size.lower().split("x"))
    opts = dict(o.split("=", 1) for o in a.option)
    ref = last_frame(a.scene, (w, h), "reference", {}, 1)
    base = last_frame(a.scene, (w, h), "stb", {}, 1)
    reuse = last_frame(a.scene, (w, h), "stb", opts, a.frames)
    print(
        f"{Path(a.scene).name} {w}x{h}: one frame HDR-FLIP, defaults "
        f"{flip_hdr_midgrey(base, ref):.3f}; {opts} (frame {a.frames}) "
        f"{flip_hdr_midgrey(reuse, ref):.3f}"
    )
    if a.out:
        lit = ref.mean(-1)
        k = 0.18 / max(float(np.median(lit[lit > 0])) if (lit > 0).any() else 1.0, 1e-12)
        gap = np.ones((h, 4, 3))
        side = np.concatenate([tonemap(base, k), gap, tonemap(reuse, k), gap, tonemap(ref, k)], 1)
        write_png(a.out, side, zoom=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
