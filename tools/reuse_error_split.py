#!/usr/bin/env python3
"""Where an STB still's error is (issue 31): HDR-FLIP / structure / relMSE / mean of an
A-frame ``--lighting stb`` still against ``reference``, and the mean HDR-FLIP map split
by what differs -- shadowed vs unshadowed pixels (a second reference with local shadows
off: a pixel is "shadowed" when shadows remove > 20 % of its light), scene regions
(``--regions``: pieces / board / table from depth, normal and albedo), and the share of
the error each carries. References are cached (``--cache DIR``), keyed by scene, size and
the shadows flag.

    PYTHONPATH=. .venv/bin/python tools/reuse_error_split.py SCENE --size 320x180 \\
        --frames 16 -o reuse=on -o N=4 [--shadows off] [--crops OUT.png]

``--shadows off`` renders the STB still *and* compares against the reference without
local shadows: what is left is the light-selection noise alone.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import time
from pathlib import Path

import numpy as np


def render(scene, method, size, frames, options, shadows=True, aovs=(), seed=0):
    from stb_hydra.renderer.engine import Engine
    from stb_hydra.renderer.frame import RenderSettings

    eng = Engine(
        scene,
        RenderSettings(
            width=size[0],
            height=size[1],
            lighting=method,
            shadows=shadows,
            method_options=dict(options),
            seed=seed,
        ),
    )
    try:
        if aovs:
            eng.request_aovs(aovs)
        t0 = time.perf_counter()
        eng.render(accumulate=frames)
        wall = time.perf_counter() - t0
        out = {k: np.array(v) for k, v in eng.aovs.items()}
        return out, wall
    finally:
        eng.release()


def reference(scene, size, shadows, cache: Path):
    """Reference colour (h, w, 3) and depth / normal / albedo AOVs, cached."""
    key = hashlib.sha1(f"{Path(scene).resolve()}|{size}|{shadows}".encode()).hexdigest()[:12]
    f = cache / f"ref_{Path(scene).stem}_{size[0]}x{size[1]}_{int(shadows)}_{key}.npz"
    if f.exists():
        d = np.load(f)
        return {k: d[k] for k in d.files}
    out, _ = render(scene, "reference", size, 1, {}, shadows, ("depth", "normal", "albedo"))
    cache.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(f, **out)
    return out


def flip_map(test, ref):
    """Per-pixel HDR-FLIP with the reference's median at mid grey (as flip_hdr_midgrey)."""
    from stb_hydra.metrics.image import _flip

    k = 0.18 / max(float(np.median(ref.mean(-1))), 1e-12)
    t = np.nan_to_num(np.maximum(test * k, 0.0)).astype(np.float32)
    r = np.nan_to_num(np.maximum(ref * k, 0.0)).astype(np.float32)
    m, mean, _ = _flip().evaluate(r, t, "HDR", applyMagma=False)
    return np.asarray(m, np.float64).reshape(ref.shape[:2]), float(mean)


def main(argv=None) -> int:
    from stb_hydra.metrics import relmse, structured_noise

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scene")
    ap.add_argument("--size", default="160x90")
    ap.add_argument("--frames", type=int, default=16)
    ap.add_argument("--option", "-o", action="append", default=[], metavar="K=V")
    ap.add_argument("--shadows", choices=("on", "off"), default="on")
    ap.add_argument("--cache", type=Path, default=Path("/tmp/stb_ref_cache"))
    ap.add_argument("--crops", type=Path, help="STB | reference | FLIP map, PNG")
    ap.add_argument("--save", type=Path, help="the STB still, .npy")
    ap.add_argument("--json", type=Path)
    ap.add_argument("--seed", type=int, default=0, help="the STB still's RenderSettings.seed")
    a = ap.parse_args(argv)
    w, h = (int(v) for v in a.size.lower().split("x"))
    options = dict(o.split("=", 1) for o in a.option)
    sh = a.shadows == "on"
    ref_d = reference(a.scene, (w, h), sh, a.cache)
    ref = ref_d["color"][..., :3].astype(np.float64)
    unsh = reference(a.scene, (w, h), False, a.cache)["color"][..., :3].astype(np.float64)
    out, wall = render(a.scene, "stb", (w, h), a.frames, options, sh, seed=a.seed)
    stb = out["color"][..., :3].astype(np.float64)
    if a.save:
        np.save(a.save, stb.astype(np.float32))
    fm, fmean = flip_map(stb, ref)
    lum_r, lum_u = ref.mean(-1), unsh.mean(-1)
    geo = ref_d["depth"].reshape(h, w, -1)[..., 0] > 0
    geo &= np.isfinite(ref_d["depth"].reshape(h, w, -1)[..., 0])
    shadowed = geo & (lum_r < 0.8 * lum_u)
    n = ref_d["normal"].reshape(h, w, -1)[..., :3]
    alb = ref_d["albedo"].reshape(h, w, -1)[..., :3]
    up = np.abs(n[..., 1]) > 0.95  # Y up: board and table tops
    table = up & (np.abs(alb - np.array([0.25, 0.16, 0.1])).max(-1) < 0.03)
    board = up & ~table
    pieces = geo & ~up
    regions = {
        "all": np.ones_like(geo),
        "shadowed (>20% of light blocked)": shadowed,
        "unshadowed": geo & ~shadowed,
        "board (up-facing, not table)": board,
        "table": table,
        "pieces / vertical": pieces,
        "background": ~geo,
    }
    tot = fm.sum()
    rec = {
        "scene": a.scene,
        "options": options,
        "shadows": a.shadows,
        "hdr_flip": round(fmean, 4),
        "structure": round(structured_noise(stb, ref), 2),
        "relmse": round(relmse(stb, ref), 5),
        "mean_ratio": round(float(stb.mean() / max(ref.mean(), 1e-12)), 4),
        "seconds": round(wall, 1),
        "regions": {},
    }
    print(
        f"{Path(a.scene).name} {options} shadows {a.shadows}: HDR-FLIP {rec['hdr_flip']:.3f}, "
        f"structure {rec['structure']:.2f}, relMSE {rec['relmse']:.3g}, "
        f"mean {rec['mean_ratio']:.3f} ({a.frames} frames, {w}x{h}, {wall:.0f} s)"
    )
    for name, m in regions.items():
        if not m.any():
            continue
        r = {
            "pixels": round(float(m.mean()), 3),
            "flip": round(float(fm[m].mean()), 4),
            "share": round(float(fm[m].sum() / max(tot, 1e-12)), 3),
            "mean_ratio": round(float(stb[m].mean() / max(ref[m].mean(), 1e-12)), 4),
        }
        rec["regions"][name] = r
        print(
            f"  {name:34s} {r['pixels']:6.1%} of pixels  FLIP {r['flip']:.3f}  "
            f"share {r['share']:5.1%}  mean {r['mean_ratio']:.3f}"
        )
    if a.crops:
        from stb_hydra.io.images import write_image

        def tm(img, k):
            x = np.maximum(img * k, 0.0)
            return np.clip(x / (1.0 + x), 0.0, 1.0) ** (1.0 / 2.2)

        lit = ref.mean(-1)
        k = 0.18 / max(float(np.median(lit[lit > 0])), 1e-12)
        fmc = np.repeat(np.clip(fm, 0, 1)[..., None], 3, -1)
        gap = np.ones((h, 4, 3))
        side = np.concatenate([tm(stb, k), gap, tm(ref, k), gap, fmc], 1)
        big = np.repeat(np.repeat(side, 2, 0), 2, 1)
        write_image(a.crops, big.astype(np.float32), display_referred=True)
    if a.json:
        a.json.write_text(json.dumps(rec, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
