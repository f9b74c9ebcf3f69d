"""The render verb's steps, shared by the local render (``apps/render.py``) and the
Ray driver and workers (``distributed/render.py``): option checks, the colour
pipeline, render settings, the engine, warnings, per-frame records and outputs.

A module of its own so that ``apps.render`` can hand ``--ray`` runs to
``stb_hydra.distributed`` while the distributed code reuses these steps without
importing the verb back (no import circle).
"""

from __future__ import annotations

import argparse
import json
import math
import os

from .. import limits
from .common import EXIT_ERROR, EXIT_OK, CliError, Reporter, parse_options


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


def _resolve_temporal(args: argparse.Namespace, stage, eng, frames, rep: Reporter) -> None:
    """``--temporal auto``: taa when the rendered camera moves over the frames (its world
    transform or lens changes), else accumulate (the engine was built with accumulate).
    ``--taa-filter`` without taa is said, not silently dropped."""
    if args.temporal == "auto":
        from ..scene.cameras import camera_moves

        if camera_moves(stage, eng.camera_path, frames):
            eng.set_temporal("taa")
            if args.verbose:
                rep.say(f"stb render: the camera {eng.camera_path} moves: --temporal taa")
    levels = int(getattr(args, "taa_filter", 0) or 0)
    if levels > 0 and eng.settings.temporal != "taa":
        why = (
            f"the camera {eng.camera_path} does not move over the frames, so --temporal "
            "auto chose accumulate"
            if args.temporal == "auto"
            else f"--temporal is {args.temporal}"
        )
        rep.warn(
            f"--taa-filter {levels} filters the taa pass only and is not applied: {why} "
            "(pass --temporal taa to filter these frames)"
        )


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
    if eng.scene_index.skipped_lights:
        return  # it has local lights, which this method does not draw (light_filter)
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
