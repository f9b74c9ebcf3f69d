"""Shared helpers of the CLI verbs: stage opening with clean errors, exit codes."""

from __future__ import annotations

import sys
from pathlib import Path

EXIT_OK = 0
EXIT_FINDINGS = 1
EXIT_ERROR = 2


class CliError(Exception):
    """A one-line user-facing error; the CLI prints it and exits with code 2."""


def open_stage(path: str | Path):
    """Open a USD stage or raise :class:`CliError` with a one-line message."""
    from pxr import Tf, Usd

    import stb_hydra  # noqa: F401  (schema registration before the stage opens)

    p = Path(path)
    if not p.exists():
        raise CliError(f"cannot open stage '{path}': file not found")
    try:
        stage = Usd.Stage.Open(str(p))
    except Tf.ErrorException as exc:
        raise CliError(f"cannot open stage '{path}': {tf_message(exc)}") from None
    if stage is None:
        raise CliError(f"cannot open stage '{path}': not a USD file")
    return stage


def tf_message(exc: BaseException) -> str:
    """The human part of a Tf.ErrorException ("Error in 'X' at line N in file F : 'msg'")."""
    import re

    lines = [ln.strip() for ln in str(exc).strip().splitlines() if ln.strip()]
    text = lines[0] if lines else "unknown error"
    m = re.search(r" : '(.*)'$", text)
    return m.group(1) if m else text


def fail(msg: str) -> int:
    print(f"stb: error: {msg}", file=sys.stderr)
    return EXIT_ERROR
