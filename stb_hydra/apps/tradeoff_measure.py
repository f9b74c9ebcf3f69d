"""The measuring half of ``stb tradeoff`` (:mod:`.tradeoff`), shared by its modes: the
configuration grid (:class:`Unit`, :func:`grid_units`), the scenes (a USD file or a
generated ``lights:N`` / ``chess:N``), one engine per stage whose lighting method is
swapped between configurations (:class:`EnginePool`), timing a configuration's frames
(:func:`measure`) and turning a run into report rows against the reference
(:func:`evaluate`: relMSE, FLIP, HDR-FLIP, structure, temporal instability), and the
load average recorded around a run (:func:`_load`).
"""

from __future__ import annotations

import os
import time as _time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .common import CliError, open_stage

STB_N = (1, 2, 4)
STB_K = (4, 8, 16, 32, 64)
ACCUMULATE = (1, 4, 16)
STB_CAP = 8.0
#: STB's default, the reservoir reuse (issue 31: each pixel resamples its big tile's K
#: reservoirs, shared over the 2x2 quad), the weight cap on, at every K of the grid
#: (quick: the largest). The temporal reuse is off as under ``--accumulate``
#: (``reuse_temporal=auto``): the grid's accumulations average independent frames. The
#: N x K grid is the talk's pipeline (``-o reuse=off``).
STB_REUSE = {"reuse": True, "reuse_temporal": "off"}
TILE_CAPS = (16, 64, None)
QUICK = {"N": (1, 4), "K": (8, 32), "A": (1, 4), "tile_caps": (16, None)}


@dataclass
class Unit:
    """One engine configuration; stochastic ones yield one row per accumulation."""

    method: str
    options: dict = field(default_factory=dict)
    accumulations: tuple[int, ...] = (1,)
    stochastic: bool = False

    def label(self, a: int = 1) -> str:
        if self.method == "stb":
            o = self.options
            cap = "cap" if o.get("weight_cap") else "nocap"
            if o.get("reuse"):
                return f"stb reuse K{o['K']} {cap} A{a}"
            return f"stb N{o['N']} K{o['K']} {cap} A{a}"
        if self.method == "tiled":
            c = self.options.get("tile_cap")
            return f"tiled cap {c if c else 'none'}"
        return self.method


def grid_units(
    quick: bool = False, methods: set[str] | None = None, tile_caps: tuple | None = None
) -> list[Unit]:
    ns, ks, accs = (QUICK["N"], QUICK["K"], QUICK["A"]) if quick else (STB_N, STB_K, ACCUMULATE)
    caps = tile_caps if tile_caps is not None else QUICK["tile_caps"] if quick else TILE_CAPS
    units = [Unit("reference")]
    for n in ns:
        for k in ks:
            for wc in (STB_CAP, None):
                opts = {"reuse": False, "N": n, "K": k, "weight_cap": wc}
                units.append(Unit("stb", opts, tuple(accs), True))
    for k in ks[-1:] if quick else ks:
        opts = {**STB_REUSE, "K": k, "weight_cap": STB_CAP}
        units.append(Unit("stb", opts, tuple(accs), True))
    units += [Unit("tiled", {"tile_cap": c}) for c in caps]
    units += [Unit("clustered"), Unit("lighttree")]
    if methods:
        units = [u for u in units if u.method in methods or u.method == "reference"]
    return units


# --- scenes --------------------------------------------------------------------------------


def generated_stage(kind: str, n: int, seed: int = 0, lumens: tuple | None = None):
    from ..scenegen import chess, lights

    try:
        if kind == "lights":
            extra = {"lumens": lumens} if lumens else {}
            return lights.build_lights_stage(n_lights=n, seed=seed, **extra)
        if kind == "chess":
            return chess.build_chess_stage(n_lights=n, seed=seed)
    except FileNotFoundError as exc:  # an input asset (IES profiles, chess set) is missing
        raise CliError(f"cannot generate {kind}:{n}: {exc}") from None
    raise CliError(f"unknown generated scene '{kind}' (lights:N or chess:N)")


def open_scene(spec: str, seed: int = 0):
    """(stage, short name) for a USD path or ``lights:N[:LO-HI]`` (LO-HI: lumens per
    light, default 100-2000) / ``chess:N``."""
    if ":" in spec and not os.path.exists(spec):
        kind, _, rest = spec.partition(":")
        n, _, lm = rest.partition(":")
        try:
            count = int(n)
            lumens = tuple(float(x) for x in lm.split("-")) if lm else None
        except ValueError:
            raise CliError(f"bad scene '{spec}': use lights:N[:LO-HI] or chess:N") from None
        if count < 1:
            raise CliError("a generated scene needs at least one light")
        if lumens is not None and (
            kind != "lights" or len(lumens) != 2 or not 0 < lumens[0] <= lumens[1]
        ):
            raise CliError(f"bad scene '{spec}': lumens as LO-HI with 0 < LO <= HI (lights only)")
        name = f"{kind}{count}" + (f"_{lm}lm" if lm else "")
        return generated_stage(kind, count, seed, lumens), name
    return open_stage(spec), Path(spec).stem


# --- measuring -----------------------------------------------------------------------------


@dataclass
class Run:
    unit: Unit
    times: list[float]
    lighting: list[float]
    images: list[np.ndarray]
    stats: list[dict]
    prepare: list[float] = field(default_factory=list)


def _settings(args, method: str, options: dict):
    from ..renderer.frame import RenderSettings

    # shadow_budget None (offline): every shadow map captured before the first
    # warm-up frame, so the measured frames are a steady state.
    return RenderSettings(
        width=args.width,
        height=args.height,
        camera=args.camera,
        lighting=method,
        seed=args.seed,
        profile=True,
        method_options=dict(options),
    )


class EnginePool:
    """One engine per stage; between configurations only its lighting method is
    replaced (``Engine.set_lighting``: scene sync, G-buffer and shadow maps are
    method-independent), so a heavy stage is loaded once."""

    def __init__(self, stage, args) -> None:
        self.stage, self.args, self.eng = stage, args, None

    def get(self, unit: Unit):
        from ..renderer.engine import Engine

        if self.eng is not None:
            self.eng.set_lighting(unit.method, **unit.options)
            self.eng.timings.frames.clear()
            return self.eng
        self.close()
        self.eng = Engine(
            self.stage, _settings(self.args, unit.method, unit.options), time=self.args.time
        )
        return self.eng

    def close(self) -> None:
        if self.eng is not None:
            self.eng.release()
            self.eng = None


def measure(pool: EnginePool, unit: Unit, args, n_frames: int, keep: int, on_frame=None) -> Run:
    """Warm up, then render up to ``n_frames`` frames (stopping early past
    ``args.max_seconds`` for deterministic methods), keeping ``keep`` images."""
    eng = pool.get(unit)
    run = Run(unit, [], [], [], [], [])
    try:
        eng.request_aovs({"color"})
        for _ in range(args.warmup):
            eng.render_frame(args.time)
        t_start = _time.perf_counter()
        for _i in range(n_frames):
            t0 = _time.perf_counter()
            frame = eng.render_frame(args.time)
            wall = (_time.perf_counter() - t0) * 1e3
            tf = eng.timings.frames[-1]
            run.times.append(wall - tf.get("aov_output", 0.0))
            run.lighting.append(tf.get("lighting", 0.0) + tf.get("prepare.lighting", 0.0))
            run.prepare.append(tf.get("prepare.lighting", 0.0))
            run.stats.append({k: v for k, v in frame.stats.items() if isinstance(v, (int, float))})
            if len(run.images) < keep:
                run.images.append(np.array(eng.aovs["color"][..., :3], dtype=np.float32))
            if on_frame:
                on_frame()
            if (
                not unit.stochastic
                and len(run.images) >= keep
                and _time.perf_counter() - t_start > args.max_seconds
            ):
                break
    except BaseException:
        pool.close()
        raise
    return run


def _median(v):
    return float(np.median(v)) if len(v) else float("nan")


def evaluate(run: Run, ref: Run, scene: str, args) -> list[dict]:
    from ..metrics import (
        accumulated_windows,
        display_referred,
        dropped_summary,
        flip_hdr_midgrey,
        flip_ldr,
        relmse,
        structured_noise,
        temporal_excess,
    )

    ref_img = ref.images[0]
    ref_disp = display_referred(ref_img)
    ref_disp_seq = [display_referred(f) for f in ref.images[:2]]
    u = run.unit
    frame_ms = _median(run.times)
    share = [s["cell_light_share"] for s in run.stats if "cell_light_share" in s]
    base = {
        "scene": scene,
        "method": u.method,
        "N": u.options.get("N", ""),
        "K": u.options.get("K", ""),
        "weight_cap": (u.options.get("weight_cap") or 0) if u.method == "stb" else "",
        "reuse": int(bool(u.options.get("reuse"))) if u.method == "stb" else "",
        "tile_cap": (u.options.get("tile_cap") or "none") if u.method == "tiled" else "",
        "frame_ms": round(frame_ms, 3),
        "frame_ms_min": round(min(run.times), 3),
        "frame_ms_max": round(max(run.times), 3),
        # The frame against the reference's (the cost side of the trade in one number).
        "x_reference": round(frame_ms / _median(ref.times), 4),
        # Cell-list methods: the share of the reference's light-pixel work their cells
        # keep (mean lights per tile / cluster over the lights in view: for tiled, the
        # mean share of the screen's tiles a light reaches); "" for the others.
        "cell_light_share": round(_median(share), 4) if share else "",
        "lighting_ms": round(_median(run.lighting), 3),
        "prepare_ms": round(_median(run.prepare), 3),
        "fov_lights": int(run.stats[-1].get("fov_lights", 0)) if run.stats else 0,
        "frames": len(run.times),
        "width": args.width,
        "height": args.height,
        "load1": round(os.getloadavg()[0], 2),
        **dropped_summary(run.stats),
    }
    rows = []
    for a in u.accumulations:
        if len(run.images) < a:
            continue
        wins = accumulated_windows(run.images, a).astype(np.float32)
        disp = [display_referred(w) for w in wins]
        row = dict(base)
        row.update(
            label=u.label(a),
            accumulate=a,
            image_ms=round(frame_ms * a, 3),
            relmse=float(np.mean([relmse(w, ref_img, args.eps) for w in wins])),
            flip=round(flip_ldr(disp[0], ref_disp), 6),
            hdr_flip=round(flip_hdr_midgrey(wins[0], ref_img), 6) if args.hdr_flip else "",
            structure=round(structured_noise(wins[0], ref_img), 4),
            temporal=round(temporal_excess(disp, ref_disp_seq), 6) if len(disp) > 1 else 0.0,
        )
        rows.append(row)
    return rows


def _load() -> str:
    return "/".join(f"{x:.2f}" for x in os.getloadavg())
