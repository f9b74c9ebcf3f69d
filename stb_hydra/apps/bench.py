"""``stb bench``: frame and per-pass times, methods x light counts x resolutions.

    stb bench gen:lights:50,500,5000 --methods stb,sun --size 745x360 --json out/bench.json
    stb bench scene.usda gen:chess:500 --methods stb:N=1,stb:N=4,K=16,sun --frames 20
    stb bench gen:lights:500 --methods stb --stb K=32 --method-option stb:eps=0.05

Scenes: USD files, or generators ``gen:KIND:COUNTS[:key=value...]`` with KIND
``lights`` (:func:`stb_hydra.scenegen.lights.build_lights_stage`), ``chess``
(:func:`stb_hydra.scenegen.chess.build_chess_stage`) or ``orbs``
(:func:`stb_hydra.scenegen.orbs.build_orbs_stage`), COUNTS a comma list of light counts and
``key=value`` extra generator arguments (``gen:lights:500:seed=3:animated=50``).

Methods: ``--methods`` takes a comma list of ``NAME[:opt=value]``; a following
bare ``opt=value`` item belongs to the method before it, so
``--methods stb:N=4,K=16,sun,stb:N=1`` is stb (N=4, K=16), sun and stb (N=1).
``--method-option NAME:opt=value[,opt=value]`` and ``--NAME opt=value[,...]``
(one flag per registered method, e.g. ``--stb K=16``) set defaults for every
entry of that method; an entry's own options win.

Each (scene, size, method) renders ``--warmup`` + ``--frames`` frames with
``RenderSettings(profile=True)`` (``ctx.finish()`` after every task) and reports
medians (see :mod:`stb_hydra.apps.bench_core`). ``lights`` in a record is the
number of FoV-culled lights in view; ``scene_lights`` the scene's local lights.
Outputs: a table on stdout, ``--json`` (list of records), ``--csv`` and
``--plot`` (PNG: frame time vs light count per method, and stacked per-pass
bars); with ``--json`` alone the CSV and PNG go beside it.
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import os
import sys
import time as _clock
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .. import limits
from ..shadows.policy import DEFAULT_RESOLUTION
from .common import EXIT_OK, CliError, fail, parse_options, parse_value

DEFAULT_METHODS = "stb,reference,sun"
DEFAULT_SIZE = (745, 360)  # the talk's Adreno 610 resolution

#: Generator kind -> (``stb_hydra.scenegen`` module, builder, name of its count argument).
GENERATORS: dict[str, tuple[str, str, str]] = {
    "lights": ("lights", "build_lights_stage", "n_lights"),
    "chess": ("chess", "build_chess_stage", "n_lights"),
    "orbs": ("orbs", "build_orbs_stage", "n_orbs"),
}

#: Pass names in the talk's words (plot legends, table).
PASS_LABELS = {
    "lighting.stb_bigtile": "Big-Tile SRS",
    "lighting.stb_smalltile": "Small-Tile SRS",
    "lighting.stb_terms": "Shadows (terms)",
    "lighting.stb_lighting": "Lighting (STB)",
    "lighting": "Lighting",
    "lighting.other": "Lighting (other)",
    "gbuffer": "G-buffer",
    "hiz": "Min/max depth",
    "shadow": "Sun shadow",
    "shadow_atlas": "Shadow atlas",
    "light_cull": "Light cull",
    "accumulate": "Accumulate",
    "color_correction": "Colour correction",
    "aov_output": "AOV readback",
    "cpu": "CPU (sync+prepare+commit)",
}


# --- specs -------------------------------------------------------------------------------


@dataclass
class MethodSpec:
    name: str
    options: dict[str, Any] = field(default_factory=dict)

    @property
    def label(self) -> str:
        if not self.options:
            return self.name
        return self.name + ":" + ",".join(f"{k}={_fmt(v)}" for k, v in self.options.items())


@dataclass
class SceneCase:
    """One scene to benchmark: a file, or one light count of a generator."""

    label: str
    build: Callable[[], Any]


def _fmt(v: Any) -> str:
    return "none" if v is None else str(v).lower() if isinstance(v, bool) else str(v)


def parse_size(text: str) -> tuple[int, int]:
    """``'745x360'`` -> (745, 360); height 0 = from the camera's aspect."""
    w, sep, h = text.lower().partition("x")
    try:
        size = (int(w), int(h)) if sep else (int(w), 0)
    except ValueError:
        raise CliError(f"bad --size '{text}': use WIDTHxHEIGHT, e.g. 745x360") from None
    if size[0] <= 0 or size[1] < 0 or size[0] > 16384 or size[1] > 16384:
        raise CliError(f"bad --size '{text}': width 1..16384, height 0..16384")
    return size


def parse_methods(
    specs: list[str], defaults: dict[str, dict[str, Any]], available: list[str]
) -> list[MethodSpec]:
    """``--methods`` items -> method specs (see the module doc); duplicates dropped."""
    out: list[MethodSpec] = []
    for spec in specs:
        for item in (s.strip() for s in spec.split(",")):
            if not item:
                continue
            if "=" in item and ":" not in item.split("=", 1)[0]:
                if not out:
                    raise CliError(f"bad --methods '{spec}': option '{item}' before any method")
                out[-1].options.update(parse_options(item, "--methods"))
                continue
            name, _, opts = item.partition(":")
            name = name.strip()
            if name not in available:
                raise CliError(
                    f"unknown lighting method '{name}' (available: {', '.join(available)})"
                )
            out.append(MethodSpec(name, parse_options(opts, "--methods")))
    result: list[MethodSpec] = []
    seen: set[str] = set()
    for m in out:
        m.options = {**defaults.get(m.name, {}), **m.options}
        if m.label not in seen:
            seen.add(m.label)
            result.append(m)
    if not result:
        raise CliError("no lighting methods to benchmark")
    return result


def method_defaults(args: argparse.Namespace, available: list[str]) -> dict[str, dict[str, Any]]:
    """Per-method default options from ``--method-option`` and ``--NAME`` flags."""
    out: dict[str, dict[str, Any]] = {}
    for item in args.method_option or []:
        name, sep, opts = item.partition(":")
        if not sep or name not in available:
            raise CliError(
                f"bad --method-option '{item}': use METHOD:key=value "
                f"(methods: {', '.join(available)})"
            )
        out.setdefault(name, {}).update(parse_options(opts, "--method-option"))
    for name in available:
        for text in getattr(args, flag_dest(name), None) or []:
            out.setdefault(name, {}).update(parse_options(text, f"--{name}"))
    return out


def flag_dest(method: str) -> str:
    return "opts_" + method.replace("-", "_")


def parse_scene(spec: str) -> list[SceneCase]:
    """A USD path or ``gen:KIND:COUNTS[:key=value...]`` -> scene cases."""
    if not spec.startswith("gen:"):
        if not Path(spec).exists():
            raise CliError(f"cannot open stage '{spec}': file not found")

        def load(path: str = spec):
            from .common import open_stage

            return open_stage(path)

        return [SceneCase(spec, load)]
    parts = spec.split(":")
    if len(parts) < 3 or parts[1] not in GENERATORS:
        raise CliError(
            f"bad generator '{spec}': use gen:KIND:COUNTS with KIND one of "
            f"{', '.join(GENERATORS)} (e.g. gen:lights:50,500)"
        )
    kind = parts[1]
    try:
        counts = [int(c) for c in parts[2].split(",") if c.strip()]
    except ValueError:
        raise CliError(f"bad generator '{spec}': light counts must be integers") from None
    if not counts or min(counts) < 1:
        raise CliError(f"bad generator '{spec}': need light counts >= 1")
    kwargs: dict[str, Any] = {}
    for kv in parts[3:]:
        key, sep, val = kv.partition("=")
        if not sep:
            raise CliError(f"bad generator '{spec}': extra arguments are key=value")
        kwargs[key.strip()] = parse_value(val)
    return [SceneCase(_gen_label(kind, n, parts[3:]), _builder(kind, n, kwargs)) for n in counts]


def _gen_label(kind: str, n: int, extra: list[str]) -> str:
    return ":".join(["gen", kind, str(n), *extra])


def _builder(kind: str, n: int, kwargs: dict[str, Any]) -> Callable[[], Any]:
    mod_name, fn_name, count_arg = GENERATORS[kind]

    def build():
        from ..scenegen import chess, lights, orbs

        modules = {"lights": lights, "chess": chess, "orbs": orbs}
        fn = getattr(modules[mod_name], fn_name)
        try:
            return fn(**{count_arg: n, **kwargs})
        except (TypeError, ValueError, FileNotFoundError, RuntimeError) as exc:
            msg = " ".join(str(exc).split())
            raise CliError(f"generator gen:{kind}:{n} failed: {msg}") from None

    return build


# --- CLI ---------------------------------------------------------------------------------


def add_parser(sub) -> None:
    from ..renderer.lighting import available

    p = sub.add_parser(
        "bench",
        help="time lighting methods over scenes/light counts and resolutions",
        description=__doc__.split("\n\n", 1)[0],
    )
    p.add_argument(
        "scenes",
        nargs="+",
        metavar="SCENE_OR_GENERATOR",
        help="USD file or gen:lights:N1,N2,... / gen:chess:N / gen:orbs:N [:key=value...]",
    )
    p.add_argument(
        "--methods",
        action="append",
        help=f"comma list of NAME[:opt=value][,opt=value] (default {DEFAULT_METHODS}; "
        f"registered: {', '.join(available())})",
    )
    p.add_argument(
        "--method-option",
        action="append",
        metavar="METHOD:KEY=VALUE",
        help="default option for every entry of METHOD (repeatable)",
    )
    for name in available():
        try:
            p.add_argument(
                f"--{name}",
                dest=flag_dest(name),
                action="append",
                metavar="KEY=VALUE[,...]",
                help=f"default options of every '{name}' entry",
            )
        except argparse.ArgumentError:
            continue  # a method named like a bench option: use --method-option
    p.add_argument(
        "--size",
        action="append",
        metavar="WxH",
        help="resolution, repeatable (default 745x360; H=0: camera aspect)",
    )
    p.add_argument("--width", type=int, help="width (alternative to --size)")
    p.add_argument("--height", type=int, help="height (with --width; default camera aspect)")
    p.add_argument("--frames", type=int, default=10, help="measured frames (default 10)")
    p.add_argument("--warmup", type=int, default=2, help="warm-up frames (default 2)")
    p.add_argument(
        "--max-seconds",
        type=float,
        help="wall-time cap per configuration: slow methods (reference at 5,000 lights) "
        "measure fewer frames, at least one after one warm-up; records say how many",
    )
    p.add_argument("--camera", help="camera prim path (default: the stage's first camera)")
    p.add_argument("--time", type=float, help="stage time to render (default: start time)")
    p.add_argument("--seed", type=int, default=0, help="render seed of stochastic methods")
    p.add_argument(
        "--shadow-budget",
        type=int,
        help=f"shadow-atlas texels per frame (default {limits.SHADOW_UPDATE_BUDGET_TEXELS_DEFAULT}"
        ", or none when only --shadow-budget-ms is given)",
    )
    p.add_argument(
        "--shadow-budget-ms",
        type=float,
        help="shadow-capture milliseconds per frame (cost model re-fitted from wall-clock "
        "times); records report the capture time per frame and when every map was fresh",
    )
    p.add_argument(
        "--shadow-capture",
        choices=("per_face", "one_pass"),
        default="per_face",
        help="omni shadow capture mode (default per_face)",
    )
    p.add_argument(
        "--shadow-resolution",
        default=DEFAULT_RESOLUTION,
        help="comma-separated RenderSettings.shadow_resolution values, one record each: "
        "lift, flux, footprint, max (issue 33 item 5; default: "
        "shadows.policy.DEFAULT_RESOLUTION)",
    )
    p.add_argument("--json", help="write the records (a JSON list) here")
    p.add_argument("--csv", help="write a CSV here (default with --json: beside it)")
    p.add_argument("--plot", help="write the plot PNG here (default with --json: beside it)")
    p.add_argument("--no-plot", action="store_true", help="no plot PNG")
    p.add_argument("--quiet", "-q", action="store_true", help="no table, no progress bar")
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    try:
        return _run(args)
    except CliError as exc:
        return fail(str(exc))


def _sizes(args: argparse.Namespace) -> list[tuple[int, int]]:
    if args.size and (args.width or args.height):
        raise CliError("use either --size or --width/--height")
    if args.size:
        sizes = [parse_size(s) for s in args.size]
    elif args.width or args.height:
        if not args.width or args.width <= 0 or (args.height or 0) < 0:
            raise CliError("--width must be positive (and --height >= 0)")
        sizes = [(args.width, args.height or 0)]
    else:
        sizes = [DEFAULT_SIZE]
    return list(dict.fromkeys(sizes))


def _output_paths(args: argparse.Namespace) -> tuple[str | None, str | None, str | None]:
    js, cs, pl = args.json, args.csv, args.plot
    if js:
        base = os.path.splitext(js)[0]
        cs = cs or base + ".csv"
        pl = pl or base + ".png"
    if args.no_plot:
        pl = None
    for path in (js, cs, pl):
        if path:
            d = os.path.dirname(os.path.abspath(path))
            if not os.path.isdir(d):
                raise CliError(f"cannot write '{path}': directory does not exist: '{d}'")
    return js, cs, pl


def _check_method_options(methods: list[MethodSpec]) -> None:
    """Reject bad options before any scene is built (the methods' option schemas)."""
    from ..renderer.lighting import validate_options

    for m in methods:
        try:
            validate_options(m.name, m.options)
        except ValueError as exc:
            raise CliError(f"{m.label}: {exc}") from None


def _run(args: argparse.Namespace) -> int:
    from ..renderer.lighting import available

    avail = available()
    if args.frames < 1 or args.warmup < 0:
        raise CliError("--frames must be >= 1 and --warmup >= 0")
    if args.max_seconds is not None and not args.max_seconds > 0:
        raise CliError("--max-seconds must be > 0")
    methods = parse_methods(args.methods or [DEFAULT_METHODS], method_defaults(args, avail), avail)
    _check_method_options(methods)
    sizes = _sizes(args)
    budget = args.shadow_budget
    if budget is not None and budget <= 0:
        raise CliError(f"--shadow-budget must be a positive number of texels, got {budget}")
    ms = args.shadow_budget_ms
    if ms is not None and not 0 < ms <= limits.SHADOW_UPDATE_BUDGET_MS_MAX:
        raise CliError(
            f"--shadow-budget-ms must be in (0, {limits.SHADOW_UPDATE_BUDGET_MS_MAX:g}] "
            f"milliseconds, got {ms:g}"
        )
    if budget is None and ms is None:
        budget = limits.SHADOW_UPDATE_BUDGET_TEXELS_DEFAULT
    cases = [c for spec in args.scenes for c in parse_scene(spec)]
    out_json, out_csv, out_plot = _output_paths(args)

    def write_files(done: list[dict[str, Any]]) -> None:
        # After every configuration: a run stopped part-way keeps the rows it finished.
        if out_json:
            write_text(out_json, json.dumps(done, indent=2, allow_nan=False) + "\n")
        if out_csv:
            write_text(out_csv, records_csv(done))

    records = run_bench(
        cases,
        methods,
        sizes,
        frames=args.frames,
        warmup=args.warmup,
        max_seconds=args.max_seconds,
        camera=args.camera,
        time=args.time,
        seed=args.seed,
        progress=not args.quiet,
        shadow_budget=budget,
        shadow_budget_ms=args.shadow_budget_ms,
        shadow_capture=args.shadow_capture,
        shadow_resolutions=_resolutions(args.shadow_resolution),
        on_record=write_files,
    )
    if out_plot:
        plot_records(records, out_plot)
    if not args.quiet:
        print_table(records)
        for path in (out_json, out_csv, out_plot):
            if path:
                print(f"wrote {path}", file=sys.stderr)
    return EXIT_OK


# --- running -----------------------------------------------------------------------------


def run_bench(
    cases: list[SceneCase],
    methods: list[MethodSpec],
    sizes: list[tuple[int, int]],
    *,
    frames: int = 10,
    warmup: int = 2,
    max_seconds: float | None = None,
    camera: str | None = None,
    time: float | None = None,
    seed: int = 0,
    progress: bool = True,
    shadow_budget: int | None = limits.SHADOW_UPDATE_BUDGET_TEXELS_DEFAULT,
    shadow_budget_ms: float | None = None,
    shadow_capture: str = "per_face",
    shadow_resolutions: Sequence[str] = (DEFAULT_RESOLUTION,),
    on_record: Callable[[list[dict[str, Any]]], None] | None = None,
) -> list[dict[str, Any]]:
    """Every (scene, size, method, shadow resolution) -> one record (see the module doc).
    As each configuration finishes, its row is printed to stderr (with ``progress``:
    ``row_line``) and ``on_record`` gets the records so far (the CLI rewrites its JSON
    and CSV), so a run stopped part-way still says where its time went."""
    from tqdm import tqdm

    total = len(cases) * len(sizes) * len(methods) * len(shadow_resolutions) * (frames + warmup)
    bar = tqdm(total=total, unit="frame", disable=None if progress else True, file=sys.stderr)
    records: list[dict[str, Any]] = []
    try:
        for case in cases:
            bar.set_description(f"building {case.label}")
            t0 = _clock.perf_counter()
            stage = case.build()
            if progress:
                bar.write(
                    f"scene {case.label}: built in {_clock.perf_counter() - t0:.2f} s",
                    file=sys.stderr,
                )
            for size in sizes:
                for m, res in ((m, r) for m in methods for r in shadow_resolutions):
                    bar.set_description(f"{m.label} {case.label} {size[0]}x{size[1]}")
                    rec = bench_one(
                        stage,
                        case.label,
                        m,
                        size,
                        frames=frames,
                        warmup=warmup,
                        max_seconds=max_seconds,
                        camera=camera,
                        time=time,
                        seed=seed,
                        on_frame=lambda: bar.update(1),
                        shadow_budget=shadow_budget,
                        shadow_budget_ms=shadow_budget_ms,
                        shadow_capture=shadow_capture,
                        shadow_resolution=res,
                    )
                    records.append(rec)
                    if progress:
                        bar.write(row_line(rec), file=sys.stderr)
                    if on_record is not None:
                        on_record(records)
                    bar.update(frames + warmup - rec["frames"] - rec["warmup"])  # skipped
                    bar.set_postfix_str(f"{rec['frame_ms']:.1f} ms")
            del stage
    finally:
        bar.close()
    return records


def bench_one(
    stage,
    scene_label: str,
    method: MethodSpec,
    size: tuple[int, int],
    *,
    frames: int,
    warmup: int,
    max_seconds: float | None = None,
    camera: str | None = None,
    time: float | None = None,
    seed: int = 0,
    on_frame: Callable[[], None] | None = None,
    shadow_budget: int | None = limits.SHADOW_UPDATE_BUDGET_TEXELS_DEFAULT,
    shadow_budget_ms: float | None = None,
    shadow_capture: str = "per_face",
    shadow_resolution: str = DEFAULT_RESOLUTION,
) -> dict[str, Any]:
    """Measure one configuration on ``stage``; the engine is always released."""
    from ..renderer.engine import Engine, RenderError
    from ..renderer.frame import RenderSettings
    from ..renderer.gl import GLError
    from .bench_core import load_average, measure_engine

    settings = RenderSettings(
        width=size[0],
        height=size[1] or None,
        camera=camera,
        lighting=method.name,
        seed=seed,
        profile=True,
        # Real-time: captures under the per-frame budget(s), as a running application.
        shadow_budget=shadow_budget,
        shadow_budget_ms=shadow_budget_ms,
        shadow_capture_mode=shadow_capture,
        shadow_resolution=shadow_resolution,
        method_options=dict(method.options),
    )
    wall0, cpu0 = _clock.perf_counter(), _clock.process_time()
    try:
        eng = Engine(stage, settings, time=time)
    except (RenderError, GLError, ValueError) as exc:
        raise CliError(f"{method.label} on {scene_label}: {exc}") from None
    setup_s = _clock.perf_counter() - wall0
    try:
        load_before = load_average()
        m = measure_engine(
            eng,
            frames=frames,
            warmup=warmup,
            time=time,
            on_frame=on_frame,
            max_seconds=max_seconds,
        )
        # + the local lights a method without them left out (renderer.lighting.base.light_filter)
        scene_lights = int(eng.delegate.light_table.local_mask().sum())
        scene_lights += eng.scene_index.skipped_lights
        renderer = eng.renderer_info
    except (RenderError, GLError) as exc:
        raise CliError(f"{method.label} on {scene_label}: {exc}") from None
    finally:
        eng.release()
    return {
        # Where the configuration's time went (s): engine set-up (population, sync,
        # pass graph), the first frame (shader compiles, first captures), all warm-up
        # frames, and the whole configuration in wall and in process CPU time (every
        # thread, llvmpipe's included: the load-independent figure on a shared machine).
        "setup_s": _r(setup_s),
        "first_frame_s": _r(m.first_frame_s),
        "warmup_s": _r(m.warmup_s),
        "config_wall_s": _r(_clock.perf_counter() - wall0),
        "config_cpu_s": _r(_clock.process_time() - cpu0),
        "method": method.name,
        "label": method.label,
        "options": dict(method.options),
        "scene": scene_label,
        "shadow_resolution": shadow_resolution,
        "lights": int(m.stats.get("fov_lights", 0)),
        "scene_lights": scene_lights,
        "width": settings.width,
        "height": int(settings.height or 0),
        "frames": len(m.frame),
        "warmup": warmup,
        **m.summary(),
        **_shadow_summary(m, shadow_budget, shadow_budget_ms),
        **{k: m.stats.get(k) for k in CELL_FIELDS},
        "stats": m.stats,
        "load_avg": load_before,
        "renderer": renderer,
    }


def _resolutions(text: str) -> tuple[str, ...]:
    """``--shadow-resolution``'s comma-separated list, checked."""
    from ..shadows.policy import RESOLUTION_MODES

    vals = tuple(v.strip() for v in text.split(",") if v.strip())
    bad = [v for v in vals if v not in RESOLUTION_MODES]
    if bad or not vals:
        raise CliError(f"--shadow-resolution: {bad or text!r} not in {RESOLUTION_MODES}")
    return vals


def _shadow_summary(m: Any, budget: int | None, budget_ms: float | None) -> dict[str, Any]:
    """Shadow-capture figures of a run: the budgets, the capture pass time per measured
    frame that captured maps (median / p95 / max, ms) and when every shadow map was
    first fresh (frame index from the engine's first frame, warm-up included, and wall
    seconds; None if never within the run)."""
    import numpy as np

    # frames that captured something, some faces of a split map included (after every
    # map is fresh a static scene captures nothing, and those frames say nothing about
    # the budget)
    cap = [
        p.get("shadow_atlas", 0.0)
        for p, st in zip(m.passes, m.frame_stats)
        if st.get("shadow_maps_updated", 0) or st.get("shadow_texels_rendered", 0)
    ]
    return {
        "shadow_budget_texels": budget,
        "shadow_budget_ms": budget_ms,
        "shadow_capture_ms": _r(float(np.median(cap))) if cap else 0.0,
        "shadow_capture_ms_p95": _r(float(np.percentile(cap, 95))) if cap else 0.0,
        "shadow_capture_ms_max": _r(max(cap, default=0.0)),
        # fraction of measured frames whose capture time was within budget + 20 %
        "shadow_capture_within_budget_120": (
            None
            if budget_ms is None or not cap
            else _r(float(np.mean(np.array(cap) <= 1.2 * budget_ms)))
        ),
        "shadow_all_fresh_frame": m.all_fresh_frame,
        "shadow_all_fresh_s": None if m.all_fresh_s is None else _r(m.all_fresh_s),
    }


def _r(x: float) -> float:
    return round(float(x), 4)


# --- outputs -----------------------------------------------------------------------------


def write_text(path: str, text: str) -> None:
    """``text`` to ``path`` atomically (``io.files.write_text_atomic``: a temporary file
    in the same directory, removed on any failure, then a rename)."""
    from ..io.files import FileWriteError, write_text_atomic

    try:
        write_text_atomic(path, text)
    except FileWriteError as exc:
        raise CliError(str(exc)) from None


#: Per-cell light counts of the cell-list methods (tiled, clustered, lighttree; None
#: for the others): lights per tile / cluster (mean, median, p95, max, uncapped) and the mean
#: over the in-view lights -- the share of the reference's light-pixel work kept.
CELL_FIELDS = (
    "cell_lights_mean",
    "cell_lights_p50",
    "cell_lights_p95",
    "cell_lights_max",
    "cell_light_share",
)

CSV_FIELDS = (
    "method",
    "label",
    "scene",
    "lights",
    "scene_lights",
    "width",
    "height",
    "frames",
    "frame_ms",
    "frame_ms_min",
    "frame_ms_max",
    "gpu_ms",
    "cpu_ms",
    "cull_upload_ms",
    "accounted_fraction",
    *CELL_FIELDS,
    "load_avg",
    "setup_s",
    "first_frame_s",
    "warmup_s",
    "config_wall_s",
    "config_cpu_s",
)


def records_csv(records: list[dict[str, Any]]) -> str:
    """One row per record: fixed columns, then ``pass:<name>`` and ``cpu:<key>`` (ms)."""
    passes = list(dict.fromkeys(k for r in records for k in r["passes"]))
    cpu = list(dict.fromkeys(k for r in records for k in r["timings"]))
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow([*CSV_FIELDS, *(f"pass:{p}" for p in passes), *(f"cpu:{k}" for k in cpu)])
    for r in records:
        w.writerow(
            [r.get(f, "") for f in CSV_FIELDS]
            + [r["passes"].get(p, "") for p in passes]
            + [r["timings"].get(k, "") for k in cpu]
        )
    return buf.getvalue()


def _bar_label(r: dict[str, Any]) -> str:
    return f"{r['label']}\n{r['lights']} lights\n{r['width']}x{r['height']}"


def plot_records(records: list[dict[str, Any]], path: str) -> None:
    """Frame time vs FoV light count per method (and size), and stacked pass bars."""
    import matplotlib
    import numpy as np

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = len(records)
    fig, (ax1, ax2) = plt.subplots(
        2, 1, figsize=(max(10.0, 0.6 * n + 5.0), 9.0), gridspec_kw={"height_ratios": [1, 1.2]}
    )
    series: dict[tuple[str, int, int], list[tuple[int, float]]] = {}
    for r in records:
        series.setdefault((r["label"], r["width"], r["height"]), []).append(
            (r["lights"], r["frame_ms"])
        )
    markers = "osD^v<>"
    sizes = list(dict.fromkeys((w, h) for _, w, h in series))
    for (label, w, h), pts in series.items():
        pts.sort()
        mk = markers[sizes.index((w, h)) % len(markers)]
        ax1.plot([p[0] for p in pts], [p[1] for p in pts], marker=mk, label=f"{label} {w}x{h}")
    xs = [r["lights"] for r in records if r["lights"] > 0]
    if xs and max(xs) / max(min(xs), 1) > 20:
        ax1.set_xscale("log")
    ys = [r["frame_ms"] for r in records if r["frame_ms"] > 0]
    if ys and max(ys) / min(ys) > 20:
        ax1.set_yscale("log")
    ax1.set_xlabel("lights in view (FoV-culled)")
    ax1.set_ylabel("frame time (ms, median)")
    ax1.set_title("Frame time vs light count")
    ax1.grid(True, alpha=0.3)
    ax1.legend(fontsize=8, bbox_to_anchor=(1.01, 1.0), loc="upper left")

    keys = ["cpu", *dict.fromkeys(k for r in records for k in r["passes"])]
    cmap = plt.get_cmap("tab20")
    bottoms = [0.0] * n
    for i, k in enumerate(keys):
        vals = [r["cpu_ms"] if k == "cpu" else r["passes"].get(k, 0.0) for r in records]
        if not any(v > 0 for v in vals):
            continue
        ax2.bar(range(n), vals, bottom=bottoms, color=cmap(i % 20), label=PASS_LABELS.get(k, k))
        bottoms = [b + v for b, v in zip(bottoms, vals)]
    # Clip the axis when a few bars (the reference at 5,000 lights) dwarf the rest,
    # and print those bars' totals instead.
    med = float(np.median(bottoms)) if bottoms else 0.0
    fits = [b for b in bottoms if b <= 10.0 * med] or bottoms
    top = max(fits, default=1.0) * 1.15 or 1.0
    ax2.set_ylim(0.0, top)
    for i, b in enumerate(bottoms):
        if b > top:
            ax2.text(i, top * 0.97, f"{b:,.0f}", rotation=90, ha="center", va="top", fontsize=7)
    ax2.set_xticks(range(n))
    ax2.set_xticklabels([_bar_label(r) for r in records], fontsize=7)
    ax2.set_ylabel("ms (median per pass)")
    ax2.set_title("Per-pass time (ctx.finish() after every pass)")
    ax2.legend(fontsize=7, bbox_to_anchor=(1.01, 1.0), loc="upper left")
    ax2.grid(True, axis="y", alpha=0.3)
    fig.tight_layout()
    tmp = f"{path}.tmp-{os.getpid()}.png"
    try:
        fig.savefig(tmp, dpi=110)
        os.replace(tmp, path)
    except BaseException as exc:  # no temporary file left, whatever failed
        if os.path.exists(tmp):
            os.unlink(tmp)
        if isinstance(exc, OSError):
            raise CliError(f"cannot write '{path}': {exc.strerror or exc}") from None
        raise
    finally:
        plt.close(fig)


def row_line(r: dict[str, Any]) -> str:
    """One finished configuration in a line: its frame medians and where its wall time
    went (engine set-up, first frame, warm-up, whole) and its process CPU time."""
    return (
        f"row {r['label']} {r['scene']} {r['width']}x{r['height']}: "
        f"frame {r['frame_ms']:.1f} ms (x{r['frames']}), lights {r['lights']}/"
        f"{r['scene_lights']}; set-up {r['setup_s']:.2f} s, first frame "
        f"{r['first_frame_s']:.2f} s, warm-up {r['warmup_s']:.2f} s, whole "
        f"{r['config_wall_s']:.2f} s wall / {r['config_cpu_s']:.2f} s CPU"
    )


def _top_passes(r: dict[str, Any], k: int = 4) -> str:
    items = sorted(r["passes"].items(), key=lambda kv: -kv[1])[:k]
    return " ".join(f"{name.removeprefix('lighting.')}={ms:.2f}" for name, ms in items)


def print_table(records: list[dict[str, Any]]) -> None:
    from rich.console import Console
    from rich.table import Table

    t = Table(title="stb bench (medians, ms)")
    for col in ("method", "scene", "lights", "size", "frame", "cpu", "cull+upl", "top passes"):
        t.add_column(col, justify="left" if col in ("method", "scene", "top passes") else "right")
    for r in records:
        t.add_row(
            r["label"],
            r["scene"],
            f"{r['lights']}/{r['scene_lights']}",
            f"{r['width']}x{r['height']}",
            f"{r['frame_ms']:.2f}",
            f"{r['cpu_ms']:.2f}",
            f"{r['cull_upload_ms']:.3f}",
            _top_passes(r),
        )
    console = Console()
    if not console.is_terminal:
        console = Console(width=200)
    console.print(t)
    loads = [r["load_avg"] for r in records if r.get("load_avg") is not None]
    if loads:
        print(f"load average (1 min) during the runs: {min(loads)}..{max(loads)}")
