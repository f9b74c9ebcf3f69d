"""The ``stb`` command: one verb per module in ``stb_hydra.apps``.

Every verb runs inside a :class:`~stb_hydra.apps.common.Reporter` (``args.reporter``):
warnings one line each on stderr, deduplicated, with a count at the end; USD's own
diagnostics are trapped and reported the same way (one line per cause).
"""

from __future__ import annotations

import argparse
import importlib
import signal
import sys
import threading
from typing import Any

VERBS = ("render", "inspect", "bench", "validate", "tradeoff", "preview", "bake")


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="stb",
        description="stb_hydra: USD scenes with many lights, Stochastic Tile-Based lighting.",
    )
    ap.add_argument("--version", action="version", version=_version())
    sub = ap.add_subparsers(dest="verb", required=True)
    for verb in VERBS:
        try:
            mod = importlib.import_module(f"stb_hydra.apps.{verb}")
        except ImportError:
            continue
        mod.add_parser(sub)
    return ap


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    from .. import __version__

    try:
        usd = version("usd-core")
    except PackageNotFoundError:  # a USD build of one's own, not the wheel
        from pxr import Usd

        usd = ".".join(str(v) for v in Usd.GetVersion())
    return f"stb {__version__} (usd-core {usd}, Python {sys.version.split()[0]})"


def main(argv: list[str] | None = None) -> int:
    from .common import Reporter

    ap = build_parser()
    args = ap.parse_args(argv)
    rep = Reporter(f"stb {args.verb}", quiet=bool(getattr(args, "quiet", False)))
    args.reporter = rep
    old = _catch_sigterm()
    try:
        with rep:
            code = int(args.func(args) or 0)
            rep.finish()
        return code
    except KeyboardInterrupt:
        print("stb: interrupted", file=sys.stderr)
        return 130
    except Terminated:
        print("stb: terminated (SIGTERM); finished outputs are complete", file=sys.stderr)
        return 128 + signal.SIGTERM
    finally:
        if old is not None:
            signal.signal(signal.SIGTERM, old)


class Terminated(BaseException):
    """SIGTERM arrived: unwinds like KeyboardInterrupt, so every atomic writer removes
    its temporary file and frames already written stay complete (issue 21, item 7)."""


def _raise_terminated(signum: int, frame: object) -> None:
    raise Terminated()


def _catch_sigterm() -> Any:
    """Turn SIGTERM into :class:`Terminated` (main thread only); the old handler."""
    if threading.current_thread() is not threading.main_thread():
        return None
    return signal.signal(signal.SIGTERM, _raise_terminated)


if __name__ == "__main__":
    sys.exit(main())
