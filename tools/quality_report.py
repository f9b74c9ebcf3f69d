#!/usr/bin/env python3
"""What a person sees of STB on a few scenes: HDR-FLIP (reference at mid grey), the
structured-noise figure and relMSE of an A-frame STB still against ``reference``,
plus side-by-side crops (STB | reference) for the docs.

    .venv/bin/python tools/quality_report.py SCENE [SCENE...] --size 320x180 --frames 16 \\
        [--option K=V ...] [--crops DIR] [--json OUT.json]

Runs in-process on whatever ``stb_hydra`` is importable (``PYTHONPATH=<worktree>`` to
measure another revision). One line per scene on stdout.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np


def render(scene: str, method: str, size: tuple[int, int], frames: int, options: dict):
    from stb_hydra.renderer.engine import Engine
    from stb_hydra.renderer.frame import RenderSettings

    eng = Engine(
        scene,
        RenderSettings(
            width=size[0], height=size[1], lighting=method, method_options=dict(options)
        ),
    )
    try:
        t0 = time.perf_counter()
        eng.render(accumulate=frames)
        wall = time.perf_counter() - t0
        return eng.aovs["color"][..., :3].astype(np.float64), wall
    finally:
        eng.release()


def tonemap(img: np.ndarray, k: float) -> np.ndarray:
    x = np.maximum(img * k, 0.0)
    return np.clip(x / (1.0 + x), 0.0, 1.0) ** (1.0 / 2.2)


def write_png(path: Path, rgb: np.ndarray, zoom: int = 2) -> None:
    from stb_hydra.io.images import write_image

    big = np.repeat(np.repeat(rgb, zoom, 0), zoom, 1)
    write_image(path, big.astype(np.float32), display_referred=True)


def main(argv: list[str] | None = None) -> int:
    from stb_hydra.metrics import flip_hdr_midgrey, relmse, structured_noise

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scenes", nargs="+")
    ap.add_argument("--size", default="320x180")
    ap.add_argument("--frames", type=int, default=16)
    ap.add_argument("--option", "-o", action="append", default=[], metavar="K=V")
    ap.add_argument("--crops", type=Path, help="write <scene>.png: STB | reference")
    ap.add_argument("--json", type=Path)
    a = ap.parse_args(argv)
    w, h = (int(v) for v in a.size.lower().split("x"))
    options = dict(o.split("=", 1) for o in a.option)
    out = []
    for scene in a.scenes:
        stb, t_stb = render(scene, "stb", (w, h), a.frames, options)
        ref, _ = render(scene, "reference", (w, h), 1, {})
        rec = {
            "scene": scene,
            "size": [w, h],
            "frames": a.frames,
            "options": options,
            "hdr_flip": round(flip_hdr_midgrey(stb, ref), 4),
            "structure": round(structured_noise(stb, ref), 2),
            "relmse": round(relmse(stb, ref), 5),
            "mean_ratio": round(float(stb.mean() / max(ref.mean(), 1e-12)), 4),
            "stb_seconds": round(t_stb, 2),
        }
        out.append(rec)
        print(
            f"{Path(scene).name}: HDR-FLIP {rec['hdr_flip']:.3f}, structure "
            f"{rec['structure']:.2f}, relMSE {rec['relmse']:.3g}, mean {rec['mean_ratio']:.3f}"
            f" of the reference ({a.frames} frames, {w}x{h}, {options or 'defaults'})"
        )
        if a.crops:
            a.crops.mkdir(parents=True, exist_ok=True)
            lit = ref.mean(-1)
            lit = lit[lit > 0]  # background excluded: mid grey on the scene itself
            k = 0.18 / max(float(np.median(lit)) if lit.size else 1.0, 1e-12)
            side = np.concatenate([tonemap(stb, k), np.ones((h, 4, 3)), tonemap(ref, k)], 1)
            write_png(a.crops / f"{Path(scene).stem}.png", side)
    if a.json:
        a.json.write_text(json.dumps(out, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
