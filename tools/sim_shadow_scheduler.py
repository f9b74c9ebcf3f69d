"""Simulate the shadow-atlas manager (no GL): a camera drives around a field of lights.

Phase 1 (cold start): every light is added at frame 0, camera still, no motion; counts
the frames until every map is captured and fresh. Phase 2: ``--frames`` frames of a
moving camera, animated dynamic lights and randomly moving static lights; reports the
staleness of dirty static maps, budget use, atlas occupancy / fragmentation and the
CPU time of the manager per frame.

    .venv/bin/python tools/sim_shadow_scheduler.py --statics 50 --dynamics 10 --frames 1000
"""

from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np

from stb_hydra.limits import (
    LIGHT_CUTOFF_LUX,
    SHADOW_ATLAS_SIZE_DEFAULT,
    SHADOW_OMNI_COST_FACTOR,
    SHADOW_TEXELS_PER_PIXEL,
    SHADOW_UPDATE_BUDGET_TEXELS_DEFAULT,
)
from stb_hydra.shadows import ShadowAtlas, ShadowScheduler


def _transform(p: np.ndarray) -> np.ndarray:
    m = np.eye(4)
    m[3, :3] = p  # row-vector convention: translation in the last row
    return m


def _camera(frame: int, moving: bool, radius: float) -> tuple[np.ndarray, np.ndarray]:
    a = 2.0 * math.pi * frame / 1000.0 if moving else 0.0
    pos = np.array([radius * math.cos(a), 1.6, radius * math.sin(a)])
    fwd = np.array([-math.sin(a), 0.0, math.cos(a)])  # tangent: drives around the circle
    return pos, fwd


def _view(pos, fwd, light_pos, rng_m, fov_y, aspect):
    d_vec = light_pos - pos
    d = np.linalg.norm(d_vec, axis=1)
    half_diag = math.atan(math.tan(0.5 * fov_y) * math.hypot(1.0, aspect))
    cos_a = (d_vec @ fwd) / np.maximum(d, 1e-9)
    ang = np.arccos(np.clip(cos_a, -1.0, 1.0))
    in_view = (d <= rng_m) | (
        ang <= half_diag + np.arcsin(np.clip(rng_m / np.maximum(d, 1e-9), 0, 1))
    )
    return d, in_view


def simulate(args: argparse.Namespace) -> dict:
    rng = np.random.default_rng(args.seed)
    n = args.statics + args.dynamics
    half = 0.5 * args.field
    pos = np.column_stack(
        [rng.uniform(-half, half, n), rng.uniform(2.0, 6.0, n), rng.uniform(-half, half, n)]
    )
    flux = np.exp(rng.uniform(math.log(200.0), math.log(20_000.0), n))
    range_m = np.sqrt(flux / (4.0 * math.pi) / LIGHT_CUTOFF_LUX)
    omni = rng.random(n) < 0.5
    dynamic = np.arange(n) >= args.statics
    fov_y, vh, aspect = math.radians(60.0), 1080, 16.0 / 9.0
    sched = ShadowScheduler(ShadowAtlas(args.atlas), budget_texels=args.budget)
    keys = list(range(n))
    for i in keys:
        sched.add_light(
            i,
            dynamic=bool(dynamic[i]),
            transform=_transform(pos[i]),
            cost_factor=SHADOW_OMNI_COST_FACTOR if omni[i] else 1.0,
        )

    def step(frame: int, moving: bool) -> tuple[list, float]:
        t0 = time.perf_counter()
        if moving:
            movers = np.flatnonzero(~dynamic & (rng.random(n) < args.p_move))
            pos[movers] += rng.normal(0.0, 0.5, (len(movers), 3))
            for i in movers:
                sched.set_transform(int(i), _transform(pos[i]))
            for i in np.flatnonzero(dynamic):  # animated: a small circle per frame
                pos[i] += 0.05 * np.array([math.cos(frame * 0.1 + i), 0.0, math.sin(frame * 0.1)])
                sched.set_transform(int(i), _transform(pos[i]))
        cam, fwd = _camera(frame, moving, args.cam_radius)
        d, in_view = _view(cam, fwd, pos, range_m, fov_y, aspect)
        sched.update_lights(
            keys,
            distance_m=d,
            flux_lm=flux,
            range_m=range_m,
            viewport_height_px=vh,
            fov_y_rad=fov_y,
            in_view=in_view,
            texels_per_pixel=args.texels_per_pixel,
        )
        plan = sched.plan_frame(frame)
        sched.commit(plan)  # the GL capture would run in between
        return plan, time.perf_counter() - t0

    frame = 0
    statics_fresh = all_captured = None
    cold_texels = 0
    while frame < 10_000 and all_captured is None:
        plan, _ = step(frame, moving=False)
        cold_texels += sum(u.cost for u in plan)
        frame += 1
        if statics_fresh is None and all(sched.is_fresh(k) for k in keys if not dynamic[k]):
            statics_fresh = frame
        if all(sched.is_valid(k) for k in keys) and sched.stats().unplaced == 0:
            all_captured = frame
    cold = sched.stats()
    texels, maps, cpu = [], [], []
    start = frame
    for frame in range(start, start + args.frames):
        plan, dt = step(frame, moving=True)
        texels.append(sum(u.cost for u in plan))
        maps.append(len(plan))
        cpu.append(dt)
    st = sched.stats()
    a = st.atlas
    return {
        "lights": {"static": args.statics, "dynamic": args.dynamics, "omni": int(omni.sum())},
        "atlas": args.atlas,
        "budget_texels": args.budget,
        "texels_per_pixel": args.texels_per_pixel,
        "cold_start": {
            "frames_until_statics_fresh": statics_fresh,
            "frames_until_every_map_captured": all_captured,
            "texels_rendered": cold_texels,
            "occupancy": round(cold.atlas.occupancy, 4),
            "map_sizes": _hist(sched, keys),
        },
        "motion_frames": args.frames,
        "static_wait_frames": {
            "samples": st.static_wait.count,
            "mean": round(st.static_wait.mean, 2),
            "p95": round(st.static_wait.p95, 2),
            "max": st.static_wait.max,
        },
        "dynamic_refresh_interval_frames": {
            "mean": round(st.dynamic_age.mean, 2),
            "p95": round(st.dynamic_age.p95, 2),
            "max": st.dynamic_age.max,
        },
        "maps_per_frame": {"mean": round(float(np.mean(maps)), 2), "max": int(np.max(maps))},
        "texels_per_frame": {
            "mean": int(np.mean(texels)),
            "p95": int(np.percentile(texels, 95)),
            "max": int(np.max(texels)),
        },
        "end": {
            "occupancy": round(a.occupancy, 4),
            "fragmentation": round(a.fragmentation, 4),
            "largest_free_fraction": round(a.largest_free_fraction, 4),
            "largest_free_block": a.largest_free_block,
            "downgrades": a.downgrades,
            "evictions": a.evictions,
            "failed_allocations": a.failed_allocations,
            "undersized": st.undersized,
            "unplaced": st.unplaced,
            "statics_pending": st.statics_pending,
            "map_sizes": _hist(sched, keys),
        },
        "cpu_ms_per_frame": {
            "mean": round(1e3 * float(np.mean(cpu)), 3),
            "p95": round(1e3 * float(np.percentile(cpu, 95)), 3),
        },
    }


def _hist(sched: ShadowScheduler, keys: list) -> dict:
    out: dict = {}
    for k in keys:
        r = sched.rect(k)
        s = 0 if r is None else r.size
        out[s] = out.get(s, 0) + 1
    return dict(sorted(out.items()))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--statics", type=int, default=50)
    ap.add_argument("--dynamics", type=int, default=10)
    ap.add_argument("--frames", type=int, default=1000)
    ap.add_argument("--atlas", type=int, default=SHADOW_ATLAS_SIZE_DEFAULT)
    ap.add_argument("--budget", type=int, default=SHADOW_UPDATE_BUDGET_TEXELS_DEFAULT)
    ap.add_argument("--field", type=float, default=120.0, help="side of the light field (m)")
    ap.add_argument("--cam-radius", type=float, default=40.0, help="camera circle (m)")
    ap.add_argument("--p-move", type=float, default=0.01, help="P(static light moves)/frame")
    ap.add_argument(
        "--texels-per-pixel",
        type=float,
        default=SHADOW_TEXELS_PER_PIXEL,
        help="policy density (map texels per px of projected influence diameter)",
    )
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--json", action="store_true", help="one JSON object instead of a table")
    args = ap.parse_args()
    res = simulate(args)
    if args.json:
        print(json.dumps(res))
        return
    for k, v in res.items():
        print(f"{k:34s} {v}")


if __name__ == "__main__":
    main()
