#!/usr/bin/env python3
"""The OpenChessSet's own looks, rendered beside the asset's ``teaser.png`` (issue 30).

Writes OUT_DIR/chess_looks.png (our render: the asset as shipped, a low camera
near the board like the teaser's, a warm key, a cool fill and a dim dome, the
reference method) and OUT_DIR/chess_looks_vs_teaser.png (the teaser, downscaled,
left; ours right). The teaser is an Arnold render with depth of field, subsurface,
transmission and an HDRI: compare materials (board squares, woods, marble, gold,
normal-map detail), not the lighting.

    .venv/bin/python tools/chess_looks.py docs/images [--width 960] [--height 540]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]

SCENE = """#usda 1.0
(
    metersPerUnit = 1
    upAxis = "Y"
)
def Xform "Set" (
    references = @{chess}@
)
{{
}}
def Camera "Cam"
{{
    float focalLength = 70
    float horizontalAperture = 36
    float verticalAperture = 20.25
    float2 clippingRange = (0.01, 100)
    double3 xformOp:translate = (0.06, 0.12, 0.95)
    float xformOp:rotateY = 4
    float xformOp:rotateX = -6
    uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateY", "xformOp:rotateX"]
}}
def SphereLight "Key"
{{
    float inputs:intensity = 1500
    float inputs:radius = 0.04
    float inputs:colorTemperature = 3400
    bool inputs:enableColorTemperature = 1
    double3 xformOp:translate = (-0.45, 0.55, 0.35)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}}
def SphereLight "Fill"
{{
    float inputs:intensity = 250
    float inputs:radius = 0.1
    float inputs:colorTemperature = 7500
    bool inputs:enableColorTemperature = 1
    double3 xformOp:translate = (0.6, 0.35, 0.5)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}}
def DomeLight "Sky"
{{
    float inputs:intensity = 0.6
}}
"""


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("out_dir", type=Path)
    ap.add_argument("--width", type=int, default=960)
    ap.add_argument("--height", type=int, default=540)
    ap.add_argument("--accumulate", type=int, default=4)
    args = ap.parse_args(argv)
    import OpenImageIO as oiio

    import stb_hydra
    from stb_hydra.color.ocio import ColorPipeline
    from stb_hydra.io.images import write_image

    shared = Path(os.environ.get("STB_SHARED", REPO.parent / "shared"))
    chess_dir = shared / "testdata" / "scenes" / "OpenChessSet"
    args.out_dir.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        scene = Path(tmp) / "chess_looks.usda"
        scene.write_text(SCENE.format(chess=(chess_dir / "chess_set.usda").as_posix()))
        rgb = stb_hydra.render(
            str(scene),
            width=args.width,
            height=args.height,
            lighting="reference",
            accumulate=args.accumulate,
        )
    ours = ColorPipeline().to_uint8(rgb)
    out = args.out_dir / "chess_looks.png"
    write_image(out, ours, display_referred=True)
    teaser = oiio.ImageBuf(str(chess_dir / "teaser.png"))
    roi = oiio.ROI(0, args.width, 0, args.height, 0, 1, 0, 3)
    small = oiio.ImageBufAlgo.resize(teaser, roi=roi)
    t = np.asarray(small.get_pixels(oiio.UINT8)).reshape(args.height, args.width, -1)[..., :3]
    gap = np.full((args.height, 8, 3), 255, np.uint8)
    both = np.concatenate([t, gap, ours[..., :3]], axis=1)
    write_image(args.out_dir / "chess_looks_vs_teaser.png", both, display_referred=True)
    print(f"wrote {out} and {args.out_dir / 'chess_looks_vs_teaser.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
