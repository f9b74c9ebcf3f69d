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
import os
import sys
import time as _time

from .. import limits
from .common import EXIT_OK, CliError, Reporter, fail, open_stage
from .render_steps import (
    _build_engine,
    _check_image_size,
    _check_outputs,
    _check_settings,
    _color_pipeline,
    _finish,
    _frame_meta,
    _frame_record,
    _render_settings,
    _resolve_temporal,
    _say_skipped,
    _stats_header,
    _warn_empty_view,
    _warn_no_lights,
    _write_outputs,
)


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
    p.add_argument(
        "--skip-existing",
        action="store_true",
        help="skip frames whose file exists; the others come out as in a full run (same "
        "seeds; with taa, existing frames before a missing one are rendered again, not "
        "written, for the history)",
    )
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
        try:
            eng.request_aovs(want)
        except ValueError as exc:  # a view the method draws only under other options
            raise CliError(str(exc)) from None
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


def _frame_output(output: str, fr: float | None) -> str:
    """The file of frame ``fr`` (one frame may be written to a plain OUTPUT, no ####)."""
    from ..io.images import frame_path, has_frame_placeholder

    numbered = fr is not None and has_frame_placeholder(output)
    return frame_path(output, fr) if numbered else output


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
    from ..io.images import ImageWriteError
    from ..renderer.engine import RenderError

    samples = max(1, int(eng.settings.accumulate))
    progress = _Progress(eng, len(frames), samples, rep)
    written = 0
    skipped: list[str] = []
    outs = [_frame_output(args.output, fr) for fr in frames]
    exists = [bool(args.skip_existing) and os.path.exists(o) for o in outs]
    # A skipped frame still feeds the taa history of the frames after it (rendered, not
    # written); in history-free modes its seeds are only counted (Engine.skip_frames).
    last_todo = max((i for i, e in enumerate(exists) if not e), default=-1)
    history = eng.settings.temporal == "taa"
    rerendered = 0
    try:
        for i, fr in enumerate(frames):
            out = outs[i]
            if exists[i]:
                skipped.append(out)
                if history and i < last_todo:
                    eng.render(fr)
                    rerendered += 1
                    progress.skip(0)
                else:
                    eng.skip_frames(samples)
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
    if rerendered:
        rep.say(
            f"stb render: {rerendered} existing frame(s) rendered again, not written: "
            "the taa history of the frames after them needs them"
        )
    stats["warnings"] = list(rep.lines)
    return written
