"""Issue 17 acceptance: the default courtyard with its unanimated lamps static and baked.

    PYTHONPATH=. python tools/bake_acceptance.py OUTDIR [--width 640] [--frames 8]

1. ``mark_static_layer``: the 34 unanimated local lights -> ``stb:mobility = static``
   (de-instanced), ``stb bake`` at the default texel density (bake time, lightmap size);
2. reference method, baked vs all-dynamic: HDR-FLIP (mid-grey exposed) over the image
   and relMSE over diffuse surfaces (roughness >= 0.5, metallic < 0.1);
3. STB accumulating A=1 and A=16 frames, baked vs all-dynamic, one process: median
   frame time and FLIP against the all-dynamic reference.
Writes OUTDIR/bake_acceptance.json and PNGs. The machine may be shared: times are
medians of interleaved runs, compare the ratios.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from stb_hydra.bake import bake_stage
from stb_hydra.bake.mark import mark_static_layer
from stb_hydra.io.images import write_image
from stb_hydra.metrics.image import relmse
from stb_hydra.metrics.structure import flip_hdr_midgrey
from stb_hydra.renderer.engine import Engine
from stb_hydra.renderer.frame import RenderSettings

ROOT = Path(__file__).resolve().parents[1]


def _surface_mask(eng: Engine) -> np.ndarray:
    """Diffuse surface pixels (roughness >= 0.5, metallic < 0.1), top row first."""

    def rd(name: str) -> np.ndarray:
        t = eng.buffers.textures[name]
        w, h = t.size
        return np.flipud(np.frombuffer(t.read(), dtype=np.float16).reshape(h, w, -1))

    br, fm = rd("g_base_rough"), rd("g_f0_metal")
    d = eng.buffers.textures["g_depth"]
    w, h = d.size
    depth = np.flipud(np.frombuffer(d.read(), dtype=np.float32).reshape(h, w))
    return (depth > 0) & (br[..., 3] >= 0.5) & (fm[..., 3] < 0.1)


def flip_map(test: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Per-pixel HDR-FLIP with the reference's median exposed to mid grey (as
    ``metrics.structure.flip_hdr_midgrey``, whose mean is this map's mean)."""
    import flip_evaluator

    k = 0.18 / max(float(np.median(ref.mean(axis=-1))), 1e-12)
    t = np.nan_to_num(np.maximum(test * k, 0.0)).astype(np.float32)
    r = np.nan_to_num(np.maximum(ref * k, 0.0)).astype(np.float32)
    m, _mean, _p = flip_evaluator.evaluate(r, t, "HDR", applyMagma=False)
    return np.asarray(m).reshape(ref.shape[:2])


def render(path: Path, w: int, lighting: str, acc: int) -> tuple[np.ndarray, Engine]:
    """``acc`` frames accumulated (A)."""
    eng = Engine(
        path, RenderSettings(width=w, height=w * 9 // 16, lighting=lighting, accumulate=acc)
    )
    eng.render()
    return eng.aovs["color"][..., :3].copy(), eng


def frame_ms(engines: dict[str, Engine], frames: int) -> dict[str, float]:
    """Median wall time per frame, engines interleaved frame by frame."""
    times: dict[str, list[float]] = {k: [] for k in engines}
    for e in engines.values():
        e.render_frame()  # warm-up (shader compiles, shadow maps)
    for _ in range(frames):
        for k, e in engines.items():
            e.ctx.finish()
            t0 = time.perf_counter()
            e.render_frame()
            e.ctx.finish()
            times[k].append((time.perf_counter() - t0) * 1e3)
    return {k: float(np.median(v)) for k, v in times.items()}


def pass_ms(engines: dict[str, Engine], frames: int = 3) -> dict[str, dict[str, float]]:
    """Median GPU-synchronised time of the main passes (``profile=True`` frames)."""
    out: dict[str, dict[str, float]] = {}
    for k, e in engines.items():
        e.settings.profile = True
        for _ in range(frames):
            e.render_frame()
        e.settings.profile = False
        fr = e.timings.frames[-frames:]
        names = ("shadow_atlas", "gbuffer", "lightmap", "lighting", "color_correction")
        out[k] = {n: float(np.median([f.get(n, 0.0) for f in fr])) for n in names}
    return out


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("outdir")
    ap.add_argument("--width", type=int, default=640)
    ap.add_argument("--frames", type=int, default=8)
    ap.add_argument("--texel-density", type=float, default=None)
    a = ap.parse_args()
    out = Path(a.outdir)
    out.mkdir(parents=True, exist_ok=True)
    static = out / "court_static.usda"
    baked = out / "court_baked.usda"
    marked = mark_static_layer(ROOT / "usd_scenes" / "default.usda", static)
    kw = {} if a.texel_density is None else {"texel_density": a.texel_density}
    rep = bake_stage(
        static,
        baked,
        cache_dir=out / "xatlas_cache",
        progress=False,
        warn=lambda m: print("warning:", m, file=sys.stderr),
        **kw,
    )
    res: dict = {
        "static_lights": len(marked),
        "baked_lights": len(rep.lights),
        "baked_meshes": len(rep.meshes),
        "skipped_meshes": rep.skipped,
        "bake_seconds": rep.seconds,
        "lightmap_texels": rep.texels,
        "lightmap_gpu_MiB": rep.gpu_bytes / 2**20,
        "width": a.width,
    }
    ref, e_ref = render(static, a.width, "reference", 1)
    mask = _surface_mask(e_ref)
    img, e_b = render(baked, a.width, "reference", 1)
    fm = flip_map(img, ref)
    res["reference"] = {
        "flip_hdr": flip_hdr_midgrey(img, ref),
        "flip_hdr_diffuse": float(fm[mask].mean()),
        "relmse_diffuse": relmse(img[mask][None], ref[mask][None]),
        "relmse_all": relmse(img, ref),
        "diffuse_fraction": float(mask.mean()),
    }
    lm = e_b.task("lightmap")
    res["lightmap_resident_MiB"] = getattr(lm, "gpu_bytes", 0) / 2**20
    write_image(out / "ref_dynamic.png", ref)
    write_image(out / "ref_baked.png", img)
    write_image(out / "ref_diff_x4.png", np.abs(img - ref) * 4.0)
    e_ref.release()
    e_b.release()
    for method, A in (("stb", 1), ("stb", 16), ("reference", 1)):
        engines = {}
        imgs = {}
        for name, p in (("dynamic", static), ("baked", baked)):
            imgs[name], engines[name] = render(p, a.width, method, A)
        ms = frame_ms(engines, a.frames)
        res[f"{method}_A{A}"] = {
            "frame_ms": ms,
            "pass_ms": pass_ms(engines),
            "speedup": ms["dynamic"] / max(ms["baked"], 1e-9),
            "flip_hdr": {k: flip_hdr_midgrey(v, ref) for k, v in imgs.items()},
            "flip_hdr_diffuse": {k: float(flip_map(v, ref)[mask].mean()) for k, v in imgs.items()},
        }
        for e in engines.values():
            e.release()
    (out / "bake_acceptance.json").write_text(json.dumps(res, indent=2))
    print(json.dumps(res, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
