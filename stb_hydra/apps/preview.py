"""``stb preview``: the interactive previewer (``stb_hydra.preview``; docs/PREVIEW.md).

Exit codes: 0 (window closed, script done, snapshot written); 2 with one line on
stderr when the window cannot open, the script or an argument is bad, or the stage
could not be shown (the error is also drawn in the window)."""

from __future__ import annotations

import argparse

from .common import EXIT_ERROR, CliError, fail, parse_options


def add_parser(sub) -> None:
    from ..renderer.lighting import available

    p = sub.add_parser(
        "preview",
        help="open a stage in an interactive window (usdview-like; needs the preview extra)",
    )
    p.add_argument("scene", help="USD file")
    p.add_argument("--camera", help="stage camera to start in (default: the first, else free)")
    p.add_argument(
        "--lighting", default="stb", choices=available(), help="lighting method (default stb)"
    )
    p.add_argument(
        "--option",
        "-o",
        action="append",
        default=[],
        metavar="KEY=VALUE[,KEY=VALUE]",
        help="lighting-method option, e.g. -o N=4,K=16 (repeatable)",
    )
    p.add_argument("--width", type=int, default=960, help="viewport width (default 960)")
    p.add_argument("--height", type=int, default=540, help="viewport height (default 540)")
    p.add_argument(
        "--temporal",
        choices=("auto", "accumulate", "taa", "off"),
        default="auto",
        help="auto (default): accumulate while still, taa while moving",
    )
    p.add_argument(
        "--while-moving",
        choices=("taa", "off"),
        default="taa",
        help="what --temporal auto runs while the camera or scene moves: taa (default) or "
        "off (raw frames: noisier, faster where the taa pass is slow, e.g. llvmpipe)",
    )
    p.add_argument(
        "--moving-scale",
        type=float,
        default=0.5,
        help="render scale while the camera or scene moves, 0.1..1 (default 0.5: a quarter "
        "of the pixels while navigating, upscaled; full resolution once still)",
    )
    p.add_argument(
        "--max-samples",
        type=int,
        default=64,
        help="still frames accumulated before rendering stops (default 64)",
    )
    p.add_argument("--time", type=float, help="start time code (default: the stage's start)")
    p.add_argument("--ocio-config", help="OCIO config (default: $OCIO, else OCIO's studio config)")
    p.add_argument("--display", help="OCIO display")
    p.add_argument("--view", help="OCIO view")
    p.add_argument("--exposure", type=float, default=0.0, help="display exposure in stops")
    p.add_argument("--script", metavar="EVENTS.json", help="scripted events (docs/PREVIEW.md)")
    p.add_argument(
        "--snapshot",
        metavar="OUT.png",
        help="after the script and --after-frames frames, write what the window shows, exit",
    )
    p.add_argument("--after-frames", type=int, default=1, help="frames before --snapshot")
    p.add_argument("--no-ui", action="store_true", help="start with the panels hidden (H)")
    p.add_argument("--screenshot-dir", default=".", help="where P / F12 screenshots go")
    p.add_argument("--exit-after-script", action="store_true", help="close when the script ends")
    p.add_argument(
        "--no-watch", action="store_true", help="no live reload when the stage's files change"
    )
    p.add_argument("--seed", type=int, default=0, help="random seed of stochastic methods")
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    try:
        return _main(args)
    except CliError as exc:
        return fail(str(exc))


def _main(args: argparse.Namespace) -> int:
    from ..color.ocio import ColorPipeline
    from ..io.images import check_output_path
    from ..renderer.frame import RenderSettings
    from ..renderer.lighting import validate_options
    from ..renderer.lighting.options import OptionError

    if args.width < 16 or args.height < 16 or args.width > 8192 or args.height > 8192:
        raise CliError(f"bad viewport {args.width}x{args.height}: 16..8192 pixels each")
    if not 0.1 <= args.moving_scale <= 1.0:
        raise CliError(f"bad --moving-scale {args.moving_scale}: 0.1..1")
    if args.max_samples < 1:
        raise CliError(f"bad --max-samples {args.max_samples}: at least 1")
    if args.after_frames < 1:
        raise CliError(f"bad --after-frames {args.after_frames}: at least 1")
    opts: dict = {}
    for text in args.option:
        opts.update(parse_options(text, "--option"))
    try:
        opts = {k: v for k, v in opts.items()}
        validate_options(args.lighting, opts)
    except (OptionError, ValueError) as exc:
        raise CliError(str(exc)) from None
    try:
        color = ColorPipeline(args.ocio_config, args.display, args.view, args.exposure)
    except ValueError as exc:
        raise CliError(str(exc)) from None
    if args.snapshot:
        try:
            check_output_path(args.snapshot)
        except (OSError, ValueError) as exc:
            raise CliError(str(exc)) from None
    try:
        from ..preview.script import ScriptError, load_script
        from ..preview.window import PreviewApp, RunOptions, WindowError
    except ImportError as exc:
        return fail(
            f"stb preview needs the preview extra (pip install 'stb_hydra[preview]'): {exc}"
        )
    try:
        events = load_script(args.script) if args.script else []
    except ScriptError as exc:
        return fail(str(exc))
    settings = RenderSettings(
        width=args.width,
        height=args.height,
        camera=args.camera,
        lighting=args.lighting,
        seed=args.seed,
        method_options=opts,
    )
    run = RunOptions(
        script=events,
        snapshot=args.snapshot,
        after_frames=args.after_frames,
        show_ui=not args.no_ui,
        screenshot_dir=args.screenshot_dir,
        exit_after_script=args.exit_after_script,
        watch=not args.no_watch,
    )
    try:
        app = PreviewApp(
            args.scene,
            settings,
            run,
            color=color,
            max_samples=args.max_samples,
            temporal=args.temporal,
            time=args.time,
            moving=args.while_moving,
            scale=args.moving_scale,
        )
    except WindowError as exc:
        return fail(str(exc))
    except ScriptError as exc:
        return fail(f"{args.script}: {exc}")
    code = app.run()
    return code if code else 0 if not app.session.error else EXIT_ERROR
