"""Generate a many-light test scene: a ground plane, occluder boxes and N local lights.

N (50 to 100,000+) lights of mixed UsdLux types are scattered over a square ground
at 0.5-3 m height with log-uniform luminous flux and mixed colours (blackbody
2000-9000 K or saturated hues); M of them move on time-sampled circular paths, the
rest are static. A fraction casts shadows, and a fraction of those asks for dynamic
shadow maps (StbLightAPI ``stb:shadow:update = "dynamic"``). A camera frames the
square from a raised corner, exposed for the scene's mean illuminance.

    python -m stb_hydra.scenegen.lights out/lights_10k.usda --lights 10000 --animated 100

(``python tools/gen_lights_scene.py ...`` in a checkout is the same command.)
In Python (tests, benchmarks, ``stb bench gen:lights:N``)::

    from stb_hydra.scenegen.lights import build_lights_stage
    stage = build_lights_stage(n_lights=10_000, seed=1, animated=100)  # in memory

Light types (``--types``): sphere (SphereLight), spot (SphereLight + ShapingAPI
cone, aimed down), disk (DiskLight, facing down), rect (RectLight, facing down),
ies (SphereLight + one of the IES profiles of usd_scenes/ies, normalised, aimed down;
``ies_dir`` / ``--ies-dir`` names that folder, by default the package's copy,
``stb_hydra/data/ies``); and, only when asked for (not in the default mix), point
(SphereLight with ``treatAsPoint``: a point light of the sphere's intensity; setting
a sphere's radius to 0 instead makes it emit nothing, its intensity being in nits).
Intensities are UsdLux luminance in nits derived from the drawn flux:
sphere/spot/point L = Phi/(4 pi * pi r^2) (spot: before the cone cuts it), ies
L = Phi/(2 pi * pi r^2) (normalised hemispherical profile), disk L = Phi/(pi^2 r^2),
rect L = Phi/(pi w h).

Deterministic: the same arguments give byte-identical .usda text (numpy PCG64).
The file is written as text (0.5 s for 10k lights, ~3 s for 100k on a 2-core box);
.usdc output converts that text through Sdf's crate writer (1.4 s at 10k, ~18 s at
100k: usd-core's Python-side crate export is the bottleneck, not the generator).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from .common import (
    REC709_Y,
    UsdaWriter,
    asset_path,
    box,
    exposure_for_illuminance,
    hsv_to_rgb,
    merge,
    plane,
    save,
    stage_from_text,
)
from .common import ies_dir as _ies_dir

ALL_TYPES = ("sphere", "spot", "disk", "rect", "ies")  # the default mix
#: Every type ``--types`` accepts: the default mix and point lights.
KNOWN_TYPES = (*ALL_TYPES, "point")
#: IES profile -> cone angle to author (180 = no cone: the uplight emits upwards).
IES_PROFILES = {
    "streetlamp_typeII": 90.0,
    "downlight_narrow": 90.0,
    "wallwash": 90.0,
    "uplight": 180.0,
}
TYPE_TOKENS = {
    "sphere": "SphereLight",
    "spot": "SphereLight",
    "disk": "DiskLight",
    "rect": "RectLight",
    "ies": "SphereLight",
    "point": "SphereLight",
}


def default_size(n_lights: int) -> float:
    """Ground side (m) keeping ~1 light per 8 m^2: 20 m for <= 50 lights, ~283 m for
    10k, ~894 m for 100k. Pass ``size`` to pack lights densely instead."""
    return float(max(20.0, round(20.0 * math.sqrt(n_lights / 50.0), 1)))


def _parse_types(s: str | Sequence[str]) -> tuple[str, ...]:
    types = tuple(t.strip() for t in (s.split(",") if isinstance(s, str) else s) if t.strip())
    bad = [t for t in types if t not in KNOWN_TYPES]
    if bad or not types:
        raise ValueError(f"unknown light types {bad}; choose from {','.join(KNOWN_TYPES)}")
    return types


def _occluders(rng: np.random.Generator, size: float) -> np.ndarray:
    """(B, 6) axis-aligned boxes lo.xyz, hi.xyz on the ground."""
    n = int(np.clip(round(size * size / 40.0), 6, 300))
    c = rng.uniform(-0.45 * size, 0.45 * size, (n, 2))
    half = rng.uniform(0.2, 1.25, (n, 2))
    h = rng.uniform(0.5, 3.5, n)
    lo = np.stack([c[:, 0] - half[:, 0], np.zeros(n), c[:, 1] - half[:, 1]], -1)
    hi = np.stack([c[:, 0] + half[:, 0], h, c[:, 1] + half[:, 1]], -1)
    return np.round(np.concatenate([lo, hi], -1), 3)


def _positions(rng: np.random.Generator, n: int, size: float, boxes: np.ndarray) -> np.ndarray:
    """Uniform over the ground at 0.5-3 m, re-drawn while inside an occluder (+0.2 m)."""
    pos = np.empty((n, 3))
    todo = np.arange(n)
    for _ in range(64):
        k = len(todo)
        pos[todo, 0] = rng.uniform(-0.5 * size, 0.5 * size, k)
        pos[todo, 1] = rng.uniform(0.5, 3.0, k)
        pos[todo, 2] = rng.uniform(-0.5 * size, 0.5 * size, k)
        p = pos[todo]
        inside = np.zeros(k, bool)
        for b in boxes:
            inside |= np.all((p > b[:3] - 0.2) & (p < b[3:] + 0.2), axis=1)
        todo = todo[inside]
        if not len(todo):
            break
    return np.round(pos, 3) + 0.0  # + 0.0 turns -0.0 into 0.0 (no "-0.000" in the text)


def lights_scene_usda(
    n_lights: int = 1000,
    seed: int = 0,
    animated: int = 0,
    types: str | Sequence[str] = ALL_TYPES,
    shadow_fraction: float = 0.25,
    dynamic_fraction: float = 0.25,
    size: float | None = None,
    frames: int = 48,
    sample_step: int = 2,
    lumens: tuple[float, float] = (100.0, 2000.0),
    anchor_dir: Path | str | None = None,
    ies_dir: Path | str | None = None,
    light_range: float | None = None,
) -> str:
    """The scene as .usda text. ``light_range``: an influence radius (m) authored on
    every light (``stb:range``) instead of the automatic one, which follows each light's
    peak intensity at the camera's exposure (an IES beam's peak is 10-50x a sphere's of
    the same flux, so its sphere of influence reaches far to the sides as well); None
    keeps the automatic range. ``anchor_dir``: directory the file will live in (IES
    paths are written relative to it); None writes absolute IES paths. ``ies_dir``:
    folder of the ``<profile>.ies`` files (default: the checkout's usd_scenes/ies;
    only needed when ``types`` includes ``ies``)."""
    if n_lights < 1:
        raise ValueError("need at least one light")
    if light_range is not None and not (math.isfinite(light_range) and light_range > 0):
        raise ValueError(f"light_range must be a positive number of metres, got {light_range}")
    if not 0 <= animated <= n_lights:
        raise ValueError("--animated must be between 0 and --lights")
    types = _parse_types(types)
    size = float(size) if size else default_size(n_lights)
    rng = np.random.default_rng(seed)
    n = n_lights

    boxes = _occluders(rng, size)
    pos = _positions(rng, n, size, boxes)
    kind = rng.integers(0, len(types), n)
    flux = np.exp(rng.uniform(math.log(lumens[0]), math.log(lumens[1]), n))
    radius = rng.uniform(0.02, 0.15, n)
    rect_w = rng.uniform(0.1, 1.0, n)
    rect_h = rng.uniform(0.05, 0.5, n)
    use_kelvin = rng.random(n) < 0.5
    kelvin = np.round(rng.uniform(2000.0, 9000.0, n), -1)
    rgb = hsv_to_rgb(rng.random(n), rng.uniform(0.3, 0.9, n), np.ones(n))
    rgb_y = rgb @ np.array(REC709_Y)  # colours keep max 1; nits compensate
    shadowed = rng.random(n) < shadow_fraction
    dynamic = shadowed & (rng.random(n) < dynamic_fraction)
    cone = rng.uniform(20.0, 60.0, n)
    softness = rng.uniform(0.1, 0.5, n)
    tilt = rng.uniform(-25.0, 25.0, n)
    yaw = rng.uniform(-180.0, 180.0, n)
    ies_pick = rng.integers(0, len(IES_PROFILES), n)
    moving = np.zeros(n, bool)
    if animated:
        moving[rng.choice(n, animated, replace=False)] = True
    orbit_r = rng.uniform(0.5, 3.0, n)
    orbit_phase = rng.uniform(0.0, 2 * math.pi, n)
    orbit_dir = np.where(rng.random(n) < 0.5, -1.0, 1.0)
    bob = rng.uniform(0.0, 0.4, n)

    # luminance (nits) from flux, per type
    tname = np.array(types)[kind]
    nits = np.empty(n)
    area_r = math.pi * radius**2
    m = (tname == "sphere") | (tname == "spot") | (tname == "point")
    nits[m] = flux[m] / (4 * math.pi) / area_r[m]
    m = tname == "ies"
    nits[m] = flux[m] / (2 * math.pi) / area_r[m]
    m = tname == "disk"
    nits[m] = flux[m] / (math.pi * area_r[m])
    m = tname == "rect"
    nits[m] = flux[m] / (math.pi * rect_w[m] * rect_h[m])
    # A coloured light's luminous flux is scaled by its colour's luminance (blackbody
    # colours are luminance-normalised by UsdLux already): divide it out.
    nits = np.where(use_kelvin, nits, nits / rgb_y)

    ies_names = list(IES_PROFILES)
    ies_assets = ["@@"] * len(ies_names)  # only referenced by "ies" lights
    if "ies" in types:
        folder = _ies_dir(ies_dir)
        ies_assets = [asset_path(folder / f"{name}.ies", anchor_dir) for name in ies_names]
    sample_frames = list(range(1, frames + 1, max(1, sample_step)))
    if sample_frames[-1] != frames:
        sample_frames.append(frames)
    tf = 2 * math.pi * (np.asarray(sample_frames, float) - 1.0) / frames

    # Mean illuminance on the ground ~ 0.6 * total flux / area (half of an isotropic
    # light's flux goes down, nearly all of a down-facing one's) -> exposure.
    e_mean = 0.6 * float(flux.sum()) / (size * size)
    exposure = exposure_for_illuminance(e_mean)

    w = UsdaWriter()
    counts = {t: int(np.sum(tname == t)) for t in types}
    w.header(
        doc=(
            f"stb_hydra many-light scene: {n} lights ("
            + ", ".join(f"{v} {k}" for k, v in counts.items())
            + f"), {int(moving.sum())} animated, {int(shadowed.sum())} shadowed "
            f"({int(dynamic.sum())} dynamic), on a {size:g} m square.\n"
            f"Generated by tools/gen_lights_scene.py --lights {n} --seed {seed} "
            f"--animated {animated} --types {','.join(types)} --shadow-fraction "
            f"{shadow_fraction:g} --dynamic-fraction {dynamic_fraction:g} --size {size:g}.\n"
            "Units: metres; inputs:intensity is luminance in nits; flux per light "
            f"{lumens[0]:g}-{lumens[1]:g} lm (log-uniform). Mean ground illuminance "
            f"~{e_mean:.1f} lx."
        ),
        default_prim="World",
        start=1,
        end=frames,
        fps=24.0,
    )
    with w.prim("Xform", "World", meta=['kind = "assembly"']):
        with w.prim("Scope", "Looks"):
            w.preview_material(
                "Ground", "/World/Looks/Ground", diffuse=(0.35, 0.35, 0.35), roughness=0.8
            )
            w.preview_material(
                "Occluder", "/World/Looks/Occluder", diffuse=(0.55, 0.5, 0.45), roughness=0.6
            )
        with w.prim("Xform", "Geometry"):
            w.mesh(
                "Ground",
                plane(size * 1.1, size * 1.1),
                material="/World/Looks/Ground",
                doc=f"{size * 1.1:g} m square ground plane (normal +Y).",
                nd=3,
            )
            occ = merge(box(b[:3], b[3:], bottom=False) for b in boxes)
            w.mesh(
                "Occluders",
                occ,
                material="/World/Looks/Occluder",
                doc=f"{len(boxes)} axis-aligned boxes, 0.5-3.5 m tall.",
                nd=3,
            )
        with w.prim("Xform", "Lights"):
            pad = w.pad
            parts: list[str] = []
            for i in range(n):
                parts.append(
                    _light_text(
                        pad,
                        i,
                        tname[i],
                        nits[i],
                        radius[i],
                        rect_w[i],
                        rect_h[i],
                        use_kelvin[i],
                        kelvin[i],
                        rgb[i],
                        shadowed[i],
                        dynamic[i],
                        cone[i],
                        softness[i],
                        tilt[i],
                        yaw[i],
                        ies_names[ies_pick[i]],
                        ies_assets[ies_pick[i]],
                        pos[i],
                        _orbit(pos[i], orbit_r[i], orbit_phase[i], orbit_dir[i], bob[i], tf)
                        if moving[i]
                        else None,
                        sample_frames,
                        light_range,
                    )
                )
            w.raw("".join(parts).rstrip("\n"))
    eye = (-0.55 * size, 0.3 * size + 1.5, 0.75 * size)
    w.camera(
        "Camera",
        eye=eye,
        target=(0.0, 0.0, -0.05 * size),
        focal_length=24.0,
        clipping=(0.1, max(200.0, 3.0 * size)),
        exposure=exposure,
        comment=f"exposure from the mean ground illuminance ~{e_mean:.1f} lx "
        "(an 18 % card under it -> 0.18 scene-linear).",
    )
    return w.text()


def _orbit(p, r, phase, direction, bob, tf) -> np.ndarray:
    a = phase + direction * tf
    x = p[0] + r * (np.cos(a) - math.cos(phase))
    z = p[2] - r * (np.sin(a) - math.sin(phase))
    y = np.maximum(p[1] + bob * np.sin(2 * tf), 0.3)
    return np.round(np.stack([x, y, z], -1), 3) + 0.0


def _f(x: float, nd: int = 3) -> str:
    return f"{x:.{nd}f}"


def _light_text(
    pad,
    i,
    t,
    nits,
    r,
    rw,
    rh,
    use_k,
    k,
    rgb,
    shadow,
    dyn,
    cone,
    soft,
    tilt,
    yaw,
    ies_name,
    ies_asset,
    pos,
    path,
    frames,
    light_range=None,
) -> str:
    token = TYPE_TOKENS[t]
    schemas = (["ShapingAPI"] if t in ("spot", "ies") else []) + ["ShadowAPI"]
    if dyn:
        schemas.append("StbLightAPI")
    p2 = pad + "    "
    out = [
        f'{pad}def {token} "L{i:06d}" (\n{p2}prepend apiSchemas = '
        + "["
        + ", ".join(f'"{s}"' for s in schemas)
        + "]\n"
        + f"{pad})\n{pad}{{\n"
    ]
    if use_k:
        out.append(
            f"{p2}float inputs:colorTemperature = {k:.0f}\n"
            f"{p2}bool inputs:enableColorTemperature = 1\n"
        )
    else:
        out.append(f"{p2}color3f inputs:color = ({rgb[0]:.3f}, {rgb[1]:.3f}, {rgb[2]:.3f})\n")
    out.append(f"{p2}float inputs:intensity = {nits:.1f}\n")
    if t == "rect":
        out.append(f"{p2}float inputs:width = {rw:.3f}\n{p2}float inputs:height = {rh:.3f}\n")
    else:
        out.append(f"{p2}float inputs:radius = {r:.3f}\n")
    if t == "point":
        out.append(f"{p2}bool treatAsPoint = 1\n")
    if t == "spot":
        out.append(
            f"{p2}float inputs:shaping:cone:angle = {cone:.1f}\n"
            f"{p2}float inputs:shaping:cone:softness = {soft:.2f}\n"
        )
    elif t == "ies":
        out.append(
            f"{p2}float inputs:shaping:cone:angle = {IES_PROFILES[ies_name]:.0f}\n"
            f"{p2}asset inputs:shaping:ies:file = {ies_asset}\n"
            f"{p2}bool inputs:shaping:ies:normalize = 1\n"
        )
    out.append(f"{p2}bool inputs:shadow:enable = {1 if shadow else 0}\n")
    if light_range is not None:
        out.append(f"{p2}float stb:range = {light_range:g}\n")
    if dyn:
        out.append(f'{p2}uniform token stb:shadow:update = "dynamic"\n')
    order = ['"xformOp:translate"']
    if path is None:
        out.append(f"{p2}double3 xformOp:translate = ({pos[0]:.3f}, {pos[1]:.3f}, {pos[2]:.3f})\n")
    else:
        out.append(f"{p2}double3 xformOp:translate.timeSamples = {{\n")
        out.extend(
            f"{p2}    {f}: ({q[0]:.3f}, {q[1]:.3f}, {q[2]:.3f}),\n" for f, q in zip(frames, path)
        )
        out.append(f"{p2}}}\n")
    if t not in ("sphere", "point"):
        # -Z (emission / cone / IES nadir axis) down, tilted for spots/disks/rects.
        tl = 0.0 if t == "ies" else tilt
        out.append(f"{p2}float3 xformOp:rotateXYZ = ({-90.0 + tl:.1f}, {yaw:.1f}, 0)\n")
        order.append('"xformOp:rotateXYZ"')
    out.append(f"{p2}uniform token[] xformOpOrder = [{', '.join(order)}]\n{pad}}}\n\n")
    return "".join(out)


def build_lights_stage(
    n_lights: int = 1000,
    seed: int = 0,
    animated: int = 0,
    path: str | Path | None = None,
    **kwargs,
):
    """Generate the scene and return a ``Usd.Stage``: in memory when ``path`` is None
    (IES paths absolute), else written to ``path`` (.usda/.usdc) and opened from it.
    ``kwargs``: types, shadow_fraction, dynamic_fraction, size, frames, sample_step,
    lumens, ies_dir (see :func:`lights_scene_usda`)."""
    from pxr import Usd

    if path is None:
        return stage_from_text(lights_scene_usda(n_lights, seed, animated, **kwargs))
    path = Path(path)
    text = lights_scene_usda(n_lights, seed, animated, anchor_dir=path.resolve().parent, **kwargs)
    save(text, path)
    return Usd.Stage.Open(str(path))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    ap.add_argument("out", type=Path, help="output .usda (text) or .usdc (crate)")
    ap.add_argument("--lights", type=int, default=1000, help="number of lights N")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--animated", type=int, default=0, help="M lights on time-sampled paths")
    ap.add_argument(
        "--types",
        default=",".join(ALL_TYPES),
        help="comma-separated subset of " + ",".join(ALL_TYPES),
    )
    ap.add_argument(
        "--shadow-fraction",
        type=float,
        default=0.25,
        help="fraction of lights with shadows enabled",
    )
    ap.add_argument(
        "--dynamic-fraction",
        type=float,
        default=0.25,
        help="fraction of the shadowed lights with dynamic shadow maps",
    )
    ap.add_argument(
        "--size",
        type=float,
        default=None,
        help="ground side in metres (default: ~1 light per 8 m^2, >= 20 m)",
    )
    ap.add_argument("--frames", type=int, default=48, help="animation length (24 fps)")
    ap.add_argument(
        "--sample-step",
        type=int,
        default=2,
        help="frames between translate samples of animated lights",
    )
    ap.add_argument(
        "--lumens",
        type=float,
        nargs=2,
        default=(100.0, 2000.0),
        metavar=("MIN", "MAX"),
        help="log-uniform flux range per light",
    )
    ap.add_argument(
        "--ies-dir",
        type=Path,
        default=None,
        help="folder of the IES profiles (default: the package's stb_hydra/data/ies)",
    )
    ap.add_argument(
        "--light-range",
        type=float,
        default=None,
        help="influence radius (m) authored on every light (default: automatic)",
    )
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    try:
        text = lights_scene_usda(
            args.lights,
            args.seed,
            args.animated,
            types=args.types,
            shadow_fraction=args.shadow_fraction,
            dynamic_fraction=args.dynamic_fraction,
            size=args.size,
            frames=args.frames,
            sample_step=args.sample_step,
            lumens=tuple(args.lumens),
            anchor_dir=args.out.resolve().parent,
            ies_dir=args.ies_dir,
            light_range=args.light_range,
        )
    except (ValueError, FileNotFoundError) as e:
        ap.error(str(e))
    save(text, args.out)
    print(
        f"wrote {args.out}: {args.lights} lights, {args.animated} animated, "
        f"{args.out.stat().st_size / 1e6:.1f} MB in {time.perf_counter() - t0:.2f} s"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
