"""``stb render SCENE OUTPUT``: scripted renders, modelled on usdrecord.

* ``OUTPUT`` extension picks the file: ``.exr`` scene-linear half float (camera
  exposure applied, display exposure not), ``.png/.jpg/.tif`` display-referred
  through OCIO (PNG/JPG on the GPU from OCIO's shader, TIFF 16-bit on the CPU).
* ``####`` in ``OUTPUT`` is the frame number (``--frames 1:48x2``).
* Errors (unknown camera, unwritable output or ``--stats`` path, unsupported
  extension, empty or unreadable stage, a size beyond the OpenGL context's limits)
  print one line and exit 2 before anything is rendered; files are written
  atomically (mode 0666 minus the umask, like any new file).
* Warnings about the scene (and USD's own diagnostics) go to stderr, one line each,
  deduplicated, with a count at the end; ``--quiet`` silences them and the progress
  bar (frames, accumulated samples, shadow maps captured; shown on a terminal only).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time as _time

from .. import limits
from .common import EXIT_ERROR, EXIT_OK, CliError, Reporter, fail, open_stage, parse_options


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
    p.add_argument(
        "--height",
        type=int,
        default=None,
        help="image height in pixels (default: from the camera aspect)",
    )
    p.add_argument(
        "--lighting",
        default="reference",
        choices=available(),
        help="lighting method (default reference)",
    )
    p.add_argument("--accumulate", type=int, default=1, help="frames averaged per image")
    p.add_argument(
        "--temporal",
        choices=("auto", "accumulate", "taa", "off"),  # auto + renderer.frame.TEMPORAL_MODES
        default="auto",
        help="temporal reuse: accumulate (average the --accumulate frames of each image: a "
        "still camera), taa (reprojected history kept across --frames, with subpixel "
        "jitter: a moving camera or animated objects), off (no reuse); auto (default): taa "
        "when the camera moves over several --frames, else accumulate",
    )
    p.add_argument(
        "--taa-filter",
        type=int,
        default=0,
        metavar="LEVELS",
        help="with taa: an edge-aware a-trous filter of the displayed lighting, this many "
        "levels (0 = off, the default; 2 steadies a moving view, at ~3x the taa pass's "
        "cost on llvmpipe; the history stays unfiltered)",
    )
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
        "--texture-budget",
        type=float,
        metavar="MIB",
        help="GPU memory for material textures, mips included (default "
        f"{limits.TEXTURE_BUDGET_BYTES // 2**20} MiB); past it the largest are halved, "
        "with one warning naming them",
    )
    p.add_argument(
        "--shadow-budget",
        type=int,
        help="shadow-atlas texels rendered per frame, to see a real-time frame "
        "(default: unlimited, every map captured before each frame; real time uses "
        f"{limits.SHADOW_UPDATE_BUDGET_TEXELS_DEFAULT})",
    )
    p.add_argument(
        "--shadow-budget-ms",
        type=float,
        help="shadow-capture milliseconds per frame, priced by a cost model (texels, "
        "passes, triangles) calibrated at start-up and re-fitted from wall-clock times; "
        "with --shadow-budget too, a frame stops at whichever budget it reaches first",
    )
    p.add_argument(
        "--shadow-capture",
        choices=("per_face", "one_pass"),
        default="per_face",
        help="omni shadow capture: each cube face drawn on its own (default) or all six "
        "in one geometry-shader submission",
    )
    p.add_argument("--atlas-size", type=int, help="shadow atlas side in texels (power of two)")
    p.add_argument(
        "--shadow-filter",
        choices=("pcf", "stochastic"),
        default="pcf",
        help="local shadow filter: 4-tap gather PCF, or stochastic PCF",
    )
    p.add_argument("--verbose", "-v", action="store_true", help="print the GL renderer")
    p.add_argument(
        "--quiet",
        "-q",
        action="store_true",
        help="no warnings, no progress bar, no messages (errors still print)",
    )
    p.add_argument(
        "--print-graph",
        action="store_true",
        help="print the frame's pass graph (passes in order, what each reads and writes, "
        "render buffers) for these settings and exit without rendering",
    )
    from ..distributed.cluster import add_ray_arguments

    add_ray_arguments(p, render=True)
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    rep = getattr(args, "reporter", None) or Reporter("stb render", quiet=args.quiet)
    try:
        return _run(args, rep)
    except CliError as exc:
        return fail(str(exc))


def _run(args: argparse.Namespace, rep: Reporter) -> int:
    if getattr(args, "ray", None) is not None and not args.print_graph:
        from ..distributed.render import run

        return run(args, rep)
    aovs = _check_settings(args)
    frames = _check_outputs(args)
    stage = open_stage(args.scene)
    rep.drain_usd(os.path.dirname(os.path.abspath(args.scene)))
    pipeline = _color_pipeline(args)
    settings = _render_settings(args)
    eng = _build_engine(stage, settings, pipeline, frames[0])
    try:
        _check_image_size(eng)
        _resolve_temporal(args, stage, eng, frames, rep)
        if args.verbose:
            rep.say(f"stb render: {eng.renderer_info}")
        ext = os.path.splitext(args.output)[1].lower()
        want = set(aovs) | ({"display"} if ext in (".png", ".jpg", ".jpeg") else set())
        eng.request_aovs(want)
    except BaseException:
        eng.release()
        raise
    if args.print_graph:
        print(eng.describe())
        eng.release()
        return EXIT_OK
    rep.warn_all(eng.warnings)
    _warn_no_lights(eng, args, rep)
    stats = _stats_header(args, eng, settings, pipeline)
    written = _render_frames(args, eng, frames, aovs, ext, pipeline, stats, rep)
    return _finish(args, stats, written, rep)


def _resolve_temporal(args: argparse.Namespace, stage, eng, frames, rep: Reporter) -> None:
    """``--temporal auto``: taa when the rendered camera moves over the frames (its world
    transform or lens changes), else accumulate (the engine was built with accumulate)."""
    if args.temporal != "auto":
        return
    from ..scene.cameras import camera_moves

    if camera_moves(stage, eng.camera_path, frames):
        eng.set_temporal("taa")
        if args.verbose:
            rep.say(f"stb render: the camera {eng.camera_path} moves: --temporal taa")


def _check_settings(args: argparse.Namespace) -> list[str]:
    """Argument checks before any work; the requested AOV names."""
    if args.width <= 0:
        raise CliError(f"--width must be a positive number of pixels, got {args.width}")
    if args.height is not None and args.height <= 0:
        raise CliError(
            f"--height must be a positive number of pixels, got {args.height} "
            "(leave it out to follow the camera aspect)"
        )
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
    if args.stats:
        from ..io.files import FileWriteError, check_file_path

        try:
            check_file_path(args.stats, "--stats")
        except FileWriteError as exc:
            raise CliError(str(exc)) from None
    return frames


def max_image_size(ctx) -> int:
    """The largest image side this OpenGL context renders: the smallest of its
    texture, renderbuffer, framebuffer and viewport limits."""
    info = ctx.info
    sides = [
        info.get("GL_MAX_TEXTURE_SIZE"),
        info.get("GL_MAX_RENDERBUFFER_SIZE"),
        info.get("GL_MAX_FRAMEBUFFER_WIDTH"),
        info.get("GL_MAX_FRAMEBUFFER_HEIGHT"),
        *(info.get("GL_MAX_VIEWPORT_DIMS") or ()),
    ]
    return int(min(int(v) for v in sides if v))


def _check_image_size(eng) -> None:
    """``--width``/``--height`` (the height resolved from the camera aspect) within
    the context's limits, before any render buffer is allocated."""
    limit = max_image_size(eng.ctx)
    w, h = eng.settings.width, eng.settings.height
    for flag, v in (("--width", w), ("--height", h)):
        if v > limit:
            raise CliError(
                f"{flag} {v} exceeds this OpenGL context's largest image side {limit} "
                f"(image {w}x{h})"
            )


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
    tb = args.texture_budget
    if tb is not None and not (math.isfinite(tb) and tb > 0):
        raise CliError(f"--texture-budget must be a positive number of MiB, got {tb:g}")
    ms = args.shadow_budget_ms
    if ms is not None and not 0 < ms <= limits.SHADOW_UPDATE_BUDGET_MS_MAX:
        raise CliError(
            f"--shadow-budget-ms must be in (0, {limits.SHADOW_UPDATE_BUDGET_MS_MAX:g}] "
            f"milliseconds, got {ms:g}"
        )
    try:
        return RenderSettings(
            width=args.width,
            height=args.height,
            camera=args.camera,
            lighting=args.lighting,
            seed=args.seed,
            accumulate=args.accumulate,
            temporal="accumulate" if args.temporal == "auto" else args.temporal,
            taa_filter=args.taa_filter,
            ambient=args.ambient,
            profile=bool(args.stats),
            shadows=not args.no_shadows,
            # None = offline: every map captured before the frame (RenderSettings).
            shadow_budget=args.shadow_budget,
            shadow_budget_ms=ms,
            shadow_capture_mode=args.shadow_capture,
            shadow_atlas_size=args.atlas_size,
            shadow_filter=args.shadow_filter,
            texture_budget_mib=args.texture_budget,
            method_options=options,
        )
    except ValueError as exc:  # a setting out of range (e.g. --taa-filter)
        raise CliError(str(exc)) from None


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
            "temporal": settings.temporal,
            "taa_filter": settings.taa_filter,
            "seed": settings.seed,
            "camera": eng.camera_path or "(free camera)",
            "display": pipeline.display,
            "view": pipeline.view,
            "exposure": pipeline.exposure,
            # null: offline, every shadow map captured before each frame
            "shadow_budget": settings.shadow_budget,
            "shadow_budget_ms": settings.shadow_budget_ms,
            "texture_budget_mib": settings.texture_budget_mib,
        },
        "frames": [],
    }


def _warn_no_lights(eng, args: argparse.Namespace, rep: Reporter) -> None:
    """One warning when nothing lights the stage (the image would be black)."""
    lights = [sp.light for sp in eng.delegate.lights.values() if sp.light is not None]
    if any(lp.enabled for lp in lights) or args.ambient > 0:
        return
    why = f"none of its {len(lights)} lights is enabled" if lights else "the stage has no lights"
    rep.warn(f"{why}: the image shows unlit (black) geometry; add a light or --ambient")


def _warn_empty_view(eng, rep: Reporter) -> None:
    """One warning when the camera sees no geometry (coverage = colour alpha)."""
    res = eng.aovs
    img = res.get("color")
    if img is None or img.ndim != 3 or img.shape[2] < 4:
        return
    if not (img[..., 3] > 0).any():
        cam = eng.camera_path or "the free camera"
        rep.warn(f"camera {cam} sees no geometry: the image is background only")


class _Progress:
    """The progress bar (stderr, a terminal only; none with ``--quiet``): accumulated
    samples of all frames, with the frame and the shadow maps captured so far."""

    def __init__(self, eng, frames: int, samples: int, rep: Reporter) -> None:
        from tqdm import tqdm

        self.frames = frames
        self.frame = 0
        self.maps = 0
        self.bar = tqdm(
            total=frames * samples,
            unit="sample",
            desc="stb render",
            file=sys.stderr,
            disable=True if rep.quiet else None,  # None: off when stderr is not a tty
            dynamic_ncols=True,
        )
        self.rep = rep
        if not self.bar.disable:
            rep.bar = self.bar
        # Engine.render(time) draws its accumulated samples through the public
        # render_frame; counting them there moves the bar within a frame.
        inner = eng.render_frame

        def render_frame(*a, **kw):
            fr = inner(*a, **kw)
            self.sample(fr)
            return fr

        eng.render_frame = render_frame

    def start_frame(self, index: int) -> None:
        self.frame = index + 1
        self._postfix()
        if not self.bar.disable:
            self.bar.refresh()

    def sample(self, frame) -> None:
        self.maps += int(frame.stats.get("shadow_maps_updated", 0) or 0)
        self.bar.update(1)
        self._postfix()

    def skip(self, samples: int) -> None:
        self.bar.update(samples)

    def _postfix(self) -> None:
        if not self.bar.disable:
            self.bar.set_postfix_str(
                f"frame {self.frame}/{self.frames}, shadow maps {self.maps}", refresh=False
            )

    def close(self) -> None:
        self.bar.close()
        self.rep.bar = None


def _render_frames(
    args: argparse.Namespace, eng, frames, aovs, ext, pipeline, stats: dict, rep: Reporter
) -> int:
    """Render and write every frame (``stats["frames"]``, then ``stats["warnings"]``);
    releases the engine. Returns the number of frames written."""
    from ..io.images import ImageWriteError, frame_path, has_frame_placeholder
    from ..renderer.engine import RenderError

    samples = max(1, int(eng.settings.accumulate))
    progress = _Progress(eng, len(frames), samples, rep)
    written = 0
    skipped: list[str] = []
    try:
        for i, fr in enumerate(frames):
            # one frame may be written to a plain OUTPUT (no ####)
            numbered = fr is not None and has_frame_placeholder(args.output)
            out = frame_path(args.output, fr) if numbered else args.output
            if args.skip_existing and os.path.exists(out):
                skipped.append(out)
                progress.skip(samples)
                continue
            progress.start_frame(i)
            t0 = _time.perf_counter()
            try:
                frame = eng.render(fr)
            except RenderError as exc:
                raise CliError(str(exc)) from None
            wall = (_time.perf_counter() - t0) * 1e3
            rep.warn_all(eng.warnings)
            rep.drain_usd()
            _warn_empty_view(eng, rep)
            meta = _frame_meta(stats, eng, fr)
            _write_outputs(eng, out, aovs, ext, pipeline, meta)
            written += 1
            stats["frames"].append(_frame_record(eng, frame, out, wall))
    except ImageWriteError as exc:
        raise CliError(str(exc)) from None
    finally:
        progress.close()
        eng.release()
    if skipped:
        _say_skipped(rep, skipped, len(frames))
    stats["warnings"] = list(rep.lines)
    return written


def _say_skipped(rep: Reporter, skipped: list[str], n_frames: int) -> None:
    names = ", ".join(os.path.basename(p) for p in skipped[:3])
    more = f" ... {os.path.basename(skipped[-1])}" if len(skipped) > 3 else ""
    rep.say(
        f"stb render: --skip-existing skipped {len(skipped)} of {n_frames} "
        f"frame{'s' if n_frames != 1 else ''} (files exist: {names}{more})"
    )


def _frame_meta(stats: dict, eng, fr: float | None) -> dict:
    """The images' metadata of frame ``fr``."""
    return {
        "stb:camera": stats["settings"]["camera"],
        "stb:frame": "default" if fr is None else fr,
        "stb:renderSettings": stats["settings"],
        "stb:renderer": eng.renderer_info,
    }


def _frame_record(eng, frame, out: str, wall: float) -> dict:
    """The ``--stats`` record of the frame just rendered to ``out``."""
    from ..scene.stage_io import time_label

    return {
        # the time code rendered: a number, or "default" for a stage
        # without a time range rendered without --frames
        "frame": time_label(eng.scene_index.time),
        "output": out,
        "wall_ms": round(wall, 3),
        "timings_ms": {k: round(v, 3) for k, v in eng.timings.frames[-1].items()},
        **{k: v for k, v in frame.stats.items() if v is None or isinstance(v, (int, float, bool))},
    }


def _finish(args: argparse.Namespace, stats: dict, written: int, rep: Reporter) -> int:
    """The ``--stats`` file and the exit code (warnings were printed as found)."""
    if args.stats:
        from ..io.files import FileWriteError, write_text_atomic

        try:
            write_text_atomic(
                args.stats, json.dumps(stats, indent=2, allow_nan=False, default=str) + "\n"
            )
        except FileWriteError as exc:
            raise CliError(str(exc)) from None
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
