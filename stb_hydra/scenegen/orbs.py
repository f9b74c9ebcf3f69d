"""Generate the "enemy orbs" scene: orbs spawn over time in an arena and swarm it.

A round arena (ring wall, pillars, a central dais, four spawn gates) lit by static
wall torches (``wall_torch`` prefab, static shadow maps) and a dim night sky. N
``enemy_orb`` prefab instances (pink SphereLight, ``stb:shadow:update = "dynamic"``,
geometry ``stb:dynamic = true``) spawn at the gates over the first 80 % of the
frames - each orb's ``visibility`` is time-sampled ``invisible`` -> ``inherited`` at
its spawn frame - then fly in from their gate onto a circling, bobbing orbit. The
number alive grows roughly linearly from a handful at frame 1 to N.

    python -m stb_hydra.scenegen.orbs out/orbs.usda --orbs 200 --frames 240

(``python tools/gen_orbs.py ...`` in a checkout is the same command.)
Orbs reference the prefab ``enemy_orb.usda`` (relative to OUT, absolute for
in-memory stages; ``--prefab-dir`` / ``prefab_dir`` names the prefab folder, by
default the package's copy ``stb_hydra/data/prefabs``) as instanceable prims: the
renderer must honour time-varying visibility on instance roots (an invisible prim hides
its lights too).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

from .common import (
    UsdaWriter,
    arch,
    asset_path,
    box,
    cylinder,
    exposure_for_illuminance,
    merge,
    plane,
    save,
    stage_from_text,
)
from .common import prefab_dir as _prefab_dir

ORB_LUMENS = 395.0  # enemy_orb prefab, white-equivalent (see its doc)
TORCH_LUMENS = 296.0


def spawn_frames(n: int, frames: int, initial: int) -> np.ndarray:
    """Spawn frame of each orb: the first ``initial`` at frame 1, the rest evenly
    over frames 1 .. 0.8 * frames (so the last quarter of the clip has all N)."""
    last = max(1, round(0.8 * frames))
    k = np.arange(n)
    s = 1 + np.floor(np.maximum(k - initial + 1, 0) * (last - 1) / max(n - initial, 1))
    return np.minimum(s.astype(int), last)


def orbs_scene_usda(
    n_orbs: int = 200,
    frames: int = 240,
    seed: int = 0,
    torches: int = 8,
    arena_radius: float = 15.0,
    sample_step: int = 4,
    initial: int = 4,
    anchor_dir: Path | str | None = None,
    prefab_dir: Path | str | None = None,
) -> str:
    """The scene as .usda text. ``anchor_dir``: directory the file will live in (prefab
    references are relative to it; None: absolute). ``prefab_dir``: folder holding
    ``enemy_orb.usda`` and ``wall_torch.usda`` (default: the checkout's
    usd_scenes/prefabs)."""
    if n_orbs < 1 or frames < 2:
        raise ValueError("need at least one orb and two frames")
    rng = np.random.default_rng(seed)
    R = float(arena_radius)
    gates = [
        (R - 1.0) * np.array([math.cos(a), 0.0, -math.sin(a)])
        for a in np.radians([0.0, 90.0, 180.0, 270.0])
    ]
    spawn = spawn_frames(n_orbs, frames, min(initial, n_orbs))
    gate = rng.integers(0, 4, n_orbs)
    orbit_r = np.empty(n_orbs)
    omega = np.empty(n_orbs)
    fly_in = np.empty(n_orbs)  # frames from the gate onto the orbit
    height = rng.uniform(0.8, 3.2, n_orbs)
    bob_amp = rng.uniform(0.05, 0.4, n_orbs)
    bob_w = rng.uniform(0.05, 0.15, n_orbs)
    phase = rng.uniform(0, 2 * math.pi, n_orbs)
    pillars = [
        (0.55 * R * math.cos(a), -0.55 * R * math.sin(a))
        for a in np.radians(np.arange(22.5, 360.0, 45.0))
    ]

    def draw(i: int) -> None:
        # ~1.5-5 m/s on a 3.5 .. R-2 m orbit, 1.5-3 s to fly in from the gate.
        orbit_r[i] = rng.uniform(3.5, R - 2.0)
        omega[i] = rng.uniform(1.5, 5.0) / 24.0 / orbit_r[i] * rng.choice((-1.0, 1.0))
        fly_in[i] = rng.uniform(36.0, 72.0)

    def clear(i: int) -> bool:
        """No pillar (r 0.6 m) closer than 0.8 m to the orb's path."""
        p = position(i, np.arange(spawn[i], frames + 1, 1.0))
        for cx, cz in pillars:
            if np.hypot(p[:, 0] - cx, p[:, 2] - cz).min() < 0.6 + 0.8:
                return False
        return True

    def position(i: int, f: np.ndarray) -> np.ndarray:
        """Orb i at frames f (>= its spawn): gate -> orbit, then circling."""
        t = np.maximum(f - spawn[i], 0.0)
        g = gates[gate[i]]
        a0 = math.atan2(-g[2], g[0])
        a = a0 + omega[i] * t
        u = np.clip(t / fly_in[i], 0.0, 1.0)
        u = u * u * (3 - 2 * u)
        rad = (R - 1.0) + (orbit_r[i] - (R - 1.0)) * u
        y = 1.2 + (height[i] - 1.2) * u + bob_amp[i] * np.sin(bob_w[i] * t + phase[i]) * u
        return np.stack([rad * np.cos(a), y, -rad * np.sin(a)], -1)

    for i in range(n_orbs):
        for _ in range(100):
            draw(i)
            if clear(i):
                break

    w = UsdaWriter()
    prefabs = _prefab_dir(prefab_dir)
    orb_ref = asset_path(prefabs / "enemy_orb.usda", anchor_dir)
    torch_ref = asset_path(prefabs / "wall_torch.usda", anchor_dir)
    e_full = (0.5 * n_orbs * ORB_LUMENS * 0.51 + 0.5 * torches * TORCH_LUMENS) / (math.pi * R * R)
    exposure = exposure_for_illuminance(max(e_full * 0.5, 1.0))
    w.header(
        doc=(
            f"stb_hydra enemy-orbs scene: {n_orbs} enemy_orb instances spawn over frames "
            f"1-{int(spawn.max())} (of {frames}, 24 fps) at 4 gates\n"
            f"of a {2 * R:g} m arena and circle it; {torches} static wall torches, dim sky.\n"
            f"Generated by tools/gen_orbs.py --orbs {n_orbs} --frames {frames} --seed {seed}. "
            "Units: metres, nits."
        ),
        default_prim="World",
        start=1,
        end=frames,
        fps=24.0,
    )
    with w.prim("Xform", "World", meta=['kind = "assembly"']):
        with w.prim("Scope", "Looks"):
            w.preview_material("Floor", "/World/Looks/Floor", (0.28, 0.27, 0.3), roughness=0.7)
            w.preview_material("Stone", "/World/Looks/Stone", (0.45, 0.43, 0.4), roughness=0.8)
            w.preview_material(
                "Gate",
                "/World/Looks/Gate",
                (0.2, 0.1, 0.18),
                roughness=0.5,
                emissive=(1.5, 0.3, 1.0),
            )
        with w.prim("Xform", "Arena"):
            w.mesh("Floor", plane(2 * R + 6, 2 * R + 6), material="/World/Looks/Floor", nd=3)
            segs = 32
            wall = []
            for k in range(segs):
                a = 360.0 * k / segs
                wall.append(
                    box(
                        (-R * math.pi / segs - 0.05, 0.0, R),
                        (R * math.pi / segs + 0.05, 2.6, R + 0.6),
                        bottom=False,
                    ).transformed(yaw_deg=a)
                )
            w.mesh(
                "RingWall",
                merge(wall),
                material="/World/Looks/Stone",
                nd=3,
                doc=f"{segs} wall segments on a {R:g} m radius, 2.6 m tall.",
            )
            pillars = [
                cylinder(
                    0.6,
                    0.0,
                    4.0,
                    16,
                    center=(0.55 * R * math.cos(a), -0.55 * R * math.sin(a)),
                    bottom=False,
                )
                for a in np.radians(np.arange(22.5, 360.0, 45.0))
            ]
            w.mesh("Pillars", merge(pillars), material="/World/Looks/Stone", nd=3)
            dais = merge(
                [
                    cylinder(2.5, 0.0, 0.4, 24, bottom=False),
                    box((-0.3, 0.4, -0.3), (0.3, 2.2, 0.3), bottom=False),
                ]
            )
            w.mesh(
                "Dais",
                dais,
                material="/World/Looks/Stone",
                nd=3,
                doc="Central dais with the 'player' post the orbs circle.",
            )
            # Arch depth (local Z) along the radius: yaw 90 + gate angle.
            gate_mesh = merge(
                arch(2.4, 2.0, 0.8, 0.4).transformed(
                    translate=tuple(g * (R - 0.2) / (R - 1.0)), yaw_deg=90.0 + a
                )
                for a, g in zip([0.0, 90.0, 180.0, 270.0], gates)
            )
            w.mesh(
                "Gates",
                gate_mesh,
                material="/World/Looks/Gate",
                nd=3,
                doc="Four spawn gates on the ring wall, faintly emissive.",
            )
        with w.prim("Xform", "Lights"):
            with w.prim("DomeLight", "NightSky", doc="Dim uniform night sky, ~0.5 lx."):
                w.attr("color3f inputs:color", "(0.25, 0.3, 0.55)")
                w.attr("float inputs:intensity", "0.5")
            with w.prim("Xform", "Torches", doc="wall_torch on the ring wall, static shadows."):
                for k in range(torches):
                    a = 2 * math.pi * (k + 0.5) / max(torches, 1)
                    p = (R - 0.01) * np.array([math.cos(a), 0.0, -math.sin(a)])
                    yaw = math.degrees(a) - 90.0  # prefab +Z -> towards the centre
                    with w.prim(
                        "Xform",
                        f"Torch_{k + 1:02d}",
                        meta=["instanceable = true", f"prepend references = {torch_ref}"],
                    ):
                        w.xform(translate=(p[0], 1.9, p[2]), rotate_xyz=(0, round(yaw, 3), 0), nd=3)
            with w.prim(
                "Xform",
                "Orbs",
                doc=f"{n_orbs} enemy_orb instances; visibility "
                "switches invisible -> inherited at each orb's spawn frame.",
            ):
                for i in range(n_orbs):
                    s = int(spawn[i])
                    fs = sorted({1, s, frames, *range(s, frames + 1, max(1, sample_step))})
                    p = position(i, np.asarray(fs, float))
                    meta = ["instanceable = true", f"prepend references = {orb_ref}"]
                    with w.prim("Xform", f"Orb_{i:04d}", meta=meta):
                        if s > 1:
                            w.time_samples(
                                "token visibility", [(1, '"invisible"'), (s, '"inherited"')]
                            )
                        w.time_samples(
                            "double3 xformOp:translate",
                            [
                                (f, f"({q[0]:.3f}, {q[1]:.3f}, {q[2]:.3f})")
                                for f, q in zip(fs, np.round(p, 3) + 0.0)
                            ],  # + 0.0: no "-0.000"
                        )
                        w.attr("uniform token[] xformOpOrder", '["xformOp:translate"]')
    w.camera(
        "Camera",
        eye=(0.0, 0.95 * R, 1.45 * R),
        target=(0.0, 0.5, 0.0),
        focal_length=24.0,
        clipping=(0.1, 10 * R),
        exposure=exposure,
        comment=f"exposure {exposure:g}: for the mean floor illuminance with half the orbs alive.",
    )
    return w.text()


def build_orbs_stage(
    n_orbs: int = 200, frames: int = 240, seed: int = 0, path: str | Path | None = None, **kwargs
):
    """``Usd.Stage`` of the orbs scene: in memory when ``path`` is None, else written."""
    from pxr import Usd

    if path is None:
        return stage_from_text(orbs_scene_usda(n_orbs, frames, seed, **kwargs))
    path = Path(path)
    save(orbs_scene_usda(n_orbs, frames, seed, anchor_dir=path.resolve().parent, **kwargs), path)
    return Usd.Stage.Open(str(path))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0], formatter_class=argparse.ArgumentDefaultsHelpFormatter
    )
    ap.add_argument("out", type=Path, help="output .usda or .usdc")
    ap.add_argument("--orbs", type=int, default=200, help="orbs alive at the end (N)")
    ap.add_argument("--frames", type=int, default=240, help="clip length F at 24 fps")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--torches", type=int, default=8, help="static wall torches")
    ap.add_argument("--arena-radius", type=float, default=15.0, help="metres")
    ap.add_argument("--sample-step", type=int, default=4, help="frames between path samples")
    ap.add_argument("--initial", type=int, default=4, help="orbs alive at frame 1")
    ap.add_argument(
        "--prefab-dir",
        type=Path,
        default=None,
        help="folder of enemy_orb.usda / wall_torch.usda "
        "(default: the package's stb_hydra/data/prefabs)",
    )
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    try:
        text = orbs_scene_usda(
            args.orbs,
            args.frames,
            args.seed,
            args.torches,
            args.arena_radius,
            args.sample_step,
            args.initial,
            anchor_dir=args.out.resolve().parent,
            prefab_dir=args.prefab_dir,
        )
    except (ValueError, FileNotFoundError) as e:
        ap.error(str(e))
    save(text, args.out)
    print(
        f"wrote {args.out}: {args.orbs} orbs over {args.frames} frames "
        f"in {time.perf_counter() - t0:.2f} s"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
