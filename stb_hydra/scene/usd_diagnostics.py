"""USD's own diagnostics (Tf warnings and errors) as one-line, deduplicated messages.

usd-core prints every Tf warning to stderr through its default diagnostic output:
opening the OpenChessSet prints 19 ``Warning: in _ReportErrors at line 3326 of
.../stage.cpp -- ...`` lines (MaterialX files usd-core cannot read), and parse errors
name ``pxrInternal_v0_26_11__pxrReserved__::Sdf_TextFileFormatParser`` rules.

**Mechanism.** ``TfDiagnosticMgr::AddDelegate`` (a ``TfDiagnosticMgr::Delegate``)
is not wrapped in usd-core's Python, but ``Tf.DiagnosticTrap`` is (USD 26.x): a
scoped interceptor on the current thread that captures every ``TfError``,
``TfWarning`` and ``TfStatus`` *reported* while it is active instead of handing them
to the delegates / default printer, with ``GetWarnings()``/``GetErrors()`` to read
them and ``Clear()`` to drop them (what is not cleared is re-posted when the trap
closes). :class:`UsdDiagnostics` holds one trap open, drains it into
:class:`Diagnostic` records, and :func:`summarize` collapses repeats into one line
per cause. Limits: the trap sees the current thread only (USD's own worker threads
report through the default printer; stage composition reports its errors on the
calling thread, ``UsdStage::_ReportErrors``), and errors raised inside a Python-wrapped
call become ``Tf.ErrorException`` (handled by the caller) rather than trapped reports.

:func:`clean_text` is the one text clean-up (also used for ``Tf.ErrorException``
messages): internal namespaces stripped, parse errors shortened, stage-instantiation
suffixes and file-format arguments dropped, paths under a base directory made
relative, whitespace folded into one line.
"""

from __future__ import annotations

import os
import re
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

#: ``pxrInternal_v0_26_11__pxrReserved__::`` and its PEGTL twin.
_NAMESPACE = re.compile(r"pxrInternal_v\d+(?:_\d+)*__pxrReserved__(?:_pegtl)?::")
#: ``FILE:LINE:COL: parse error matching RULE at 'TOKEN' in <PATH>``
_PARSE = re.compile(
    r"^(?P<file>.*?):(?P<line>\d+):(?P<col>\d+): parse error matching (?P<rule>.*) "
    r"at '(?P<tok>.*?)' in <(?P<path>[^>]*)>$"
)
_INSTANTIATING = re.compile(r"\s*\(instantiating stage on stage @[^@]*@ <0x[0-9a-fA-F]+>\)")
_FORMAT_ARGS = re.compile(r":SDF_FORMAT_ARGS:[^@]*@")
_ASSET = re.compile(r"@([^@]+)@")
_PRIM = re.compile(r"<[^<>]*>")
_NUMBER = re.compile(r"\b0x[0-9a-fA-F]+\b|\b\d+\b")
#: usd-core cannot open ``.mtlx`` layers (no usdMtlx plugin); the scene index reads
#: those references itself (:mod:`stb_hydra.scene.materialx`) and warns in its own
#: words when a document is missing or unreadable, so USD's composition error is
#: dropped (see :func:`handled_elsewhere`).
_MTLX_ARC = re.compile(
    r"Could not open asset @[^@]*\.mtlx@ for (?:reference|payload) introduced by"
)


def strip_namespaces(text: str) -> str:
    """``pxrInternal_v0_26_11__pxrReserved__::UsdStage::_ReportErrors`` ->
    ``UsdStage::_ReportErrors``."""
    return _NAMESPACE.sub("", text)


def _parse_error(text: str, stage_file: str | None) -> str | None:
    m = _PARSE.match(text)
    if m is None:
        return None
    rule = m.group("rule").rsplit("::", 1)[-1]
    tok = m.group("tok")
    where = f"line {m.group('line')}, column {m.group('col')}"
    f = m.group("file")
    if stage_file is None or os.path.abspath(f) != os.path.abspath(stage_file):
        where = f"{f}: {where}"
    at = f"'{tok}'" if tok else "end of file"
    expected = f" (expected {rule})" if re.fullmatch(r"\w+", rule) else ""
    return f"{where}: parse error at {at}{expected}"


def clean_text(text: str, base_dir: str | None = None, stage_file: str | None = None) -> str:
    """One line of a USD diagnostic's commentary for a user (see the module doc).
    ``base_dir``: asset paths under it are shown relative to it; ``stage_file``: a
    parse error in this file drops the repeated file name."""
    t = " ".join(strip_namespaces(text).split())
    parsed = _parse_error(t, stage_file)
    if parsed is not None:
        return parsed
    t = _INSTANTIATING.sub("", t)
    t = _FORMAT_ARGS.sub("@", t)
    if base_dir:
        base = os.path.abspath(base_dir)

        def rel(m: re.Match) -> str:
            p = m.group(1)
            if os.path.isabs(p):
                try:
                    r = os.path.relpath(p, base)
                except ValueError:
                    return m.group(0)
                if not r.startswith(".."):
                    return f"@{r}@"
            return m.group(0)

        t = _ASSET.sub(rel, t)
    return t.strip()


def cause_key(text: str) -> str:
    """What two diagnostics must share to be one cause: the text with asset paths'
    directories, prim paths and numbers blanked (the file extension is kept: a
    missing ``.mtlx`` and a missing ``.usd`` are two causes)."""
    k = _ASSET.sub(lambda m: "@*" + os.path.splitext(m.group(1))[1] + "@", text)
    k = _PRIM.sub("<*>", k)
    return _NUMBER.sub("#", k)


def handled_elsewhere(text: str) -> bool:
    """A (cleaned) USD diagnostic that stb_hydra reports in its own words: the
    failed composition of a ``.mtlx`` reference or payload."""
    return _MTLX_ARC.search(text) is not None


@dataclass(frozen=True)
class Diagnostic:
    """One trapped USD diagnostic: ``kind`` 'warning' | 'error'; ``text`` cleaned
    (one line); ``source``: the reporting C++ function, namespace stripped."""

    kind: str
    text: str
    source: str


class UsdDiagnostics:
    """Trap USD's Tf diagnostics on this thread while open (``with``)::

        with UsdDiagnostics(base_dir="scenes") as diag:
            stage = Usd.Stage.Open(...)
            for line in summarize(diag.drain()):
                print("warning:", line)

    ``drain()`` returns what was trapped since the last drain (status messages are
    dropped: informational; so are the failed ``.mtlx`` arcs the scene index reads
    itself, :func:`handled_elsewhere`). Anything not drained is dropped when the block ends
    (``keep=True``: re-posted to USD's default output instead)."""

    def __init__(self, base_dir: str | None = None, keep: bool = False) -> None:
        self.base_dir = base_dir
        self.keep = keep
        self._trap: Any = None
        self._ctx: Any = None

    def __enter__(self) -> UsdDiagnostics:
        from pxr import Tf

        self._trap = Tf.DiagnosticTrap()
        self._ctx = self._trap.__enter__()
        return self

    def drain(self) -> list[Diagnostic]:
        ctx = self._ctx
        if ctx is None:
            return []
        out: list[Diagnostic] = []
        for kind, items in (("error", ctx.GetErrors()), ("warning", ctx.GetWarnings())):
            for d in items:
                text = clean_text(str(d.commentary), self.base_dir)
                if handled_elsewhere(text):
                    continue
                out.append(Diagnostic(kind, text, strip_namespaces(str(d.sourceFunction))))
        ctx.Clear()
        return out

    def __exit__(self, *exc: object) -> None:
        ctx, self._ctx = self._ctx, None
        if ctx is not None and not self.keep:
            ctx.Clear()
        self._trap.__exit__(None, None, None)


def summarize(diags: Iterable[Diagnostic], seen: set[str] | None = None) -> list[str]:
    """One line per cause, in order of first appearance: ``usd: TEXT`` (errors:
    ``usd error: TEXT``), ``(+N more like this)`` when the cause repeats. Causes in
    ``seen`` (updated) are left out: a cause is reported once per run."""
    groups: dict[str, list[Diagnostic]] = {}
    for d in diags:
        groups.setdefault(d.kind + ":" + cause_key(d.text), []).append(d)
    lines = []
    for key, ds in groups.items():
        if seen is not None:
            if key in seen:
                continue
            seen.add(key)
        head = "usd error" if ds[0].kind == "error" else "usd"
        more = f" (+{len(ds) - 1} more like this)" if len(ds) > 1 else ""
        lines.append(f"{head}: {ds[0].text}{more}")
    return lines
