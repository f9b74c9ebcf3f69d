"""``stb tradeoff SCENE``: error against frame time for every lighting method.

Runs a grid of configurations on one static view (camera, time fixed):

* ``stb``: N in {1, 2, 4} x K in {4, 8, 16, 32, 64} x weight cap on (8) / off, each
  rendered as one sequence of frames (distinct seeds) from which accumulations of
  A in {1, 4, 16} frames are formed as sliding means (what a display accumulating A
  frames shows each frame);
* ``tiled`` with caps {16, 64, none}; ``clustered``; ``lighttree``; ``reference``.

Per configuration: the median frame time over its frames after warm-up
(``RenderSettings.profile``: ``ctx.finish()`` after every task; the AOV readback the
study needs is excluded), the lighting share (``prepare.lighting`` + ``lighting``),
relMSE against ``reference`` (scene-linear, eps ``--eps``), mean LDR-FLIP on the
display-referred images (OCIO, the renderer's default view), mean HDR-FLIP on
scene-linear with the reference's median exposed to mid grey (``--no-hdr-flip`` skips
it), the structured-noise figure (``stb_hydra.metrics.structured_noise``: 1 = white
noise, a 2x2 checkerboard ~16), temporal instability (mean |frame-to-frame change| of
the displayed, display-referred image minus the reference's), dropped lights.

Writes ``tradeoff.csv``, ``pareto.png`` (error against time: per frame on the left,
time to the accumulated image = A x frame on the right; one marker per method, the
Pareto frontier drawn) and ``report.md`` (best configuration per time budget).

``SCENE`` is a USD file or ``lights:N`` / ``chess:N`` (:mod:`stb_hydra.scenegen.lights`
/ :mod:`stb_hydra.scenegen.chess`, in memory, seed ``--seed``).

``--sweep-lights 50,500,5000`` measures frame time against light count instead (the
``lights`` generator, or ``chess`` with ``SCENE=chess``) for stb, reference, sun,
tiled, clustered and lighttree (defaults), writing ``sweep.csv``, ``sweep.md`` and
``frame_time_vs_lights.png``.

``--moving DEG`` runs the moving-camera scenario instead (:mod:`.tradeoff_moving`: the
camera orbits DEG degrees per frame; per-frame HDR-FLIP against the per-frame
reference and temporal instability of raw STB, STB with ``taa`` and the exact methods;
``moving.csv``, ``moving.md``).
"""

from __future__ import annotations

import argparse
import csv
import datetime as _dt
import json
import math
import os
import sys
import time as _time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..io.files import write_csv_atomic, write_text_atomic
from .common import EXIT_OK, CliError, fail, open_stage

STB_N = (1, 2, 4)
STB_K = (4, 8, 16, 32, 64)
ACCUMULATE = (1, 4, 16)
STB_CAP = 8.0
TILE_CAPS = (16, 64, None)
QUICK = {"N": (1, 4), "K": (8, 32), "A": (1, 4), "tile_caps": (16, None)}
SWEEP_METHODS = ("stb", "reference", "sun", "tiled", "clustered", "lighttree")
#: Marker and colour per method in the plots.
STYLE = {
    "stb": ("o", "tab:blue"),
    "tiled": ("s", "tab:orange"),
    "clustered": ("^", "tab:green"),
    "lighttree": ("D", "tab:red"),
    "reference": ("*", "black"),
    "sun": ("x", "tab:gray"),
}
#: relMSE drawn for (near-)exact methods on the log axis.
EXACT_FLOOR = 1e-7
CSV_FIELDS = [
    "scene",
    "method",
    "label",
    "N",
    "K",
    "weight_cap",
    "accumulate",
    "tile_cap",
    "frame_ms",
    "frame_ms_min",
    "frame_ms_max",
    "lighting_ms",
    "prepare_ms",
    "image_ms",
    "relmse",
    "flip",
    "hdr_flip",
    "structure",
    "temporal",
    "dropped_median",
    "dropped_max",
    "fov_lights",
    "frames",
    "width",
    "height",
    "load1",
]


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
                units.append(Unit("stb", {"N": n, "K": k, "weight_cap": wc}, tuple(accs), True))
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
    base = {
        "scene": scene,
        "method": u.method,
        "N": u.options.get("N", ""),
        "K": u.options.get("K", ""),
        "weight_cap": (u.options.get("weight_cap") or 0) if u.method == "stb" else "",
        "tile_cap": (u.options.get("tile_cap") or "none") if u.method == "tiled" else "",
        "frame_ms": round(frame_ms, 3),
        "frame_ms_min": round(min(run.times), 3),
        "frame_ms_max": round(max(run.times), 3),
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


# --- analysis ------------------------------------------------------------------------------


def pareto_front(times: np.ndarray, errors: np.ndarray) -> np.ndarray:
    """Indices of the non-dominated points (no other point is both faster-or-equal and
    strictly better, or strictly faster and better-or-equal), sorted by time."""
    t = np.asarray(times, dtype=np.float64)
    e = np.asarray(errors, dtype=np.float64)
    order = np.lexsort((e, t))
    keep, best = [], np.inf
    for i in order:
        if e[i] < best:
            keep.append(int(i))
            best = e[i]
    return np.array(keep, dtype=np.int64)


def best_within(
    rows: list[dict], budget_ms: float, time_key: str = "frame_ms", metric: str = "relmse"
) -> dict | None:
    """Lowest-``metric`` row (ties: faster, then lower FLIP) with time <= budget."""
    ok = [r for r in rows if float(r[time_key]) <= budget_ms]
    if not ok:
        return None
    return min(ok, key=lambda r: (float(r[metric]), float(r[time_key]), float(r["flip"])))


def cheapest_reaching(rows: list[dict], max_err: float, time_key: str = "frame_ms"):
    ok = [r for r in rows if float(r["relmse"]) <= max_err]
    return min(ok, key=lambda r: float(r[time_key])) if ok else None


def default_budgets(rows: list[dict], time_key: str = "frame_ms") -> list[float]:
    t = sorted(float(r[time_key]) for r in rows)
    if not t:
        return []
    lo, hi = t[0], t[-1]
    cand = [a * 10.0**e for e in range(-1, 7) for a in (1, 2, 5)]
    out = [c for c in cand if lo <= c < hi]
    above = [c for c in cand if c >= hi]
    return out + above[:1] if above else [*out, hi]


def plot_pareto(rows: list[dict], path: Path, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(13, 5.2), sharey=True)
    for ax, key, xlabel in (
        (axes[0], "frame_ms", "median frame time (ms, static camera, A-frame accumulation)"),
        (axes[1], "image_ms", "time to the accumulated image: A x frame time (ms)"),
    ):
        t = np.array([float(r[key]) for r in rows])
        e = np.array([max(float(r["relmse"]), EXACT_FLOOR) for r in rows])
        for m in STYLE:
            idx = [i for i, r in enumerate(rows) if r["method"] == m]
            if not idx:
                continue
            marker, color = STYLE[m]
            if m == "stb":
                for a, alpha in zip(
                    sorted({int(rows[i]["accumulate"]) for i in idx}), (0.35, 0.65, 1.0, 1.0)
                ):
                    sel = [i for i in idx if int(rows[i]["accumulate"]) == a]
                    ax.scatter(
                        t[sel],
                        e[sel],
                        marker=marker,
                        color=color,
                        alpha=alpha,
                        s=28,
                        label=f"stb A={a}",
                    )
            else:
                ax.scatter(
                    t[idx],
                    e[idx],
                    marker=marker,
                    color=color,
                    s=70 if m == "reference" else 44,
                    label=m,
                    zorder=3,
                )
                for i in idx:
                    if m == "tiled":
                        ax.annotate(
                            f"cap {rows[i]['tile_cap']}",
                            (t[i], e[i]),
                            fontsize=7,
                            xytext=(4, 4),
                            textcoords="offset points",
                        )
        front = pareto_front(t, e)
        ax.step(
            t[front], e[front], where="post", color="k", lw=1.0, alpha=0.6, label="Pareto frontier"
        )
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(xlabel)
        ax.grid(True, which="both", alpha=0.25)
    axes[0].set_ylabel(f"relMSE vs reference (exact methods drawn at {EXACT_FLOOR:g})")
    axes[0].legend(fontsize=8, loc="best")
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _opt(v: object, fmt: str = ".4f") -> str:
    """A metric that may be absent ("" when skipped)."""
    return "" if v in ("", None) else format(float(v), fmt)  # type: ignore[arg-type]


def _fmt_row(r: dict | None, key: str = "frame_ms") -> str:
    if r is None:
        return "| (none) | | | | |"
    return (
        f"| {r['label']} | {float(r[key]):.1f} | {float(r['relmse']):.3g} | "
        f"{float(r['flip']):.4f} | {float(r['temporal']):.4f} |"
    )


def _short(r: dict | None, key: str) -> str:
    if r is None:
        return "(none) | |"
    return (
        f"{r['label']} ({float(r[key]):.0f} ms) | {float(r['relmse']):.3g} / {float(r['flip']):.3f}"
    )


def write_report(rows, path: Path, meta: dict, budgets: list[float] | None) -> None:
    lines = [
        f"# Trade-off: {meta['scene']}",
        "",
        f"- {meta['width']}x{meta['height']} px, {meta['fov_lights']} lights in view, "
        f"renderer `{meta['renderer']}`",
        f"- {meta['date']}; load average (1/5/15 min) before {meta['load_before']}, "
        f"after {meta['load_after']}; {meta['wall_s']:.0f} s",
        f"- command: `{meta['command']}`",
        "- frame time: median over the measured frames (profile mode, readback excluded); "
        "relMSE vs `reference` in scene-linear (eps "
        f"{meta['eps']:g}); FLIP: LDR-FLIP of the display-referred images; temporal: mean "
        "|frame-to-frame change| of the displayed image (display-referred) minus the "
        "reference's. `A` = frames accumulated (sliding mean, static camera).",
    ]
    if meta.get("mitsuba"):
        lines.append(f"- `reference` against Mitsuba 3: {meta['mitsuba']}")
    lines.append("")
    for key, heading in (
        (
            "frame_ms",
            "Best configuration per frame-time budget (static camera, A frames "
            "accumulated over time)",
        ),
        ("image_ms", "Best configuration per time-to-image budget (A x frame time)"),
    ):
        bs = budgets or default_budgets(rows, key)
        lines += [
            f"## {heading}",
            "",
            "| budget (ms) | lowest relMSE | relMSE / FLIP | lowest FLIP | relMSE / FLIP |",
            "|---|---|---|---|---|",
        ]
        for b in bs:
            lines.append(
                f"| {b:g} | {_short(best_within(rows, b, key), key)} | "
                f"{_short(best_within(rows, b, key, 'flip'), key)} |"
            )
        lines.append("")
    lines += [
        "## Cheapest configuration reaching an error level",
        "",
        "| relMSE <= | cheapest (frame time) | time (ms) | relMSE | FLIP | temporal |",
        "|---|---|---|---|---|---|",
    ]
    for lvl in (1.0, 0.1, 1e-2, 1e-3, 1e-4):
        lines.append(f"| {lvl:g} " + _fmt_row(cheapest_reaching(rows, lvl)))
    lines += [
        "",
        "## Pareto set (frame time)",
        "",
        "| config | frame (ms) | lighting (ms) | relMSE | FLIP | HDR-FLIP | structure | "
        "temporal | dropped |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    t = np.array([float(r["frame_ms"]) for r in rows])
    e = np.array([float(r["relmse"]) for r in rows])
    for i in pareto_front(t, e):
        r = rows[i]
        lines.append(
            f"| {r['label']} | {float(r['frame_ms']):.1f} | {float(r['lighting_ms']):.1f} | "
            f"{float(r['relmse']):.3g} | {float(r['flip']):.4f} | {_opt(r['hdr_flip'])} | "
            f"{float(r['structure']):.2f} | {float(r['temporal']):.4f} | {r['dropped_median']:g} |"
        )
    lines += [
        "",
        "## Exact methods and capped lists",
        "",
        "| config | frame (ms) | lighting (ms) | relMSE | FLIP | dropped/frame |",
        "|---|---|---|---|---|---|",
    ]
    for r in rows:
        if r["method"] != "stb":
            lines.append(
                f"| {r['label']} | {float(r['frame_ms']):.1f} | {float(r['lighting_ms']):.1f} | "
                f"{float(r['relmse']):.3g} | {float(r['flip']):.4f} | {r['dropped_median']:g} |"
            )
    write_text_atomic(path, "\n".join(lines) + "\n")


def read_rows(path: Path) -> list[dict]:
    """A CSV written by :func:`write_csv`, numbers parsed back."""
    out = []
    with open(path, newline="") as f:
        for r in csv.DictReader(f):
            row = {}
            for k, v in r.items():
                try:
                    row[k] = float(v) if v not in ("", None) else v
                except ValueError:
                    row[k] = v
            for k in ("accumulate", "frames", "fov_lights", "width", "height"):
                if isinstance(row.get(k), float):
                    row[k] = int(row[k])
            out.append(row)
    return out


def write_csv(rows: list[dict], path: Path, fields: list[str]) -> None:
    """``rows`` to ``path`` as CSV, atomically (:func:`~stb_hydra.io.files.write_csv_atomic`)."""
    write_csv_atomic(path, rows, fields)


def command_line(args) -> str:
    if len(sys.argv) > 1 and sys.argv[1] == "tradeoff":
        return "stb " + " ".join(sys.argv[1:])
    return f"stb tradeoff {args.scene} (called from Python)"


def _load() -> str:
    return "/".join(f"{x:.2f}" for x in os.getloadavg())


# --- the two modes -------------------------------------------------------------------------


def run_tradeoff(args, units: list[Unit] | None = None) -> list[dict]:
    from tqdm import tqdm

    from ..renderer.gl import get_context, renderer_info

    stage, name = open_scene(args.scene, args.seed)
    out = Path(args.out or Path("out") / "tradeoff" / name)
    out.mkdir(parents=True, exist_ok=True)
    methods = set(args.methods.split(",")) if args.methods else None
    units = units or grid_units(args.quick, methods, getattr(args, "tile_caps", None))
    windows = max(2, int(args.temporal_frames))
    plan = []
    for u in units:
        if u.stochastic:
            plan.append((u, max(u.accumulations) + windows - 1, max(u.accumulations) + windows - 1))
        else:
            plan.append((u, args.frames, 2 if u.method == "reference" else 1))
    total = sum(n + args.warmup for _u, n, _k in plan)
    load_before, t0 = _load(), _time.perf_counter()
    rows: list[dict] = []
    ref: Run | None = None
    truth: dict = {}
    bar = tqdm(total=total, unit="frame", desc=f"tradeoff {name}", disable=None, file=sys.stderr)
    pool = EnginePool(stage, args)
    try:
        for u, n, keep in plan:
            bar.set_postfix_str(u.label(max(u.accumulations)))
            run = measure(pool, u, args, n, keep, on_frame=lambda: bar.update(1))
            bar.update(args.warmup + n - len(run.times))  # warm-up + frames skipped
            if u.method == "reference":
                ref = run
                truth = mitsuba_check(stage, run.images[0], args)
            if ref is None:
                raise CliError("the reference must be measured first")
            rows.extend(evaluate(run, ref, name, args))
            write_csv(rows, out / "tradeoff.csv", CSV_FIELDS)  # partial results survive
    finally:
        pool.close()
        bar.close()
    meta = {
        "scene": args.scene,
        "width": args.width,
        "height": args.height,
        "fov_lights": rows[0]["fov_lights"] if rows else 0,
        "renderer": renderer_info(get_context()),
        "date": _dt.datetime.now().isoformat("T", "seconds"),
        "load_before": load_before,
        "load_after": _load(),
        "wall_s": _time.perf_counter() - t0,
        "command": command_line(args),
        "eps": args.eps,
        **truth,
    }
    write_text_atomic(out / "tradeoff.json", json.dumps({**meta, "name": name}, indent=2))
    finish_report(rows, out, meta, name, args.budgets)
    print(
        f"stb tradeoff: wrote {out / 'tradeoff.csv'}, {out / 'pareto.png'}, {out / 'report.md'}",
        file=sys.stderr,
    )
    return rows


def mitsuba_check(stage, ref_img: np.ndarray, args) -> dict:
    """The reference's own per-pixel error against Mitsuba 3 (an independent renderer,
    ``metrics.mitsuba_truth``): {} when the ``mitsuba`` wheel is not installed or
    ``--mitsuba-spp 0``; a ``mitsuba`` line saying why when the stage holds something the
    conversion does not support (then nothing is compared)."""
    spp = int(getattr(args, "mitsuba_spp", 0) or 0)
    if spp <= 0:
        return {}
    try:
        from ..metrics import mitsuba_truth as mt
    except ImportError:
        return {}
    try:
        img, hit, light, nrm = mt.render_mitsuba(
            stage,
            args.width,
            args.height,
            spp,
            seed=args.seed,
            emitter_samples=4,
            camera=args.camera,
        )
    except ValueError as exc:
        return {"mitsuba": f"not compared (conversion: {exc})"}
    err, mask, _ = mt.compare(ref_img, img, hit, light, nrm)
    if err.size == 0:
        return {"mitsuba": "not compared (no lit pixels)"}
    med, p95 = float(np.median(err)), float(np.percentile(err, 95))
    return {
        "mitsuba": f"per-pixel relative error median {med * 100:.2f} %, p95 {p95 * 100:.2f} % "
        f"over {int(mask.sum())} px (Mitsuba 3 scalar_rgb `direct`, {spp} spp x 4 light "
        "samples; pixels over 1 % of the floor's maximum, light shapes and silhouette "
        "edges left out; Mitsuba's own noise included)",
        "mitsuba_median": med,
        "mitsuba_p95": p95,
    }


def run_moving_scenario(args) -> list[dict]:
    """``--moving DEG``: :mod:`.tradeoff_moving` on the scene (a generated one included)."""
    from .tradeoff_moving import run_moving

    if not math.isfinite(args.moving) or args.moving == 0.0:
        raise CliError("--moving needs a non-zero number of degrees per frame")
    stage, name = open_scene(args.scene, args.seed)
    out = Path(args.out or Path("out") / "tradeoff" / name)
    out.mkdir(parents=True, exist_ok=True)
    rows = run_moving(args, stage, name, out)
    print(f"stb tradeoff: wrote {out / 'moving.csv'}, {out / 'moving.md'}", file=sys.stderr)
    return rows


def finish_report(rows, out: Path, meta: dict, name: str, budgets) -> None:
    plot_pareto(
        rows,
        out / "pareto.png",
        f"{name}: {meta['width']}x{meta['height']}, {meta['fov_lights']} lights in view, "
        f"{meta['renderer'].split('|')[0].strip()}, load {meta['load_before']}",
    )
    write_report(rows, out / "report.md", meta, budgets)


def report_only(args) -> None:
    """Plot + report again from ``--out``'s tradeoff.csv (and tradeoff.json)."""
    out = Path(args.out or "")
    if not (out / "tradeoff.csv").is_file():
        raise CliError(f"--report-only needs {out / 'tradeoff.csv'} (give --out)")
    rows = read_rows(out / "tradeoff.csv")
    meta_path = out / "tradeoff.json"
    meta = json.loads(meta_path.read_text()) if meta_path.is_file() else {}
    r0 = rows[0] if rows else {}
    meta = {
        "scene": args.scene,
        "width": r0.get("width", 0),
        "height": r0.get("height", 0),
        "fov_lights": r0.get("fov_lights", 0),
        "renderer": "?",
        "date": "?",
        "load_before": "?",
        "load_after": "?",
        "wall_s": 0.0,
        "command": command_line(args),
        "eps": args.eps,
        **meta,
    }
    finish_report(rows, out, meta, meta.get("name", str(r0.get("scene", args.scene))), args.budgets)
    print(f"stb tradeoff: wrote {out / 'pareto.png'}, {out / 'report.md'}", file=sys.stderr)


SWEEP_FIELDS = [
    "scene",
    "lights",
    "fov_lights",
    "method",
    "frame_ms",
    "frame_ms_min",
    "frame_ms_max",
    "lighting_ms",
    "prepare_ms",
    "relmse",
    "flip",
    "dropped_median",
    "list_entries",
    "frames",
    "width",
    "height",
    "load1",
]


def run_sweep(args) -> list[dict]:
    from tqdm import tqdm

    from ..metrics import display_referred, flip_ldr, relmse
    from ..renderer.gl import get_context, renderer_info

    kind = args.scene if args.scene in ("lights", "chess") else "lights"
    counts = [int(x) for x in args.sweep_lights.split(",") if x.strip()]
    methods = args.sweep_methods.split(",") if args.sweep_methods else list(SWEEP_METHODS)
    if "reference" in methods:  # first: the others' relMSE needs its image
        methods = ["reference"] + [m for m in methods if m != "reference"]
    out = Path(args.out or Path("out") / "tradeoff" / f"sweep_{kind}")
    out.mkdir(parents=True, exist_ok=True)
    rows: list[dict] = []
    load_before, t0 = _load(), _time.perf_counter()
    bar = tqdm(
        total=len(counts) * len(methods), unit="config", desc="sweep", disable=None, file=sys.stderr
    )
    try:
        for n in counts:
            stage = generated_stage(kind, n, args.seed)
            pool = EnginePool(stage, args)
            ref_img = None
            for m in methods:
                bar.set_postfix_str(f"{n} lights, {m}")
                run = measure(pool, Unit(m), args, args.frames, 1)
                if m == "reference":
                    ref_img = run.images[0]
                    ref_disp = display_referred(ref_img)
                st = run.stats[-1] if run.stats else {}
                rows.append(
                    {
                        "scene": kind,
                        "lights": n,
                        "fov_lights": int(st.get("fov_lights", 0)),
                        "method": m,
                        "frame_ms": round(_median(run.times), 3),
                        "frame_ms_min": round(min(run.times), 3),
                        "frame_ms_max": round(max(run.times), 3),
                        "lighting_ms": round(_median(run.lighting), 3),
                        "prepare_ms": round(_median(run.prepare), 3),
                        "relmse": (
                            relmse(run.images[0], ref_img, args.eps) if ref_img is not None else ""
                        ),
                        "flip": (
                            round(flip_ldr(display_referred(run.images[0]), ref_disp), 5)
                            if ref_img is not None
                            else ""
                        ),
                        "dropped_median": float(
                            np.median([s.get("dropped_lights", 0) for s in run.stats])
                        ),
                        "list_entries": int(st.get("list_entries", 0)),
                        "frames": len(run.times),
                        "width": args.width,
                        "height": args.height,
                        "load1": round(os.getloadavg()[0], 2),
                    }
                )
                write_csv(rows, out / "sweep.csv", SWEEP_FIELDS)
                bar.update(1)
            pool.close()
    finally:
        bar.close()
    renderer = renderer_info(get_context())
    plot_sweep(
        rows,
        out / "frame_time_vs_lights.png",
        f"{kind} scene, {args.width}x{args.height}, {renderer.split('|')[0].strip()}, "
        f"load {load_before}",
    )
    lines = [
        f"# Frame time vs light count ({kind} scene)",
        "",
        f"- {args.width}x{args.height}, `{renderer}`; load average before {load_before}, "
        f"after {_load()}; {_time.perf_counter() - t0:.0f} s",
        "- median frame time (ms, profile mode, readback excluded); in brackets relMSE / "
        "LDR-FLIP of one frame vs the reference (and light-tile pairs dropped)",
        "",
        "| lights (in view) | " + " | ".join(methods) + " |",
        "|---|" + "---|" * len(methods),
    ]
    for n in counts:
        cells = []
        for m in methods:
            r = next((r for r in rows if r["lights"] == n and r["method"] == m), None)
            if r is None:
                cells.append("")
                continue
            extra = f", drops {r['dropped_median']:g}" if r["dropped_median"] else ""
            err = (
                f" ({float(r['relmse']):.2g} / {float(r['flip']):.3f}{extra})"
                if r["relmse"] not in ("", None) and m != "reference"
                else ""
            )
            cells.append(f"{float(r['frame_ms']):.0f}{err}")
        fov = next((r["fov_lights"] for r in rows if r["lights"] == n), n)
        lines.append(f"| {n} ({fov}) | " + " | ".join(cells) + " |")
    write_text_atomic(out / "sweep.md", "\n".join(lines) + "\n")
    print(
        f"stb tradeoff: wrote {out / 'sweep.csv'}, {out / 'frame_time_vs_lights.png'}",
        file=sys.stderr,
    )
    return rows


def plot_sweep(rows: list[dict], path: Path, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 5))
    for m in dict.fromkeys(r["method"] for r in rows):
        rs = sorted((r for r in rows if r["method"] == m), key=lambda r: r["fov_lights"])
        marker, color = STYLE.get(m, ("o", None))
        ax.plot(
            [r["fov_lights"] or r["lights"] for r in rs],
            [r["frame_ms"] for r in rs],
            marker=marker,
            color=color,
            label=m,
        )
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("local lights in view")
    ax.set_ylabel("median frame time (ms)")
    ax.grid(True, which="both", alpha=0.25)
    ax.legend()
    ax.set_title(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


# --- CLI -----------------------------------------------------------------------------------


def _tile_caps(s: str) -> tuple:
    from ..renderer.lighting.tiled import parse_cap

    try:
        caps = tuple(parse_cap(x) for x in s.split(",") if x.strip())
    except ValueError:
        raise argparse.ArgumentTypeError("tile caps: comma list of integers or none") from None
    if not caps:
        raise argparse.ArgumentTypeError("tile caps: at least one")
    return caps


def _budgets(s: str) -> list[float]:
    try:
        v = [float(x) for x in s.split(",") if x.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError("budgets: comma list of milliseconds") from None
    if not v or any(not math.isfinite(x) or x <= 0 for x in v):
        raise argparse.ArgumentTypeError("budgets must be positive")
    return v


def add_parser(sub) -> None:
    p = sub.add_parser(
        "tradeoff",
        help="error vs frame time of stb / tiled / clustered / lighttree / reference",
        description=__doc__.split("\n\n")[0],
    )
    p.add_argument("scene", help="USD file, or lights:N / chess:N (generated in memory)")
    p.add_argument("--out", help="output folder (default out/tradeoff/<scene>)")
    p.add_argument("--width", type=int, default=745)
    p.add_argument("--height", type=int, default=360)
    p.add_argument("--camera", help="camera prim path (default: the stage's first)")
    p.add_argument("--time", type=float, default=None, help="stage time (default: start)")
    p.add_argument("--seed", type=int, default=0, help="generator / renderer seed")
    p.add_argument("--quick", action="store_true", help="small grid (N 1,4; K 8,32; A 1,4)")
    p.add_argument("--methods", help="comma list to keep (reference always runs)")
    p.add_argument(
        "--frames", type=int, default=3, help="timed frames of deterministic methods (default 3)"
    )
    p.add_argument("--warmup", type=int, default=1, help="untimed frames first (default 1)")
    p.add_argument(
        "--max-seconds",
        type=float,
        default=60.0,
        help="stop timing a deterministic method after this long (>= 1 frame)",
    )
    p.add_argument(
        "--temporal-frames",
        type=int,
        default=4,
        help="accumulated images per stb config for temporal instability",
    )
    p.add_argument("--eps", type=float, default=1e-2, help="relMSE epsilon (default 1e-2)")
    p.add_argument(
        "--mitsuba-spp",
        type=int,
        default=64,
        help="with the mitsuba wheel installed: the reference's error against Mitsuba 3 at "
        "this many samples per pixel, when the stage converts (0: skip; default 64)",
    )
    p.add_argument(
        "--hdr-flip",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="also HDR-FLIP on scene-linear (default on)",
    )
    p.add_argument(
        "--tile-caps",
        type=_tile_caps,
        help="tiled caps of the grid, e.g. 16,64,none (default 16,64,none)",
    )
    p.add_argument("--budgets", type=_budgets, help="frame-time budgets (ms) for the report")
    p.add_argument(
        "--report-only",
        action="store_true",
        help="redo the plot and report.md from --out's tradeoff.csv",
    )
    p.add_argument("--sweep-lights", help="frame time vs light count instead, e.g. 50,500,5000")
    p.add_argument(
        "--moving",
        type=float,
        metavar="DEG",
        help="moving-camera scenario instead: the camera orbits DEG degrees per frame "
        "(per-frame reference; stb raw and taa, exact methods); writes moving.csv/moving.md",
    )
    p.add_argument("--moving-frames", type=int, default=24, help="frames of the orbit (24)")
    p.add_argument(
        "--moving-skip", type=int, default=8, help="first frames left out of the medians (8)"
    )
    p.add_argument(
        "--pivot", type=float, default=12.0, help="orbit about the ground point this far ahead (m)"
    )
    p.add_argument(
        "--sweep-methods", help=f"methods of the sweep (default {','.join(SWEEP_METHODS)})"
    )
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    try:
        if args.width <= 0 or args.height <= 0:
            raise CliError("--width and --height must be positive")
        if args.frames < 1 or args.warmup < 0 or args.eps <= 0:
            raise CliError("need --frames >= 1, --warmup >= 0, --eps > 0")
        from ..renderer.engine import RenderError
        from ..renderer.gl import GLError

        try:
            if args.report_only:
                report_only(args)
            elif args.sweep_lights:
                run_sweep(args)
            elif args.moving is not None:
                run_moving_scenario(args)
            else:
                run_tradeoff(args)
        except (RenderError, GLError) as exc:
            raise CliError(str(exc)) from None
    except CliError as exc:
        return fail(str(exc))
    return EXIT_OK
