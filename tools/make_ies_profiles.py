#!/usr/bin/env python3
"""Write stb_hydra's own synthetic IES LM-63-2002 photometric profiles.

Every profile here is made up from closed-form shapes (no measured data, nothing
copied): TILT=NONE, photometric type C (vertical angle 0 = nadir, i.e. the
luminaire's downward axis, 180 = zenith), units in metres, one lamp. The candela
table is scaled so that its integral over the sphere equals the rated lumens
written on the counts line (relative photometry, multiplier 1.0).

Orientation in USD (UsdLux ShapingAPI): the vertical angle is measured from the
light's -Z axis (the cone axis), the horizontal angle from the light's +X axis
towards +Y. Our prefabs rotate IES lights with rotateX -90 so -Z points down
(world -Y) and the IES nadir is down; horizontal 0 then points along prefab +X.

Usage: python tools/make_ies_profiles.py [--out usd_scenes/ies] [--check]
Deterministic: running it twice writes byte-identical files.
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from stb_hydra.scenegen.common import write_text_atomic

IES_DIR = Path(__file__).resolve().parents[1] / "usd_scenes" / "ies"  # this checkout's

ISSUE_DATE = "2025-08-10"


@dataclass(frozen=True)
class Profile:
    name: str
    lumens: float
    vertical: np.ndarray  # degrees, ascending
    horizontal: np.ndarray  # degrees, ascending; [0] = axially symmetric
    shape: Callable[[np.ndarray, np.ndarray], np.ndarray]  # (V, H) degrees -> relative cd
    luminaire: str
    lumcat: str
    lamp: str
    input_watts: float
    opening_m: tuple[float, float, float]  # width, length, height (negative = round)
    other: str


def _smoothstep(e0: float, e1: float, x: np.ndarray) -> np.ndarray:
    t = np.clip((x - e0) / (e1 - e0), 0.0, 1.0)
    return t * t * (3 - 2 * t)


def _street_typeII(v: np.ndarray, h: np.ndarray) -> np.ndarray:
    """IES Type II roadway: two lateral lobes thrown up and down the road (H ~ 65 deg
    from the street-side axis, mirrored to 295 by the bilateral symmetry), peaking at
    ~68 deg vertical, a broad cosine fill underneath, dimmer towards the house side
    (H = 180), full cut-off (no light at or above the horizon)."""
    vr, hr = np.radians(v), np.radians(h)
    fill = 0.45 * np.cos(vr) ** 0.8
    side = 0.6 + 0.4 * np.cos(hr)  # street side (H=0) brighter than house side (H=180)
    lobe = np.exp(-(((v - 68.0) / 11.0) ** 2)) * np.exp(-(((h - 65.0) / 30.0) ** 2))
    return (fill * side + 1.9 * lobe) * (1.0 - _smoothstep(80.0, 90.0, v))


def _downlight_narrow(v: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Axial narrow downlight: Gaussian core with 25 deg FWHM beam (half-max at 12.5 deg)
    plus 3 % wide spill from the reflector, cut off at the horizon."""
    core = np.exp(-math.log(2.0) * (v / 12.5) ** 2)
    spill = 0.03 * np.cos(np.radians(v)) ** 2
    return (core + spill) * (1.0 - _smoothstep(60.0, 90.0, v))


def _wallwash(v: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Asymmetric wall washer: kicked towards the wall (H = 0) at ~38 deg from nadir,
    spreading sideways (bilateral about the 0-180 plane), little to the room side."""
    vr, hr = np.radians(v), np.radians(h)
    towards_wall = (0.5 + 0.5 * np.cos(hr)) ** 2
    kick = np.exp(-(((v - 38.0) / 17.0) ** 2)) * towards_wall
    base = 0.18 * np.cos(vr)
    return (base + kick) * (1.0 - _smoothstep(78.0, 90.0, v))


def _uplight(v: np.ndarray, h: np.ndarray) -> np.ndarray:
    """Axial in-ground uplight: 60 deg FWHM beam to the zenith (V = 180) plus a soft
    4 % flood, nothing below the horizon (V <= 90)."""
    g = 180.0 - v  # angle from zenith
    beam = np.exp(-math.log(2.0) * (g / 30.0) ** 2)
    flood = 0.04 * np.cos(np.radians(g))
    return (beam + flood) * (1.0 - _smoothstep(75.0, 90.0, g))


PROFILES: tuple[Profile, ...] = (
    Profile(
        name="streetlamp_typeII",
        lumens=5000.0,
        vertical=np.arange(0.0, 90.0 + 1e-9, 5.0),
        horizontal=np.arange(0.0, 180.0 + 1e-9, 10.0),
        shape=_street_typeII,
        luminaire="STB-ROAD-II synthetic LED roadway luminaire, IES Type II, full cut-off",
        lumcat="STB-ROAD-II-5K",
        lamp="LED module 5000 lm 3000 K (synthetic)",
        input_watts=38.0,
        opening_m=(0.5, 0.25, 0.0),
        other="H=0 street side, H=90 along the road, H=180 house side",
    ),
    Profile(
        name="downlight_narrow",
        lumens=800.0,
        vertical=np.arange(0.0, 90.0 + 1e-9, 2.5),
        horizontal=np.array([0.0]),
        shape=_downlight_narrow,
        luminaire="STB-DL-25 synthetic recessed downlight, 25 deg beam (FWHM)",
        lumcat="STB-DL-25-800",
        lamp="LED 800 lm 4000 K (synthetic)",
        input_watts=8.0,
        opening_m=(-0.08, -0.08, 0.0),
        other="axially symmetric; 3 percent spill outside the beam",
    ),
    Profile(
        name="wallwash",
        lumens=1500.0,
        vertical=np.arange(0.0, 90.0 + 1e-9, 5.0),
        horizontal=np.arange(0.0, 180.0 + 1e-9, 15.0),
        shape=_wallwash,
        luminaire="STB-WW synthetic asymmetric wall washer",
        lumcat="STB-WW-1500",
        lamp="LED 1500 lm 3500 K (synthetic)",
        input_watts=14.0,
        opening_m=(0.12, 0.12, 0.0),
        other="H=0 points at the wall; bilateral about the 0-180 plane",
    ),
    Profile(
        name="uplight",
        lumens=1200.0,
        vertical=np.arange(90.0, 180.0 + 1e-9, 5.0),
        horizontal=np.array([0.0]),
        shape=_uplight,
        luminaire="STB-UP-60 synthetic in-ground uplight, 60 deg beam (FWHM)",
        lumcat="STB-UP-60-1200",
        lamp="LED 1200 lm 3000 K (synthetic)",
        input_watts=11.0,
        opening_m=(-0.06, -0.06, 0.0),
        other="axially symmetric; emits only above the horizon (V 90-180)",
    ),
)


def flux(vertical: np.ndarray, horizontal: np.ndarray, cd: np.ndarray) -> float:
    """Luminous flux (lm) of a type C table cd[h, v]: trapezoid in theta on
    I*sin(theta), then over phi with the symmetry the horizontal range implies."""
    th = np.radians(vertical)
    per_h = np.trapezoid(cd * np.sin(th)[None, :], th, axis=1)  # (n_h,)
    last = horizontal[-1]
    if len(horizontal) == 1:
        return float(2 * math.pi * per_h[0])
    ph = np.radians(horizontal)
    part = float(np.trapezoid(per_h, ph))
    if math.isclose(last, 90.0):
        return 4.0 * part
    if math.isclose(last, 180.0):
        return 2.0 * part
    if math.isclose(last, 360.0):
        return part
    raise ValueError(f"unsupported last horizontal angle {last}")


def candela_table(p: Profile) -> np.ndarray:
    vv, hh = np.meshgrid(p.vertical, p.horizontal)  # (n_h, n_v)
    rel = np.maximum(p.shape(vv, hh), 0.0)
    cd = rel * (p.lumens / flux(p.vertical, p.horizontal, rel))
    return np.round(cd, 1)


def _wrap(values: list[str], per_line: int = 10) -> list[str]:
    return [" ".join(values[i : i + per_line]) for i in range(0, len(values), per_line)]


def _fmt(x: float, nd: int = 1) -> str:
    s = f"{x:.{nd}f}"
    return s.rstrip("0").rstrip(".") if "." in s else s


def render(p: Profile) -> str:
    cd = candela_table(p)
    w, length, height = p.opening_m
    lines = [
        "IESNA:LM-63-2002",
        "[TEST] SYNTHETIC-" + p.name.upper() + " (computed, not measured)",
        "[TESTLAB] stb_hydra tools/make_ies_profiles.py",
        f"[ISSUEDATE] {ISSUE_DATE}",
        "[MANUFAC] stb_hydra synthetic profile - not a real product",
        f"[LUMCAT] {p.lumcat}",
        f"[LUMINAIRE] {p.luminaire}",
        f"[LAMP] {p.lamp}",
        f"[OTHER] {p.other}",
        "[OTHER] licence: Apache-2.0, part of the stb_hydra repository",
        "TILT=NONE",
        # lamps, lumens/lamp, multiplier, n_vert, n_horiz, type C=1, metres=2, w, l, h
        f"1 {_fmt(p.lumens)} 1.0 {len(p.vertical)} {len(p.horizontal)} 1 2 "
        f"{_fmt(w, 3)} {_fmt(length, 3)} {_fmt(height, 3)}",
        # ballast factor, future use (ballast-lamp factor), input watts
        f"1.0 1.0 {_fmt(p.input_watts)}",
    ]
    lines += _wrap([_fmt(a, 2) for a in p.vertical])
    lines += _wrap([_fmt(a, 2) for a in p.horizontal])
    for row in cd:
        lines += _wrap([_fmt(c, 1) for c in row])
    return "\n".join(lines) + "\n"


def write_all(out_dir: Path) -> list[Path]:
    paths = []
    for p in PROFILES:
        path = out_dir / f"{p.name}.ies"
        write_text_atomic(path, render(p))
        paths.append(path)
    return paths


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, default=IES_DIR, help="output folder (default %(default)s)")
    ap.add_argument(
        "--check",
        action="store_true",
        help="do not write; exit 1 if a file in --out differs from what would be written",
    )
    args = ap.parse_args(argv)
    if args.check:
        stale = [
            p.name
            for p in PROFILES
            if not (args.out / f"{p.name}.ies").is_file()
            or (args.out / f"{p.name}.ies").read_bytes() != render(p).encode()
        ]
        for name in stale:
            print(f"stale: {name}.ies", file=sys.stderr)
        return 1 if stale else 0
    for path in write_all(args.out):
        p = next(q for q in PROFILES if q.name == path.stem)
        cd = candela_table(p)
        print(
            f"{path}: {p.lumens:.0f} lm, peak {cd.max():.0f} cd, "
            f"table flux {flux(p.vertical, p.horizontal, cd):.0f} lm, "
            f"{path.stat().st_size} bytes"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
