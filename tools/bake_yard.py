"""Issue 35 acceptance at full size: a 40 m ground quad, 24 ``UsdGeom.Cube`` boxes and
64 shadowed static sphere lights (``tests/stagegen.bake_yard_usda``), baked and
rendered with the reference method against the unbaked stage.

    PYTHONPATH=. python tools/bake_yard.py OUTDIR [--width 640] [--height 360]
        [--density 16] [--shadow-height H]

``--shadow-height`` (default: ``--height``) sizes the bake's shadow maps as a render of
that height does, so baked and unbaked images differ by the lightmaps only (a bake at
1080p compared with a 360p reference also differs by the reference's coarser shadow
maps). Prints and writes OUTDIR/bake_yard.json: the bake's seconds (unwrap, GPU,
write), texels, the texel-light throughput (sum over meshes of lightmap texels x
the baked lights whose range reaches the mesh, / GPU seconds), the achieved density
per mesh (min, max) and HDR-FLIP, relMSE and the mean ratio of the baked image; PNGs
of both renders.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("outdir")
    ap.add_argument("--width", type=int, default=640)
    ap.add_argument("--height", type=int, default=360)
    ap.add_argument("--density", type=float, default=16.0)
    ap.add_argument("--shadow-height", type=int, default=None)
    args = ap.parse_args(argv)
    sys.path.insert(0, str(ROOT / "tests"))
    from stagegen import bake_yard_usda

    import stb_hydra
    from stb_hydra.bake import bake_stage
    from stb_hydra.io.images import write_image
    from stb_hydra.metrics.image import relmse
    from stb_hydra.metrics.structure import flip_hdr_midgrey

    out = Path(args.outdir)
    out.mkdir(parents=True, exist_ok=True)
    src = out / "yard.usda"
    src.write_text(bake_yard_usda())
    baked = out / "yard_baked.usda"
    warnings: list[str] = []
    rep = bake_stage(
        src,
        baked,
        texel_density=args.density,
        cache_dir=out / "cache",
        progress=False,
        warn=warnings.append,
        shadow_view_height=args.shadow_height or args.height,
    )
    w, h = args.width, args.height
    t0 = time.perf_counter()
    ref = stb_hydra.render(str(src), width=w, height=h, lighting="reference")[..., :3]
    t1 = time.perf_counter()
    img = stb_hydra.render(str(baked), width=w, height=h, lighting="reference")[..., :3]
    t2 = time.perf_counter()
    write_image(out / "unbaked.png", ref)
    write_image(out / "baked.png", img)
    dens = [d for _w, _h, d in rep.densities.values()]
    res = {
        "size": [w, h],
        "density_asked": args.density,
        "shadow_view_height": args.shadow_height or args.height,
        "meshes": len(rep.meshes),
        "lights": len(rep.lights),
        "texels": rep.texels,
        "density_min": min(dens),
        "density_max": max(dens),
        "bake_s": rep.seconds,
        "texel_lights_in_range": rep.texel_lights,
        "texel_lights_per_s": rep.texel_lights / rep.seconds["gpu"],
        "render_unbaked_s": t1 - t0,
        "render_baked_s": t2 - t1,
        "flip_hdr": flip_hdr_midgrey(img, ref),
        "relmse": relmse(img, ref),
        "mean_ratio": float(img.mean() / ref.mean()),
        "warnings": warnings,
    }
    (out / "bake_yard.json").write_text(json.dumps(res, indent=2))
    print(json.dumps(res, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
