"""Area lights (issue 20): acceptance figures against Mitsuba 3, side-by-side crops,
the GGX check and the cost of the area model. Not a CLI verb; run from the checkout with
the tests' helpers importable (they hold the Mitsuba converter and the test scenes)::

    PYTHONPATH=$PWD:$PWD/tests python tools/area_lights.py accuracy --out docs/area_lights
    PYTHONPATH=$PWD:$PWD/tests python tools/area_lights.py specular
    PYTHONPATH=$PWD:$PWD/tests python tools/area_lights.py glossy --out docs/area_lights
    PYTHONPATH=$PWD:$PWD/tests python tools/area_lights.py cost

``--point-model`` renders with the area integration switched off (every light lit as a
point: what the renderer did before issue 20), by raising ``LIM_AREA_POINT_RATIO`` in
the generated GLSL constants of this process only.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np


def _point_model() -> None:
    from stb_hydra.renderer import shader_constants as sc

    sc.GLSL_CONSTANTS["LIM_AREA_POINT_RATIO"] = "1.0e9"
    sc.GLSL_CONSTANTS["LIM_AREA_SPEC_POINT"] = "1.0e9"
    sc.GLSL_CONSTANTS["LIM_AREA_SPEC_LTC"] = "2.0e9"


def _pcss() -> None:
    """Soft shadows of area lights by PCSS on the centre map (before the multi-point
    visibility): ``LIM_AREA_SHADOW_POINTS`` = 0 in this process's GLSL constants."""
    from stb_hydra.renderer import shader_constants as sc

    sc.GLSL_CONSTANTS["LIM_AREA_SHADOW_POINTS"] = "0"


def _png(path: Path, rgb: np.ndarray) -> None:
    import OpenImageIO as oiio

    img = np.ascontiguousarray(rgb.astype(np.uint8))
    out = oiio.ImageOutput.create(str(path))
    spec = oiio.ImageSpec(img.shape[1], img.shape[0], 3, oiio.UINT8)
    out.open(str(path), spec)
    out.write_image(img)
    out.close()


def _mitsuba_cached(
    cache: str, stage: object, name: str, spp: int, es: int, w: int, h: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``mitsuba_ref.render_mitsuba`` of ``stage``, kept in ``cache/`` (a folder; "" = no
    cache) under a key of the scene's text and the sample counts: Mitsuba's truths take
    minutes on a shared machine, and a shadow change does not change them."""
    import hashlib

    import mitsuba_ref as mr

    if cache:
        text = stage.GetRootLayer().ExportToString()  # type: ignore[attr-defined]
        key = hashlib.sha1(f"{text}|{w}x{h}|{spp}|{es}".encode()).hexdigest()[:16]
        f = Path(cache) / f"{name}_{key}.npz"
        if f.exists():
            z = np.load(f)
            return z["ref"], z["hit"], z["light"], z["nrm"]
    ref, hit, light, nrm = mr.render_mitsuba(stage, w, h, spp, emitter_samples=es)
    if cache:
        f.parent.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(f, ref=ref, hit=hit, light=light, nrm=nrm)
    return ref, hit, light, nrm


def accuracy(args: argparse.Namespace) -> None:
    """Per-pixel relative error against Mitsuba (median / p95 over pixels brighter than
    1 % of the floor's maximum; light-shape and silhouette-edge pixels left out), with
    the box (shadows) and without it; crops ours | Mitsuba | error map (0..10 %)."""
    import area_scenes
    import mitsuba_ref as mr

    import stb_hydra

    if args.point_model:
        _point_model()
    if args.pcss:
        _pcss()
    out = Path(args.out) if args.out else None
    if out:
        out.mkdir(parents=True, exist_ok=True)
    w, h = args.width, args.height
    print(
        f"{w}x{h}, Mitsuba {args.spp} spp x {args.emitter_samples} light samples "
        f"(point, spot: {4 * args.spp} spp x 1)"
    )
    print("| scene | box | median | p95 | pixels |")
    print("|---|---|---|---|---|")
    for kind in args.kinds.split(","):
        for box in (True, False):
            if args.box != "both" and box != (args.box == "yes"):
                continue
            if not box and kind in ("point", "spot"):
                continue
            stage = area_scenes.area_stage(kind) if box else area_scenes.area_stage_no_box(kind)
            # Mitsuba's `direct` integrator counts a delta light once per emitter sample
            # (x emitter_samples): point and spot get 4x the camera rays, 1 light sample.
            delta = kind in ("point", "spot")
            spp = 4 * args.spp if delta else args.spp
            es = 1 if delta else args.emitter_samples
            ref, hit, light, nrm = _mitsuba_cached(
                args.cache, stage, f"{kind}_{int(box)}", spp, es, w, h
            )
            ours = stb_hydra.render(stage, width=w, height=h, lighting="reference")
            err, mask, emap = mr.compare(ours, ref, hit, light, nrm)
            med, p95 = np.median(err) * 100, np.percentile(err, 95) * 100
            print(
                f"| {kind} | {'yes' if box else 'no'} | {med:.2f} % | {p95:.2f} % | {mask.sum()} |"
            )
            sys.stdout.flush()
            if out and box:
                s = np.percentile(mr.luminance(ref), 99.5)

                def tm(x: np.ndarray, s: float = s) -> np.ndarray:
                    return np.clip(x[..., :3] / s, 0, 1) ** (1 / 2.2) * 255

                sign = np.sign(mr.luminance(ours) - mr.luminance(ref))
                e = np.clip(emap / 0.1, 0, 1) * 255 * mask
                em = np.stack([e * (sign > 0), np.zeros_like(e), e * (sign < 0)], -1)
                row = np.concatenate([tm(ours), tm(ref), em], 1)
                row = np.repeat(np.repeat(row, 2, 0), 2, 1)
                suffix = "_point" if args.point_model else "_pcss" if args.pcss else ""
                _png(out / f"{kind}{suffix}.png", row)


def _half_d(V: np.ndarray, L: np.ndarray, a2: float) -> tuple[np.ndarray, np.ndarray]:
    """Half vectors H of V and the directions L (floor normal +Y) and GGX D(N.H)."""
    H = V + L
    H = H / np.linalg.norm(H, axis=-1, keepdims=True)
    noh = np.maximum(H[..., 1], 0)
    d = noh * noh * (a2 - 1) + 1
    return H, a2 / (math.pi * d * d)


def _ggx(V: np.ndarray, L: np.ndarray, a: float, f0: float) -> np.ndarray:
    """brdf.glsl's GGX x cos (floor normal +Y), numpy."""
    nol = L[..., 1]
    nov = max(float(V[1]), 1e-4)
    a2 = a * a
    H, D = _half_d(V, L, a2)
    voh = np.maximum((V * H).sum(-1), 0)
    gv = nol * math.sqrt(nov * nov * (1 - a2) + a2)
    gl = nov * np.sqrt(np.maximum(nol * nol * (1 - a2) + a2, 0))
    F = f0 + (1 - f0) * (1 - voh) ** 5
    return np.where(nol > 0, D * 0.5 / np.maximum(gv + gl, 1e-8) * F * nol, 0)


SPEC_STAGE = """#usda 1.0
(
    metersPerUnit = 1
    upAxis = "Y"
)
def Camera "Cam"
{{
    float focalLength = 18
    float horizontalAperture = 36
    float verticalAperture = 20.25
    double3 xformOp:translate = (0, 1.5, 2.5)
    float xformOp:rotateX = -30
    uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateX"]
}}
def Mesh "Ground" (
    prepend apiSchemas = ["MaterialBindingAPI"]
)
{{
    int[] faceVertexCounts = [4]
    int[] faceVertexIndices = [0, 1, 2, 3]
    point3f[] points = [(-6, 0, -6), (-6, 0, 6), (6, 0, 6), (6, 0, -6)]
    rel material:binding = </Looks/M>
}}
def Scope "Looks"
{{
    def Material "M"
    {{
        token outputs:surface.connect = </Looks/M/PBR.outputs:surface>
        def Shader "PBR"
        {{
            uniform token info:id = "UsdPreviewSurface"
            color3f inputs:diffuseColor = (0, 0, 0)
            int inputs:useSpecularWorkflow = 1
            color3f inputs:specularColor = (0.5, 0.5, 0.5)
            float inputs:roughness = {rough}
            token outputs:surface
        }}
    }}
}}
{light}
"""
SPEC_LIGHTS = {
    "rect": 'def RectLight "L" {\n float inputs:intensity = 1000\n float inputs:diffuse = 0\n'
    " float inputs:width = 1\n float inputs:height = 0.5\n"
    " double3 xformOp:translate = (0, 0.6, -0.5)\n float xformOp:rotateX = -90\n"
    ' uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateX"]\n}\n',
    "sphere": 'def SphereLight "L" {\n float inputs:intensity = 1000\n float inputs:diffuse = 0\n'
    " float inputs:radius = 0.25\n double3 xformOp:translate = (0, 0.6, -0.5)\n"
    ' uniform token[] xformOpOrder = ["xformOp:translate"]\n}\n',
}


def specular(args: argparse.Namespace) -> None:
    """GGX (f0 0.5, no diffuse) floor under a 1 x 0.5 m rect and a 0.25 m sphere: our
    reference against a 200 x 100 (rect) / 40,000-point (sphere) quadrature of the same
    lobe over the light's surface, shadows off."""
    from stagegen import plane_points, usda_stage

    import stb_hydra

    if args.point_model:
        _point_model()
    w, h = 64, 36
    cam = np.array([0.0, 1.5, 2.5])
    for kind in ("rect", "sphere"):
        if kind == "rect":
            n = 200
            u = (np.arange(n) + 0.5) / n - 0.5
            v = ((np.arange(n // 2) + 0.5) / (n // 2) - 0.5) * 0.5
            U, V = np.meshgrid(u, v, indexing="ij")
            pts = np.stack([U.ravel(), np.full(U.size, 0.6), -0.5 + V.ravel()], -1)
            nrm = np.tile([0.0, -1.0, 0.0], (len(pts), 1))
            dA = (1 / n) * (0.5 / (n // 2))
        else:
            m = 40000
            th = np.arccos(1 - 2 * (np.arange(m) + 0.5) / m)
            ph = np.arange(m) * 2.39996323
            nrm = np.stack([np.sin(th) * np.cos(ph), np.cos(th), np.sin(th) * np.sin(ph)], -1)
            pts = np.array([0, 0.6, -0.5]) + 0.25 * nrm
            dA = 4 * math.pi * 0.25**2 / m
        for rough in (0.2, 0.4, 0.7):
            stage = usda_stage(SPEC_STAGE.format(rough=rough, light=SPEC_LIGHTS[kind]))
            img = stb_hydra.render(stage, width=w, height=h, lighting="reference", shadows=False)
            img = img[..., 1].astype(np.float64)
            P = plane_points(stage, w, h).reshape(-1, 3)
            a = max(rough * rough, 0.002)
            ex = np.zeros(len(P))
            for i, p in enumerate(P):
                V = (cam - p) / np.linalg.norm(cam - p)
                dl = pts - p
                dist = np.linalg.norm(dl, axis=-1)
                L = dl / dist[:, None]
                ce = np.maximum(-(L * nrm).sum(-1), 0)
                ex[i] = (_ggx(V, L, a, 0.5) * 1000.0 * ce / dist**2).sum() * dA
            ex = ex.reshape(h, w)
            mk = ex > 0.01 * ex.max()
            rel = np.abs(img[mk] - ex[mk]) / ex[mk]
            core = ex > 0.1 * ex.max()
            relc = np.abs(img[core] - ex[core]) / ex[core]
            print(
                f"{kind} roughness {rough}: median {np.median(rel) * 100:.1f} %, "
                f"p95 {np.percentile(rel, 95) * 100:.1f} %, "
                f"sum ratio {img[mk].sum() / ex[mk].sum():.3f}; pixels over 10 % of the "
                f"maximum: median {np.median(relc) * 100:.1f} %, "
                f"p95 {np.percentile(relc, 95) * 100:.1f} %"
            )
            sys.stdout.flush()


def _ggx_sep(V: np.ndarray, L: np.ndarray, a: float) -> np.ndarray:
    """GGX x cos with Mitsuba's separable Smith G1(V) G1(L) and Fresnel 1 (floor +Y)."""
    nol = L[..., 1]
    nov = max(float(V[1]), 1e-4)
    a2 = a * a
    _, D = _half_d(V, L, a2)

    def g1(c: np.ndarray | float) -> np.ndarray:
        c = np.maximum(c, 1e-6)
        return 2.0 / (1.0 + np.sqrt(1.0 + a2 * (1.0 - c * c) / (c * c)))

    return np.where(nol > 0, D * g1(nov) * g1(nol) / (4.0 * nov), 0.0)


def _rect_quadrature(P: np.ndarray, cam: np.ndarray, a: float, sep: bool) -> np.ndarray:
    """Specular radiance per unit emitted radiance of area_scenes' rect (1 x 0.5 m, 0.6 m
    up, facing down) on a Fresnel-1 GGX floor: 200 x 100 midpoint quadrature."""
    n = 200
    u = (np.arange(n) + 0.5) / n - 0.5
    v = ((np.arange(n // 2) + 0.5) / (n // 2) - 0.5) * 0.5
    U, W = np.meshgrid(u, v, indexing="ij")
    pts = np.stack([U.ravel(), np.full(U.size, 0.6), W.ravel()], -1)
    dA = (1 / n) * (0.5 / (n // 2))
    out = np.zeros(len(P))
    for i, p in enumerate(P):
        V = (cam - p) / np.linalg.norm(cam - p)
        dl = pts - p
        dist = np.linalg.norm(dl, axis=-1)
        L = dl / dist[:, None]
        ce = np.maximum(L[:, 1], 0)
        f = _ggx_sep(V, L, a) if sep else _ggx(V, L, a, 1.0)
        out[i] = (f * ce / dist**2).sum() * dA
    return out


def glossy(args: argparse.Namespace) -> None:
    """Specular against Mitsuba: area_scenes.glossy_stage (GGX metal floor, Fresnel 1,
    no box), ours (reference) vs Mitsuba ``roughconductor`` (GGX, separable Smith G);
    for the rect also the two against a quadrature of our lobe and of Mitsuba's (the
    convention mismatch alone). Crops ours | Mitsuba | error (0..10 %) with --out."""
    import area_scenes
    import mitsuba_ref as mr
    from stagegen import plane_points

    import stb_hydra

    if args.point_model:
        _point_model()
    if args.pcss:
        _pcss()
    out = Path(args.out) if args.out else None
    w, h = args.width, args.height
    cam = np.array([0.0, 2.4, 2.2])
    print(f"{w}x{h}, Mitsuba {args.spp} spp x {args.emitter_samples} light samples")
    print("| light | roughness | median | p95 | pixels | over 10 % of max: median | p95 |")
    print("|---|---|---|---|---|---|---|")
    for kind in args.kinds.split(","):
        for rough in (float(x) for x in args.roughness.split(",")):
            stage = area_scenes.glossy_stage(kind, rough)
            ref, hit, light, nrm = mr.render_mitsuba(
                stage, w, h, args.spp, emitter_samples=args.emitter_samples
            )
            ours = stb_hydra.render(stage, width=w, height=h, lighting="reference")
            err, mask, emap = mr.compare(ours, ref, hit, light, nrm)
            yo, yr = mr.luminance(ours), mr.luminance(ref)
            core = mask & (yr > 0.1 * yr[mask].max())
            ec = np.abs(yo[core] - yr[core]) / yr[core]
            print(
                f"| {kind} | {rough} | {np.median(err) * 100:.2f} % | "
                f"{np.percentile(err, 95) * 100:.2f} % | {mask.sum()} | "
                f"{np.median(ec) * 100:.2f} % | {np.percentile(ec, 95) * 100:.2f} % |"
            )
            if kind == "rect" and args.quadrature:
                P = plane_points(stage, w, h).reshape(-1, 3)
                a = max(rough * rough, 0.002)
                qc = _rect_quadrature(P, cam, a, False).reshape(h, w) * 20000.0
                qs = _rect_quadrature(P, cam, a, True).reshape(h, w) * 20000.0
                for name, x, y in (
                    ("ours vs quadrature (our lobe)", yo, qc),
                    ("Mitsuba vs quadrature (separable G)", yr, qs),
                    ("quadrature separable vs correlated G", qs, qc),
                ):
                    e = np.abs(x[mask] - y[mask]) / y[mask]
                    e2 = np.abs(x[core] - y[core]) / y[core]
                    print(
                        f"|   {name} | {rough} | {np.median(e) * 100:.2f} % | "
                        f"{np.percentile(e, 95) * 100:.2f} % | | {np.median(e2) * 100:.2f} % | "
                        f"{np.percentile(e2, 95) * 100:.2f} % |"
                    )
            sys.stdout.flush()
            if out:
                s = np.percentile(yr, 99.5)

                def tm(x: np.ndarray, s: float = s) -> np.ndarray:
                    return np.clip(x[..., :3] / s, 0, 1) ** (1 / 2.2) * 255

                sign = np.sign(yo - yr)
                e = np.clip(emap / 0.1, 0, 1) * 255 * mask
                em = np.stack([e * (sign > 0), np.zeros_like(e), e * (sign < 0)], -1)
                row = np.concatenate([tm(ours), tm(ref), em], 1)
                row = np.repeat(np.repeat(row, 2, 0), 2, 1)
                _png(out / f"glossy_{kind}_{rough}.png", row)


def bench_scenes(args: argparse.Namespace) -> None:
    """Write the ``stb bench`` pair: ``area<N>.usda`` (area_scenes.many_area_lights_stage)
    and ``point<N>.usda``, the same lights shrunk to 1 % of their size with 10^4 x the
    radiance (same flux, hence the same shadow maps; lit with the point model: half
    extent / distance < limits.AREA_POINT_RATIO)."""
    import re

    import area_scenes

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    text = area_scenes.many_area_lights_stage(args.lights).GetRootLayer().ExportToString()
    (out / f"area{args.lights}.usda").write_text(text)

    def shrink(m: re.Match) -> str:
        return f"{m.group(1)} = {float(m.group(2)) * 0.01:.6g}"

    def brighten(m: re.Match) -> str:
        return f"{m.group(1)} = {float(m.group(2)) * 1e4:.6g}"

    pt = re.sub(r"(float inputs:(?:width|height|radius|length)) = ([0-9.e+-]+)", shrink, text)
    pt = re.sub(r"(float inputs:intensity) = ([0-9.e+-]+)", brighten, pt)
    (out / f"point{args.lights}.usda").write_text(pt)
    print(f"wrote {out / f'area{args.lights}.usda'}, {out / f'point{args.lights}.usda'}")


def cost_one(args: argparse.Namespace) -> None:
    """One engine, one model (a process of its own: programs are cached per context by
    their defines, not by the generated constants): prints frame and lighting medians."""
    import area_scenes

    from stb_hydra.apps.bench_core import measure_engine
    from stb_hydra.renderer.engine import Engine
    from stb_hydra.renderer.frame import RenderSettings

    if args.model == "point":
        _point_model()
    if args.model == "pcss":
        _pcss()
    stage = area_scenes.many_area_lights_stage(args.lights)
    eng = Engine(stage, RenderSettings(width=745, height=360, lighting=args.method, profile=True))
    try:
        m = measure_engine(eng, frames=args.frames, warmup=1)
    finally:
        eng.release()
    light = [sum(v for k, v in p.items() if k.startswith("lighting")) for p in m.passes]
    print(f"RESULT {float(np.median(m.frame)):.3f} {float(np.median(light)):.3f}")


def cost(args: argparse.Namespace) -> None:
    """Frame time of the area model against the point model (the same area lights),
    reference and STB, 745 x 360: one process per (model, repeat), the models run in
    turn ``--repeats`` times so that a shared machine's load drift hits them alike;
    medians over the repeats' ``--frames`` finished frames, and of the lighting task's
    time. ``--models point,pcss,area`` adds the area model with its shadows by PCSS."""
    import subprocess

    from stb_hydra.apps.bench_core import load_average

    models = args.models.split(",")
    print(
        f"745x360, {args.repeats} x {args.frames} frames each (median), "
        f"load average {load_average()}"
    )
    print(
        "| lights | method | "
        + " | ".join(f"{m}: frame / lighting (ms)" for m in models)
        + " | "
        + " | ".join(f"{m} / {models[0]}" for m in models[1:])
        + " |"
    )
    print("|---|---|" + "---|" * (2 * len(models) - 1))
    for cfg in args.configs.split(","):
        n_s, method = cfg.split(":")
        n = int(n_s)
        res: dict[str, list[tuple[float, float]]] = {m: [] for m in models}
        for _ in range(args.repeats):
            for model in models:
                cmd = [sys.executable, __file__, "_cost_one", "--model", model, "--method", method]
                cmd += ["--lights", str(n), "--frames", str(args.frames)]
                out = subprocess.run(cmd, capture_output=True, text=True, check=True).stdout
                line = next(x for x in out.splitlines() if x.startswith("RESULT"))
                f, li = (float(x) for x in line.split()[1:])
                res[model].append((f, li))
        med = {m: tuple(float(np.median([r[i] for r in res[m]])) for i in (0, 1)) for m in models}
        f0, l0 = med[models[0]]
        cells = [f"{med[m][0]:.0f} / {med[m][1]:.0f}" for m in models]
        ratios = [f"{med[m][0] / f0:.2f} / {med[m][1] / max(l0, 1e-9):.2f}" for m in models[1:]]
        print(f"| {n} | {method} | " + " | ".join(cells + ratios) + " |")
        sys.stdout.flush()


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    a = sub.add_parser("accuracy")
    a.add_argument("--out", default="")
    a.add_argument("--width", type=int, default=128)
    a.add_argument("--height", type=int, default=72)
    a.add_argument("--spp", type=int, default=256)
    a.add_argument("--emitter-samples", type=int, default=32)
    a.add_argument("--kinds", default="rect,disk,sphere,cylinder,point,spot")
    a.add_argument("--point-model", action="store_true")
    a.add_argument("--cache", default="", help="folder keeping Mitsuba's renders")
    a.add_argument("--pcss", action="store_true", help="area shadows by PCSS (before)")
    a.add_argument("--box", choices=("both", "yes", "no"), default="both")
    b = sub.add_parser("bench-scenes")
    b.add_argument("--out", required=True)
    b.add_argument("--lights", type=int, default=24)
    g = sub.add_parser("glossy")
    g.add_argument("--out", default="")
    g.add_argument("--width", type=int, default=128)
    g.add_argument("--height", type=int, default=72)
    g.add_argument("--spp", type=int, default=256)
    g.add_argument("--emitter-samples", type=int, default=32)
    g.add_argument("--kinds", default="rect,disk,sphere,cylinder")
    g.add_argument("--roughness", default="0.25,0.5")
    g.add_argument("--quadrature", action="store_true", help="rect: split the error")
    g.add_argument("--point-model", action="store_true")
    s = sub.add_parser("specular")
    s.add_argument("--point-model", action="store_true")
    c = sub.add_parser("cost")
    c.add_argument("--frames", type=int, default=4)
    c.add_argument("--repeats", type=int, default=2)
    c.add_argument("--models", default="point,area")
    c.add_argument("--configs", default="24:reference,24:stb,120:stb")
    o = sub.add_parser("_cost_one")
    o.add_argument("--model", choices=("point", "area", "pcss"), required=True)
    o.add_argument("--method", default="reference")
    o.add_argument("--lights", type=int, default=24)
    o.add_argument("--frames", type=int, default=4)
    args = ap.parse_args(argv)
    t = time.perf_counter()
    cmds = {
        "accuracy": accuracy,
        "glossy": glossy,
        "bench-scenes": bench_scenes,
        "specular": specular,
        "cost": cost,
        "_cost_one": cost_one,
    }
    cmds[args.cmd](args)
    print(f"({time.perf_counter() - t:.0f} s)")


if __name__ == "__main__":
    main()
