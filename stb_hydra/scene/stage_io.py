"""Opening USD stages with one-line errors (shared by the renderer and the CLI verbs)."""

from __future__ import annotations

import re
from pathlib import Path
from typing import TYPE_CHECKING

from .._plugins import register_schema

if TYPE_CHECKING:
    from pxr import Usd


class StageOpenError(Exception):
    """A stage could not be opened; ``str(exc)`` is a one-line, user-facing message
    (``cannot open stage 'PATH': REASON``)."""


def open_stage(path: str | Path) -> Usd.Stage:
    """Open a USD stage or raise :class:`StageOpenError` with a one-line message."""
    from pxr import Tf, Usd

    register_schema()  # StbLightAPI / StbGeometryAPI before the stage opens (idempotent)
    p = Path(path)
    if not p.exists():
        raise StageOpenError(f"cannot open stage '{path}': file not found")
    try:
        stage = Usd.Stage.Open(str(p))
    except Tf.ErrorException as exc:
        raise StageOpenError(
            f"cannot open stage '{path}': {tf_message(exc, stage_file=str(p))}"
        ) from None
    if stage is None:
        raise StageOpenError(f"cannot open stage '{path}': not a USD file")
    return stage


def tf_message(exc: BaseException, stage_file: str | None = None) -> str:
    """The human part of a Tf.ErrorException: its first error's commentary, one line,
    internal namespaces stripped and parse errors shortened
    (:func:`stb_hydra.scene.usd_diagnostics.clean_text`; ``stage_file``: a parse
    error in it is reported by line and column only)."""
    from .usd_diagnostics import clean_text

    for err in getattr(exc, "args", ()):
        text = getattr(err, "commentary", None)
        if text:
            return clean_text(str(text), stage_file=stage_file)
    lines = [ln.strip() for ln in str(exc).strip().splitlines() if ln.strip()]
    text = lines[0] if lines else "unknown error"
    m = re.search(r" : '(.*)'$", text)
    return clean_text(m.group(1) if m else text, stage_file=stage_file)


def time_label(time: Usd.TimeCode | float | None) -> float | str:
    """A time code for people and reports: its value, or ``"default"`` for the
    default time and for the earliest time (what a stage without an authored time
    range is read at when no time is given)."""
    from pxr import Usd

    if time is None:
        return "default"
    if isinstance(time, Usd.TimeCode):
        if time.IsDefault() or time.IsEarliestTime():
            return "default"
        return float(time.GetValue())
    return float(time)
