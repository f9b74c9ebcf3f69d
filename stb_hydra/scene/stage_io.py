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
        raise StageOpenError(f"cannot open stage '{path}': {tf_message(exc)}") from None
    if stage is None:
        raise StageOpenError(f"cannot open stage '{path}': not a USD file")
    return stage


def tf_message(exc: BaseException) -> str:
    """The human part of a Tf.ErrorException ("Error in 'X' at line N in file F : 'msg'")."""
    lines = [ln.strip() for ln in str(exc).strip().splitlines() if ln.strip()]
    text = lines[0] if lines else "unknown error"
    m = re.search(r" : '(.*)'$", text)
    return m.group(1) if m else text
