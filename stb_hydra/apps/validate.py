"""``stb validate PATH... [--library-root DIR] [--json FILE] [--html FILE] [--thumbnails]
[--jobs N] [--rules ...] [--fail-on error|warning]``: asset-library light validation.

Modelled on ``usdchecker``: OpenUSD's built-in UsdValidation validators plus ours
(keyword ``stb``) on every ``.usd/.usda/.usdc/.usdz`` file found. Asset paths must stay
inside the library root: ``--library-root DIR`` (every PATH must lie inside it: e.g.
``stb validate usd_scenes/prefabs --library-root usd_scenes``, whose prefabs share
``usd_scenes/ies``), else each PATH directory (or a file's directory).
Exit codes: 0 clean, 1 findings at or above ``--fail-on``, 2 could not run.
Rules, JSON schema and thresholds: docs/VALIDATE.md.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

from .common import EXIT_ERROR, EXIT_FINDINGS, EXIT_OK, CliError, fail

_EXTS = (".usd", ".usda", ".usdc", ".usdz")


def collect_inputs(paths: list[str], library_root: str | None = None) -> list[tuple[str, str]]:
    """(file, library root) for every USD file under PATHs, sorted, deduplicated.
    ``library_root``: the one root of every file (each PATH must lie inside it);
    default: each PATH directory, or a file's directory."""
    out: dict[str, str] = {}
    lib = None
    if library_root is not None:
        lib_path = Path(library_root)
        if not lib_path.is_dir():
            raise CliError(f"--library-root '{library_root}' is not a directory")
        lib = str(lib_path.resolve())
    for arg in paths:
        p = Path(arg)
        if lib is not None and p.exists():
            real = str(p.resolve())
            if os.path.commonpath([real, lib]) != lib:
                raise CliError(f"'{arg}' is outside --library-root '{library_root}'")
        if p.is_dir():
            root = lib or str(p.resolve())
            for dirpath, dirnames, files in os.walk(p):
                dirnames.sort()
                for name in sorted(files):
                    if name.lower().endswith(_EXTS):
                        # a symlink out of the root stays a link: the scan reports it
                        # and never opens its target
                        f = Path(dirpath, name).resolve()
                        inside = os.path.commonpath([str(f), root]) == root
                        out.setdefault(str(f if inside else Path(dirpath, name).absolute()), root)
        elif p.is_file():
            if not p.name.lower().endswith(_EXTS):
                raise CliError(f"'{arg}' is not a USD file ({', '.join(_EXTS)})")
            out.setdefault(str(p.resolve()), lib or str(p.resolve().parent))
        else:
            raise CliError(f"cannot read '{arg}': no such file or directory")
    return sorted(out.items())


def _check_output(path: str | None, what: str) -> None:
    if path is None:
        return
    parent = Path(path).resolve().parent
    if not parent.is_dir() or not os.access(parent, os.W_OK):
        raise CliError(f"cannot write {what} '{path}': directory missing or not writable")


def add_parser(sub) -> None:
    p = sub.add_parser(
        "validate",
        help="validate USD assets (lights, IES, photometry, shadows, STB noise, units, paths)",
        description=__doc__.split("\n\n")[1] if __doc__ else None,
    )
    p.add_argument("paths", nargs="+", metavar="PATH", help="USD file or directory to walk")
    p.add_argument(
        "--library-root",
        metavar="DIR",
        help="the library's root directory: asset paths (references, IES "
        "files, textures) must resolve inside it; every PATH must lie inside "
        "it (default: each PATH directory, or a file's directory)",
    )
    p.add_argument("--json", metavar="FILE", help="write the JSON report")
    p.add_argument("--html", metavar="FILE", help="write an HTML report (one row per asset)")
    p.add_argument(
        "--thumbnails",
        action="store_true",
        help="render a small reference-lit thumbnail per asset into the HTML",
    )
    p.add_argument(
        "--jobs",
        "-j",
        type=int,
        default=1,
        metavar="N",
        help="worker processes (default 1; 0 = in this process, no crash isolation)",
    )
    p.add_argument(
        "--rules",
        nargs="+",
        metavar="RULE",
        help="rules to run: default, stb, usd, usd:all, rule ids, validator "
        "names or UsdValidation keywords (default: default)",
    )
    p.add_argument(
        "--fail-on",
        choices=("error", "warning"),
        default="error",
        help="lowest severity that makes the exit code 1 (default error)",
    )
    p.add_argument(
        "--timeout",
        type=float,
        default=None,
        metavar="S",
        help="seconds per asset before its worker is killed (default 300)",
    )
    p.add_argument("--quiet", "-q", action="store_true", help="no progress bar or table")
    from ..distributed.cluster import add_ray_arguments

    add_ray_arguments(p)  # --ray: one task per asset, --jobs ignored
    p.set_defaults(func=main)


def main(args: argparse.Namespace) -> int:
    from .. import limits

    try:
        if args.jobs < 0:
            raise CliError(f"--jobs must be >= 0, got {args.jobs}")
        _check_output(args.json, "JSON report")
        _check_output(args.html, "HTML report")
        tasks = collect_inputs(args.paths, args.library_root)
        if not tasks:
            raise CliError(
                "no USD files (.usd, .usda, .usdc, .usdz) found in "
                + ", ".join(f"'{p}'" for p in args.paths)
            )
        from ..validate import findings as fnd
        from ..validate.runner import Selection, SelectionError

        try:
            sel = Selection.parse(args.rules)
        except SelectionError as exc:
            raise CliError(str(exc)) from None
    except CliError as exc:
        return fail(str(exc))

    from ..validate import report
    from ..validate.parallel import WorkerStartError, run_parallel
    from ..validate.runner import validate_in_process

    timeout = args.timeout if args.timeout else limits.VALIDATE_ASSET_TIMEOUT_S
    t0 = time.perf_counter()
    bar = None
    if not args.quiet:
        from tqdm import tqdm

        bar = tqdm(
            total=len(tasks),
            unit="asset",
            desc="stb validate",
            file=sys.stderr,
            disable=None,
            dynamic_ncols=True,
        )

    def tick(_rep) -> None:
        if bar is not None:
            bar.update(1)

    jobs = args.jobs
    try:
        if getattr(args, "ray", None) is not None:
            from ..distributed.validate import run_on_ray

            reports, jobs = run_on_ray(
                args.ray, tasks, args.rules, args.thumbnails, timeout, on_done=tick
            )
        elif args.jobs == 0:
            reports = []
            for path, root in tasks:
                rep = validate_in_process(path, root, sel, args.thumbnails)
                reports.append(rep)
                tick(rep)
        else:
            reports = run_parallel(
                tasks, args.jobs, args.rules, args.thumbnails, timeout, on_done=tick
            )
    except (WorkerStartError, CliError) as exc:
        return fail(str(exc))
    finally:
        if bar is not None:
            bar.close()
    wall = time.perf_counter() - t0
    summ = report.summary(reports, wall, jobs)
    try:
        if args.json:
            report.write_json(
                args.json, report.document(reports, wall, jobs, args.fail_on, sel.validators)
            )
        if args.html:
            report.write_html(args.html, reports, summ, args.fail_on, args.thumbnails)
    except OSError as exc:
        return fail(f"cannot write report: {exc}")
    if not args.quiet:
        report.print_console(reports, summ, args.fail_on)
    threshold = fnd.severity_rank(args.fail_on)
    worst = max((r.worst() for r in reports), default=-1)
    return EXIT_FINDINGS if worst >= threshold else EXIT_OK


__all__ = ["EXIT_ERROR", "add_parser", "collect_inputs", "main"]
