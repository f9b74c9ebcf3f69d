#!/usr/bin/env python3
"""Textured-RectLight accuracy (issue 37 item 3), the figures of docs/DOME.md.

A 1 m x 0.5 m rect 0.6 m above a floor, facing it, with four textures (8-bit sRGB):
``half`` (white | black), ``quad`` (four colours, 2 x 2), ``checker`` (16 x 16 coloured
checker over a gradient: finer than the exact methods' 8 x 8 cells) and ``softbox``
(16 x 16, a bright centre falling off smoothly to the edges). Floors: Lambert (albedo
0.5, seen from above) and GGX metal (roughness 0.3, area_scenes' glossy floor).

Truth: the same rect as one untextured rect light per texel (each integrated exactly by
the reference: a piecewise-constant texture is exactly that). Reported: median / p95
relative luminance error (pixels above 1 % of the truth's maximum) of the reference
(8 x 8 cells), STB (2 x 2 cells x the textured-LTC lookup) and the former model (the rect
emitting its texture's mean), unshadowed, one frame.

    PYTHONPATH=$PWD:$PWD/tests .venv/bin/python tools/rect_texture_accuracy.py [--size 96x54]

``--bench-scenes DIR`` instead writes the cost scenes of docs/PERFORMANCE.md ("Textured
RectLights"): tests/area_scenes.py's floor + box under its rect light, with the
``softbox`` texture (``rect_tex.usda``) and without (``rect_plain.usda``, the same mean
colour), for ``stb bench``.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
import OpenImageIO as oiio

import stb_hydra

TEXTURES = ("half", "quad", "checker", "softbox")


def texture(name: str) -> np.ndarray:
    """(h, w, 3) uint8 test texture."""
    if name == "half":
        img = np.zeros((1, 2, 3), np.uint8)
        img[0, 0] = 255
        return img
    if name == "quad":
        return np.array(
            [[[255, 255, 255], [255, 0, 0]], [[0, 255, 0], [0, 0, 255]]], dtype=np.uint8
        )
    yy, xx = np.mgrid[0:16, 0:16]
    if name == "checker":
        on = (xx + yy) % 2
        return np.stack([xx * 16 * on, yy * 16, (1 - on) * 255], axis=-1).astype(np.uint8)
    r = np.hypot(xx - 7.5, yy - 7.5) / 10.6
    v = np.clip(1.0 - r * r, 0.02, 1.0) ** 0.4545 * 255  # sRGB-ish encoded falloff
    return np.stack([v, v * 0.95, v * 0.85], axis=-1).astype(np.uint8)


def write_png(path: Path, img8: np.ndarray) -> str:
    h, w = img8.shape[:2]
    out = oiio.ImageOutput.create(str(path))
    out.open(str(path), oiio.ImageSpec(w, h, 3, oiio.UINT8))
    out.write_image(np.ascontiguousarray(img8))
    out.close()
    return str(path)


def rect(body: str, w: float, h: float, x: float, z: float, spec: int, k: int = 0) -> str:
    return (
        f'def RectLight "L{k}" {{\n    float inputs:specular = {spec}\n'
        f"    float inputs:width = {w}\n    float inputs:height = {h}\n{body}"
        f"    double3 xformOp:translate = ({x}, 0.6, {z})\n    float xformOp:rotateX = -90\n"
        '    uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateX"]\n}\n'
    )


def lights(img8: np.ndarray, path: str, model: str, spec: int, L: float = 1000.0) -> str:
    """The textured rect (``textured``), its mean (``mean``) or one rect per texel
    (``truth``; light +X = world +X, light +Y = world -Z, first column on +X)."""
    from stb_hydra.color.texture_spaces import srgb_to_linear

    lin = srgb_to_linear(img8.astype(np.float32) / 255.0).astype(np.float64)
    if model == "textured":
        body = f"    float inputs:intensity = {L}\n    asset inputs:texture:file = @{path}@\n"
        return rect(body, 1.0, 0.5, 0.0, 0.0, spec)
    if model == "mean":
        c = lin.mean(axis=(0, 1))
        col = f"    color3f inputs:color = ({c[0]}, {c[1]}, {c[2]})\n"
        return rect(f"    float inputs:intensity = {L}\n{col}", 1.0, 0.5, 0.0, 0.0, spec)
    ny, nx = lin.shape[:2]
    out = []
    for j in range(ny):
        for i in range(nx):
            c = lin[j, i]
            if c.max() <= 0:
                continue
            x = 0.5 - (i + 0.5) / nx
            z = -(0.25 - (j + 0.5) * 0.5 / ny)  # light +Y = world -Z
            col = f"    color3f inputs:color = ({c[0]}, {c[1]}, {c[2]})\n"
            body = f"    float inputs:intensity = {L}\n{col}"
            out.append(rect(body, 1 / nx, 0.5 / ny, x, z, spec, len(out)))
    return "".join(out)


def bench_scenes(out: Path) -> None:
    """``rect_tex.usda`` / ``rect_plain.usda`` in ``out`` (see the module docstring)."""
    from area_scenes import LIGHTS, SCENE_USDA

    from stb_hydra.color.texture_spaces import srgb_to_linear

    out.mkdir(parents=True, exist_ok=True)
    img8 = texture("softbox")
    path = write_png(out / "softbox.png", img8)
    c = srgb_to_linear(img8.astype(np.float32) / 255.0).astype(np.float64).mean(axis=(0, 1))
    tex = f"    float inputs:height = 0.5\n    asset inputs:texture:file = @{path}@\n"
    col = f"    float inputs:height = 0.5\n    color3f inputs:color = ({c[0]}, {c[1]}, {c[2]})\n"
    for name, body in (("rect_tex", tex), ("rect_plain", col)):
        light = LIGHTS["rect"].replace("    float inputs:height = 0.5\n", body)
        (out / f"{name}.usda").write_text(SCENE_USDA.format(light=light))
        print(out / f"{name}.usda")


def luma(img: np.ndarray) -> np.ndarray:
    return img[..., :3].astype(np.float64) @ np.array([0.2126, 0.7152, 0.0722])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", default="96x54")
    ap.add_argument("--textures", default=",".join(TEXTURES))
    ap.add_argument("--bench-scenes", metavar="DIR", help="write the cost scenes and stop")
    args = ap.parse_args()
    if args.bench_scenes:
        bench_scenes(Path(args.bench_scenes))
        return
    w, h = (int(v) for v in args.size.split("x"))
    from area_scenes import glossy_stage
    from stagegen import LAMBERT_FLOOR_USDA, usda_stage

    tmp = Path(tempfile.mkdtemp())
    print("| texture | floor | reference median / p95 | STB | mean (before) |")
    print("|---|---|---|---|---|")
    for name in args.textures.split(","):
        img8 = texture(name)
        path = write_png(tmp / f"{name}.png", img8)
        for floor in ("lambert", "glossy"):
            spec = int(floor == "glossy")

            def stage(model: str, spec: int = spec, floor: str = floor, img8=img8, path=path):
                text = lights(img8, path, model, spec)
                if floor == "lambert":
                    return usda_stage(LAMBERT_FLOOR_USDA.format(rho=0.5, light=text))
                return glossy_stage("rect", 0.3, text)

            kw = {"width": w, "height": h, "shadows": False}
            truth = luma(stb_hydra.render(stage("truth"), lighting="reference", **kw))
            m = truth > 0.01 * truth.max()
            cells = []
            for model, method in (("textured", "reference"), ("textured", "stb"), ("mean", "stb")):
                got = luma(stb_hydra.render(stage(model), lighting=method, **kw))
                rel = np.abs(got[m] - truth[m]) / truth[m]
                cells.append(f"{100 * np.median(rel):.2f} / {100 * np.percentile(rel, 95):.1f} %")
            print(f"| {name} | {floor} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()
