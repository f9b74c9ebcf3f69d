"""``stb bake SCENE -o OUT.usda``: static lights' direct light into lightmaps (docs/BAKE.md)."""

from __future__ import annotations

import argparse
from pathlib import Path

from .. import limits
from .common import EXIT_OK, fail


def add_parser(sub) -> None:
    p = sub.add_parser(
        "bake",
        help="bake static lights (stb:mobility = static) into lightmaps",
        description="Unwrap static meshes with xatlas, bake the direct light of static "
        "lights (with shadows) on the GPU into EXR lightmaps, and write OUT.usda: it "
        "sublayers SCENE and adds the lightmap UVs, the lightmap files and "
        "stb:baked = true on the baked lights.",
    )
    p.add_argument("scene", help="USD file")
    p.add_argument("-o", "--output", required=True, help="output layer (.usda)")
    p.add_argument(
        "--texel-density",
        type=float,
        default=limits.BAKE_TEXEL_DENSITY_DEFAULT,
        help=f"lightmap texels per metre (default {limits.BAKE_TEXEL_DENSITY_DEFAULT:g})",
    )
    p.add_argument("--jobs", type=int, default=1, help="threads for the xatlas unwrap")
    p.add_argument(
        "--shadow-height",
        type=int,
        default=limits.BAKE_SHADOW_VIEW_HEIGHT,
        help="view height (px) the shadow maps are sized for, as a render of that height "
        f"(default {limits.BAKE_SHADOW_VIEW_HEIGHT})",
    )
    p.add_argument("--camera", default=None, help="camera whose exposure sets light ranges")
    p.add_argument("--cache-dir", default=None, help="unwrap cache (default ~/.cache/stb_hydra)")
    p.add_argument("--quiet", action="store_true", help="no progress bar or summary")
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    from ..bake import bake_stage
    from ..io.files import FileWriteError
    from ..io.images import ImageWriteError
    from ..renderer.engine import RenderError

    out = Path(args.output)
    if out.suffix.lower() not in (".usda", ".usd"):
        return fail(f"'{out}': the output must be a .usda layer")
    if not out.parent.is_dir():
        return fail(f"'{out}': no such directory '{out.parent}'")
    if not (args.texel_density > 0):
        return fail(f"--texel-density must be > 0, got {args.texel_density:g}")
    if args.shadow_height < 1:
        return fail(f"--shadow-height must be >= 1, got {args.shadow_height}")
    if args.jobs < 1:
        return fail(f"--jobs must be >= 1, got {args.jobs}")
    rep_cli = getattr(args, "reporter", None)
    warn = rep_cli.warn if rep_cli is not None else (lambda m: None)
    try:
        rep = bake_stage(
            args.scene,
            out,
            texel_density=args.texel_density,
            jobs=args.jobs,
            cache_dir=Path(args.cache_dir) if args.cache_dir else None,
            camera=args.camera,
            warn=warn,
            progress=not args.quiet,
            shadow_view_height=args.shadow_height,
        )
    except (RenderError, FileWriteError, ImageWriteError, ValueError) as exc:
        return fail(str(exc))
    if not args.quiet and rep_cli is not None:
        for path, (w, h, dens) in rep.densities.items():
            rep_cli.say(
                f"  {path}: {w} x {h} texels, {dens:.3f} texels/m (asked {args.texel_density:g})"
            )
        rep_cli.say(
            f"baked {len(rep.lights)} light(s) into {len(rep.meshes)} mesh lightmap(s), "
            f"{rep.texels / 1e6:.2f} Mtexel ({rep.gpu_bytes / 2**20:.1f} MiB on the GPU), "
            f"{rep.seconds.get('total', 0.0):.1f} s -> {out}"
        )
    return EXIT_OK
