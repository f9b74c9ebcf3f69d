"""``stb render SCENE OUTPUT``: scripted renders, modelled on usdrecord.

* ``OUTPUT`` extension picks the file: ``.exr`` scene-linear half float (camera
  exposure applied, display exposure not), ``.png/.jpg/.tif`` display-referred
  through OCIO (PNG/JPG on the GPU from OCIO's shader, TIFF 16-bit on the CPU).
* ``####`` in ``OUTPUT`` is the frame number (``--frames 1:48x2``).
* Errors (unknown camera, unwritable output, unsupported extension, empty or
  unreadable stage) print one line and exit 2; files are written atomically.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time as _time

from .. import limits
from .common import EXIT_ERROR, EXIT_OK, CliError, fail, open_stage, parse_options


def parse_frames(spec: str) -> list[float]:
    """usdrecord-style frames: ``F``, ``A:B`` or ``A:BxS`` (inclusive, step S > 0)."""
    s = spec.strip()
    try:
        if ":" not in s:
            return [float(s)]
        a, rest = s.split(":", 1)
        b, step = rest.split("x", 1) if "x" in rest else (rest, "1")
        a, b, st = float(a), float(b), float(step)
    except ValueError:
        raise CliError(f"bad --frames '{spec}': use F, A:B or A:BxS") from None
    if not (math.isfinite(a) and math.isfinite(b) and math.isfinite(st)) or st <= 0 or b < a:
        raise CliError(f"bad --frames '{spec}': need A <= B and a positive step")
    n = math.floor((b - a) / st + 1e-9) + 1
    if n > 100_000:
        raise CliError(f"bad --frames '{spec}': {n} frames is too many")
    return [a + i * st for i in range(n)]


def add_parser(sub) -> None:
    from ..renderer.lighting import available

    p = sub.add_parser("render", help="render a USD stage to image files (like usdrecord)")
    p.add_argument("scene", help="USD file")
    p.add_argument("output", help="image file (.exr .png .jpg .tif); #### = frame number")
    p.add_argument("--camera", help="camera prim path (default: the first camera, else a free one)")
    p.add_argument("--frames", help="F, A:B or A:BxS (default: the stage's start time)")
    p.add_argument("--width", type=int, default=960, help="image width in pixels (default 960)")
    p.add_argument("--height", type=int, default=0, help="image height (default: camera aspect)")
    p.add_argument(
        "--lighting",
        default="reference",
        choices=available(),
        help="lighting method (default reference)",
    )
    p.add_argument("--accumulate", type=int, default=1, help="frames averaged per image")
    p.add_argument("--seed", type=int, default=0, help="random seed of stochastic methods")
    p.add_argument("--ocio-config", help="OCIO config (default: $OCIO, else OCIO's studio config)")
    p.add_argument("--display", help="OCIO display (default: the config's default)")
    p.add_argument("--view", help="OCIO view (default: the config's default)")
    p.add_argument("--exposure", type=float, default=0.0, help="display exposure in stops")
    p.add_argument(
        "--aov",
        default="color",
        help="comma list of AOVs: color,depth,normal,albedo (written beside OUTPUT as .exr); "
        "debug views bigtile,smalltile,shadowterms (--lighting stb) and lightcount "
        "(written beside OUTPUT as .png; lightcount also as .exr counts)",
    )
    p.add_argument("--stats", help="write per-frame timings and counts to this JSON file")
    p.add_argument("--skip-existing", action="store_true", help="skip frames whose file exists")
    p.add_argument("--ambient", type=float, default=0.0, help="extra uniform ambient (nits)")
    p.add_argument(
        "--option",
        "-o",
        action="append",
        default=[],
        metavar="KEY=VALUE[,KEY=VALUE]",
        help="lighting-method option, e.g. -o N=4,K=16 for stb (repeatable)",
    )
    p.add_argument(
        "--no-weight-cap",
        action="store_true",
        help="stb: no weight capping (the unbiased mode; same as -o weight_cap=none)",
    )
    p.add_argument("--no-shadows", action="store_true", help="local lights unshadowed")
    p.add_argument(
        "--shadow-budget",
        type=int,
        help="shadow-atlas texels rendered per frame, to see a real-time frame "
        "(default: unlimited, every map captured before each frame; real time uses "
        f"{limits.SHADOW_UPDATE_BUDGET_TEXELS_DEFAULT})",
    )
    p.add_argument("--atlas-size", type=int, help="shadow atlas side in texels (power of two)")
    p.add_argument(
        "--shadow-filter",
        choices=("pcf", "stochastic"),
        default="pcf",
        help="local shadow filter: 4-tap gather PCF, or stochastic PCF",
    )
    p.add_argument("--verbose", "-v", action="store_true", help="print GL renderer and warnings")
    p.add_argument(
        "--print-graph",
        action="store_true",
        help="print the frame's pass graph (passes in order, what each reads and writes, "
        "render buffers) for these settings and exit without rendering",
    )
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    try:
        return _run(args)
    except CliError as exc:
        return fail(str(exc))


def _run(args: argparse.Namespace) -> int:
    aovs = _check_settings(args)
    frames = _check_outputs(args)
    stage = open_stage(args.scene)
    pipeline = _color_pipeline(args)
    settings = _render_settings(args)
    eng = _build_engine(stage, settings, pipeline, frames[0])
    if args.verbose:
        print(f"stb render: {eng.renderer_info}", file=sys.stderr)
    ext = os.path.splitext(args.output)[1].lower()
    want = set(aovs) | ({"display"} if ext in (".png", ".jpg", ".jpeg") else set())
    eng.request_aovs(want)
    if args.print_graph:
        print(eng.describe())
        eng.release()
        return EXIT_OK
    stats = _stats_header(args, eng, settings, pipeline)
    written = _render_frames(args, eng, frames, aovs, ext, pipeline, stats)
    return _finish(args, stats, written)


def _check_settings(args: argparse.Namespace) -> list[str]:
    """Argument checks before any work; the requested AOV names."""
    if args.width <= 0 or args.height < 0:
        raise CliError("--width and --height must be positive")
    if args.accumulate < 1:
        raise CliError("--accumulate must be >= 1")
    aovs = [a.strip() for a in args.aov.split(",") if a.strip()]
    from ..renderer.tasks.aov_output import AOVS, check_debug_aovs

    known = tuple(a for a in AOVS if a != "display")  # display: the PNG itself
    unknown = sorted(set(aovs) - set(known))
    if unknown:
        raise CliError(f"unknown AOV(s) {', '.join(unknown)} (choose from {','.join(known)})")
    try:
        check_debug_aovs(aovs, args.lighting)
    except ValueError as exc:
        raise CliError(str(exc)) from None
    return aovs


def _check_outputs(args: argparse.Namespace) -> list[float | None]:
    """OUTPUT is writable and names every frame; the frames to render (``[None]``: the
    stage's default time)."""
    from ..io.images import ImageWriteError, check_output_path, has_frame_placeholder

    try:
        check_output_path(args.output)
    except (ImageWriteError, ValueError) as exc:
        raise CliError(str(exc)) from None
    frames: list[float | None] = parse_frames(args.frames) if args.frames else [None]
    if len(frames) > 1 and not has_frame_placeholder(args.output):
        raise CliError("several --frames need a frame placeholder (####) in OUTPUT")
    return frames


def _color_pipeline(args: argparse.Namespace):
    from ..color.ocio import ColorPipeline

    try:
        return ColorPipeline(
            config_path=args.ocio_config,
            display=args.display,
            view=args.view,
            exposure=args.exposure,
        )
    except ValueError as exc:
        raise CliError(str(exc)) from None


def _render_settings(args: argparse.Namespace):
    """``RenderSettings`` from the flags (method options checked here)."""
    from ..renderer.frame import RenderSettings

    options: dict = {}
    for text in args.option:
        options.update(parse_options(text, "--option"))
    if args.no_weight_cap:
        if args.lighting != "stb":
            raise CliError("--no-weight-cap applies to --lighting stb")
        options["weight_cap"] = None
    if args.atlas_size is not None and (
        args.atlas_size < 256 or args.atlas_size & (args.atlas_size - 1)
    ):
        raise CliError(f"--atlas-size must be a power of two >= 256, got {args.atlas_size}")
    if args.shadow_budget is not None and args.shadow_budget <= 0:
        raise CliError(
            f"--shadow-budget must be a positive number of texels, got {args.shadow_budget}"
        )
    return RenderSettings(
        width=args.width,
        height=args.height or None,
        camera=args.camera,
        lighting=args.lighting,
        seed=args.seed,
        accumulate=args.accumulate,
        ambient=args.ambient,
        profile=bool(args.stats),
        shadows=not args.no_shadows,
        # None = offline: every map captured before the frame (RenderSettings).
        shadow_budget=args.shadow_budget,
        shadow_atlas_size=args.atlas_size,
        shadow_filter=args.shadow_filter,
        method_options=options,
    )


def _build_engine(stage, settings, pipeline, first: float | None):
    from ..renderer.engine import Engine, RenderError
    from ..renderer.gl import GLError

    try:
        return Engine(stage, settings, color=pipeline, time=first)
    except (RenderError, GLError, ValueError) as exc:
        raise CliError(str(exc)) from None


def _stats_header(args: argparse.Namespace, eng, settings, pipeline) -> dict:
    """The ``--stats`` document before any frame (also the images' metadata)."""
    return {
        "scene": args.scene,
        "renderer": eng.renderer_info,
        "settings": {
            "width": settings.width,
            "height": settings.height,
            "lighting": settings.lighting,
            "accumulate": settings.accumulate,
            "seed": settings.seed,
            "camera": eng.camera_path or "(free camera)",
            "display": pipeline.display,
            "view": pipeline.view,
            "exposure": pipeline.exposure,
        },
        "frames": [],
    }


def _render_frames(args: argparse.Namespace, eng, frames, aovs, ext, pipeline,
                   stats: dict) -> int:
    """Render and write every frame (``stats["frames"]``, then ``stats["warnings"]``);
    releases the engine. Returns the number of frames written."""
    from ..io.images import ImageWriteError, frame_path
    from ..renderer.engine import RenderError

    progress = None
    if len(frames) > 1:
        from tqdm import tqdm

        progress = tqdm(total=len(frames), unit="frame", disable=None, file=sys.stderr)
    written = 0
    try:
        for fr in frames:
            out = frame_path(args.output, fr) if fr is not None else args.output
            if args.skip_existing and os.path.exists(out):
                if progress:
                    progress.update(1)
                continue
            t0 = _time.perf_counter()
            try:
                frame = eng.render(fr)
            except RenderError as exc:
                raise CliError(str(exc)) from None
            wall = (_time.perf_counter() - t0) * 1e3
            meta = {
                "stb:camera": stats["settings"]["camera"],
                "stb:frame": "default" if fr is None else fr,
                "stb:renderSettings": stats["settings"],
                "stb:renderer": eng.renderer_info,
            }
            _write_outputs(eng, out, aovs, ext, pipeline, meta)
            written += 1
            stats["frames"].append(
                {
                    "frame": fr,
                    "output": out,
                    "wall_ms": round(wall, 3),
                    "timings_ms": {k: round(v, 3) for k, v in eng.timings.frames[-1].items()},
                    **{k: v for k, v in frame.stats.items() if isinstance(v, (int, float, bool))},
                }
            )
            if progress:
                progress.update(1)
    except ImageWriteError as exc:
        raise CliError(str(exc)) from None
    finally:
        if progress:
            progress.close()
        warnings = list(eng.warnings)
        eng.release()
    stats["warnings"] = warnings
    return written


def _finish(args: argparse.Namespace, stats: dict, written: int) -> int:
    """Warnings (``--verbose``), the ``--stats`` file and the exit code."""
    if args.verbose:
        for w in stats["warnings"]:
            print(f"warning: {w}", file=sys.stderr)
    if args.stats:
        _write_json_atomic(args.stats, stats)
    if written == 0 and not args.skip_existing:
        return EXIT_ERROR
    return EXIT_OK


def _write_outputs(eng, out, aovs, ext, pipeline, meta) -> None:
    from ..io.debug_views import write_debug_aov
    from ..io.images import write_aov, write_image
    from ..renderer.tasks.aov_output import DEBUG_AOVS

    res = eng.aovs
    if ext == ".exr":
        write_image(out, res["color"], metadata=meta, color_pipeline=pipeline)
    elif ext in (".png", ".jpg", ".jpeg") and "display" in res:
        write_image(
            out, res["display"], metadata=meta, color_pipeline=pipeline, display_referred=True
        )
    else:
        write_image(out, res["color"], metadata=meta, color_pipeline=pipeline)
    for a in aovs:
        if a == "color":
            continue
        if a in DEBUG_AOVS:
            write_debug_aov(out, a, res[a], metadata=meta)
            continue
        write_aov(out, a, res[a], metadata=meta)


def _write_json_atomic(path: str, data: dict) -> None:
    import tempfile

    d = os.path.dirname(os.path.abspath(path)) or "."
    try:
        fd, tmp = tempfile.mkstemp(prefix=".stats.", suffix=".json", dir=d)
    except OSError as exc:
        raise CliError(f"cannot write '{path}': {exc.strerror}") from None
    try:
        with os.fdopen(fd, "w") as f:
            json.dump(data, f, indent=2, allow_nan=False, default=str)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
