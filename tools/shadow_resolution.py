"""Shadow-map resolution policy, measured (issue 33 item 5): map sizes, atlas texels,
capture time and the image against a render whose every map is 4x denser (2 octaves
up the policy's own target, ``--truth-scale``), with the reference method, offline
(every map captured before the frame).

Works on any revision whose scheduler calls ``stb_hydra.shadows.policy.target_texels``
(the truth patches that function) and whose ``RenderSettings`` has ``shadow_resolution``
(always passed: the truth and ``--resolution flux`` name "flux" whatever the default),
so before / after comparisons run the same script:

    .venv/bin/python tools/shadow_resolution.py usd_scenes/default.usda --size 320x180
    python -m stb_hydra.scenegen.chess /tmp/chess64.usda --lights 64
    .venv/bin/python tools/shadow_resolution.py /tmp/chess64.usda --size 320x180

Prints one JSON object per scene (``--json`` writes them). Figures: docs/PERFORMANCE.md
"Map resolution against the screen footprint" and the sections after it ("lift":
``--resolution lift``, ``--lift-ratio``).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np


def _render(
    scene: str,
    width: int,
    height: int,
    frames: int,
    scale: float,
    resolution: str = "flux",
    atlas_size: int | None = None,
) -> dict:
    from pxr import Usd

    from stb_hydra.renderer.engine import Engine
    from stb_hydra.renderer.frame import RenderSettings
    from stb_hydra.shadows import policy

    orig = policy.target_texels
    orig_fp = getattr(policy, "footprint_texels", None)

    def scaled(*a, **kw):
        return orig(*a, **kw) * scale

    def scaled_fp(*a, **kw):
        return orig_fp(*a, **kw) * scale

    policy.target_texels = scaled  # type: ignore[assignment]
    if orig_fp is not None:
        policy.footprint_texels = scaled_fp  # type: ignore[assignment]
    try:
        stage = Usd.Stage.Open(scene)
        # Always named: the default changed (flux -> lift) and the truth is flux-sized.
        extra: dict = {"shadow_resolution": resolution}
        if atlas_size:
            extra["shadow_atlas_size"] = atlas_size
        settings = RenderSettings(
            width=width,
            height=height,
            lighting="reference",
            accumulate=frames,
            profile=True,
            **extra,  # type: ignore[arg-type]
        )
        eng = Engine(stage, settings)
        try:
            eng.request_aovs({"color"})
            if resolution != "flux":  # the footprint is measured on a frame's G-buffer:
                eng.render(None)  # one render before, so every measured frame uses it
            t0 = time.perf_counter()
            eng.render(None)
            wall = time.perf_counter() - t0
            img = np.array(eng.aovs["color"][..., :3], dtype=np.float32)
            atlas = eng.task("shadow_atlas")
            sch = atlas.scheduler
            sides = np.array(
                [sch.rect(k).size for k in atlas.registered_keys() if sch.rect(k) is not None]
            )
            cap = sum(
                t.get("prepare.shadow_atlas", 0.0) + t.get("shadow_atlas", 0.0)
                for t in eng.timings.frames
            )
            st = atlas.last_stats
        finally:
            eng.release()
    finally:
        policy.target_texels = orig  # type: ignore[assignment]
        if orig_fp is not None:
            policy.footprint_texels = orig_fp  # type: ignore[assignment]
    return {
        "img": img,
        "maps": len(sides),
        "side_median": float(np.median(sides)) if len(sides) else 0.0,
        "side_max": int(sides.max()) if len(sides) else 0,
        "side_min": int(sides.min()) if len(sides) else 0,
        "mtexels": round(float((sides.astype(np.float64) ** 2).sum()) / 1e6, 3),
        "unplaced": st.unplaced,
        "undersized": st.undersized,
        "shadow_ms": round(cap, 1),
        "wall_s": round(wall, 2),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenes", nargs="+")
    ap.add_argument("--size", default="320x180")
    ap.add_argument("--frames", type=int, default=4, help="accumulated frames")
    ap.add_argument("--truth-scale", type=float, default=4.0)
    ap.add_argument(
        "--truth-atlas",
        type=int,
        default=None,
        help="atlas side of the truth render (e.g. 8192 with --truth-scale 1000: every "
        "map at the maximum side, not limited by the default atlas)",
    )
    ap.add_argument(
        "--percentile",
        type=float,
        default=None,
        help="limits.SHADOW_FOOTPRINT_PERCENTILE for the policy's image (footprint, max)",
    )
    ap.add_argument(
        "--lift-ratio",
        type=float,
        default=None,
        help="limits.SHADOW_LIFT_MIN_RATIO for the policy's image (lift)",
    )
    ap.add_argument("--scale", type=float, default=1.0, help="scale of the policy's targets")
    ap.add_argument(
        "--resolution",
        default="flux",
        help="RenderSettings.shadow_resolution of the policy's image: flux, footprint, max",
    )
    ap.add_argument("--no-truth", action="store_true", help="skip the truth render (use --against)")
    ap.add_argument("--json", type=Path)
    ap.add_argument(
        "--against",
        type=Path,
        help="also compare with this .npy image (e.g. another revision's --save)",
    )
    ap.add_argument("--save", type=Path, help="save the policy's image as .npy (one scene)")
    ap.add_argument("--save-truth", type=Path, help="save the truth image as .npy (one scene)")
    a = ap.parse_args()
    from stb_hydra.metrics.image import flip_hdr, relmse

    w, h = (int(v) for v in a.size.lower().split("x"))
    if a.percentile is not None:
        from stb_hydra import limits

        limits.SHADOW_FOOTPRINT_PERCENTILE = a.percentile
    if a.lift_ratio is not None:
        from stb_hydra import limits as _limits

        _limits.SHADOW_LIFT_MIN_RATIO = a.lift_ratio
    rows = []
    for scene in a.scenes:
        got = _render(scene, w, h, a.frames, a.scale, a.resolution)
        img = got.pop("img")
        row = {
            "scene": scene,
            "size": a.size,
            "resolution": a.resolution,
            "scale": a.scale,
            "percentile": a.percentile,
            "lift_ratio": a.lift_ratio,
            **got,
        }
        if not a.no_truth:
            truth = _render(scene, w, h, a.frames, a.truth_scale, atlas_size=a.truth_atlas)
            ref = truth.pop("img")
            row.update(
                {
                    "truth": truth,
                    "hdr_flip_vs_truth": round(float(flip_hdr(img, ref)), 4),
                    "relmse_vs_truth": float(f"{relmse(img, ref):.3g}"),
                    "mean_ratio": round(float(img.mean() / max(ref.mean(), 1e-30)), 4),
                }
            )
        if a.save:
            np.save(a.save, img)
        if a.save_truth and not a.no_truth:
            np.save(a.save_truth, ref)
        if a.against:
            other = np.load(a.against)
            row["hdr_flip_vs_against"] = round(float(flip_hdr(img, other)), 4)
            row["relmse_vs_against"] = float(f"{relmse(img, other):.3g}")
        print(json.dumps(row))
        rows.append(row)
    if a.json:
        a.json.write_text(json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
