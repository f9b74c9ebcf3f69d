"""Shared helpers of the CLI verbs: stage opening with clean errors, exit codes, options,
and the :class:`Reporter` of warnings."""

from __future__ import annotations

import sys
from collections.abc import Iterable
from pathlib import Path
from typing import Any, TextIO

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


class Reporter:
    """A verb's warnings on stderr: one line each (``warning: ...``), deduplicated,
    printed as they are found, and a count at the end (:meth:`finish`); ``quiet``
    silences all of it (``--quiet``). :attr:`lines` keeps them for reports.

    While open (``with``), USD's own diagnostics reported on this thread are trapped
    (``Tf.DiagnosticTrap``, see :mod:`stb_hydra.scene.usd_diagnostics`) instead of
    printed raw; :meth:`drain_usd` turns them into warnings, one line per cause
    (repeats collapsed, internal namespaces stripped). Messages go through
    ``tqdm.write`` while a progress bar is shown (:attr:`bar`), so they do not break it.
    """

    def __init__(
        self,
        prog: str,
        quiet: bool = False,
        stream: TextIO | None = None,
        base_dir: str | None = None,
    ) -> None:
        self.prog = prog
        self.quiet = quiet
        self.stream = stream
        self.base_dir = base_dir
        self.lines: list[str] = []
        self.bar: Any = None
        self._seen: set[str] = set()
        self._causes: set[str] = set()
        self._usd: Any = None

    def __enter__(self) -> Reporter:
        from ..scene.usd_diagnostics import UsdDiagnostics

        self._usd = UsdDiagnostics().__enter__()
        return self

    def __exit__(self, *exc: object) -> None:
        usd = self._usd
        if usd is None:
            return
        try:
            if exc[0] is None:
                self.drain_usd()
        finally:
            self._usd = None
            usd.__exit__(None, None, None)

    def _out(self) -> TextIO:
        return self.stream or sys.stderr

    def say(self, text: str) -> None:
        """An informational line (not counted), silenced by ``quiet``."""
        if self.quiet:
            return
        if self.bar is not None:
            from tqdm import tqdm

            tqdm.write(text, file=self._out())
        else:
            print(text, file=self._out(), flush=True)

    def warn(self, msg: str) -> bool:
        """Report ``msg`` once (one line); True when it is new."""
        line = " ".join(str(msg).split())
        if not line or line in self._seen:
            return False
        self._seen.add(line)
        self.lines.append(line)
        self.say(f"warning: {line}")
        return True

    def warn_all(self, msgs: Iterable[str]) -> None:
        for m in msgs:
            self.warn(m)

    def take_usd(self, base_dir: str | None = None) -> list[str]:
        """Trapped USD diagnostics so far as lines (one per new cause), not printed:
        for verbs that report them elsewhere (``stb inspect``). ``base_dir``: asset
        paths under it are shown relative to it."""
        from ..scene.usd_diagnostics import summarize

        if base_dir is not None:
            self.base_dir = base_dir
        if self._usd is None:
            return []
        self._usd.base_dir = self.base_dir
        return summarize(self._usd.drain(), self._causes)

    def drain_usd(self, base_dir: str | None = None) -> None:
        """Trapped USD diagnostics so far -> warnings (one line per new cause)."""
        self.warn_all(self.take_usd(base_dir))

    @property
    def count(self) -> int:
        return len(self.lines)

    def finish(self) -> None:
        """The count line (``stb render: 3 warnings``), when there were any."""
        self.drain_usd()
        n = self.count
        if n:
            self.say(f"{self.prog}: {n} warning{'s' if n != 1 else ''}")
