"""``stb tradeoff SCENE``: error against frame time for every lighting method.

Runs a grid of configurations on one static view (camera, time fixed):

* ``stb``: the talk's pipeline (``-o reuse=off``), N in {1, 2, 4} x K in {4, 8, 16, 32,
  64} x weight cap on (8) / off, and the default, reservoir reuse (cap on), at every K, each
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

The code: :mod:`.tradeoff_measure` (the grid, scenes, engine pool, timing and
evaluation), :mod:`.tradeoff_report` (Pareto frontier, budget picks, plot, report and
CSV), :mod:`.tradeoff_sweep` (``--sweep-lights``), :mod:`.tradeoff_moving`
(``--moving``); this module runs the grid and ``--report-only`` and holds the verb.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import math
import sys
import time as _time
from pathlib import Path

import numpy as np

from ..io.files import write_text_atomic
from .common import EXIT_OK, CliError, fail
from .tradeoff_measure import (
    EnginePool,
    Run,
    Unit,
    _load,
    evaluate,
    grid_units,
    measure,
    open_scene,
)
from .tradeoff_report import finish_report, read_rows, write_csv
from .tradeoff_sweep import SWEEP_METHODS, run_sweep

CSV_FIELDS = [
    "scene",
    "method",
    "label",
    "N",
    "K",
    "weight_cap",
    "reuse",
    "accumulate",
    "tile_cap",
    "frame_ms",
    "frame_ms_min",
    "frame_ms_max",
    "x_reference",
    "cell_light_share",
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


def command_line(args) -> str:
    if len(sys.argv) > 1 and sys.argv[1] == "tradeoff":
        return "stb " + " ".join(sys.argv[1:])
    return f"stb tradeoff {args.scene} (called from Python)"


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
