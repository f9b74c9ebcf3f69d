"""Shared helpers of the CLI verbs: stage opening with clean errors, exit codes, options."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

from ..scene.stage_io import StageOpenError
from ..scene.stage_io import open_stage as _open_stage

EXIT_OK = 0
EXIT_FINDINGS = 1
EXIT_ERROR = 2


class CliError(Exception):
    """A one-line user-facing error; the CLI prints it and exits with code 2."""


def open_stage(path: str | Path):
    """Open a USD stage or raise :class:`CliError` with a one-line message
    (:func:`stb_hydra.scene.stage_io.open_stage`, its error as the CLI's)."""
    try:
        return _open_stage(path)
    except StageOpenError as exc:
        raise CliError(str(exc)) from None


def fail(msg: str) -> int:
    print(f"stb: error: {msg}", file=sys.stderr)
    return EXIT_ERROR


def parse_value(text: str) -> Any:
    """``'4'`` -> 4, ``'0.1'`` -> 0.1, ``true/false`` -> bool, ``none`` -> None, else str."""
    t = text.strip()
    low = t.lower()
    if low in ("true", "yes", "on"):
        return True
    if low in ("false", "no", "off"):
        return False
    if low in ("none", "null"):
        return None
    for conv in (int, float):
        try:
            return conv(t)
        except ValueError:
            pass
    return t


def parse_options(text: str, where: str) -> dict[str, Any]:
    """``'N=4,K=16'`` -> {'N': 4, 'K': 16}."""
    out: dict[str, Any] = {}
    for item in (s.strip() for s in text.split(",")):
        if not item:
            continue
        key, sep, val = item.partition("=")
        if not sep or not key.strip():
            raise CliError(f"bad option '{item}' in {where}: use key=value")
        out[key.strip()] = parse_value(val)
    return out
