"""Small helpers shared by the rule modules: finding construction, authored values at
every time, compact time lists."""

from __future__ import annotations

import math
from collections.abc import Iterable

from pxr import Usd

from .findings import RULES, Finding


def finding(
    rule: str, prim: str, message: str, hint: str | None = None, severity: str | None = None
) -> Finding:
    """A finding of an stb rule with the table's severity/hint unless overridden."""
    r = RULES[rule]
    return Finding(
        rule, severity or r.severity, prim, message, r.hint if hint is None else hint, r.validator
    )


def authored_values(attr: Usd.Attribute) -> list[tuple[float | None, object]]:
    """(time, value) for the default (time None) and every authored time sample.

    The default is the composed default value, which is the schema fallback when
    none is authored (fallbacks are valid, so they never produce findings)."""
    out: list[tuple[float | None, object]] = []
    v = attr.Get(Usd.TimeCode.Default())
    if v is not None:
        out.append((None, v))
    for t in attr.GetTimeSamples():
        out.append((float(t), attr.Get(Usd.TimeCode(t))))
    return out


def fmt_times(times: Iterable[float | None]) -> str:
    """ "default", "time 59", "default, times 46-58, 60-63" (integer runs collapsed)."""
    times = list(times)
    ts = sorted({t for t in times if t is not None})
    runs: list[str] = []
    i = 0
    while i < len(ts):
        j = i
        while j + 1 < len(ts) and float(ts[j]).is_integer() and ts[j + 1] - ts[j] == 1:
            j += 1
        runs.append(f"{ts[i]:g}" if i == j else f"{ts[i]:g}-{ts[j]:g}")
        i = j + 1
    parts = ["default"] if None in times else []
    if ts:
        parts.append(("time " if len(ts) == 1 else "times ") + ", ".join(runs))
    return ", ".join(parts) or "-"


def fmt_value(v: object) -> str:
    if isinstance(v, float):
        return f"{v:g}"
    try:
        return "(" + ", ".join(f"{float(v[i]):g}" for i in range(len(v))) + ")"  # type: ignore[index]
    except (TypeError, ValueError):
        return str(v)


def components(v: object) -> list[float] | None:
    """Float components of a number or vector; None when not numeric."""
    try:
        if isinstance(v, (int, float)):
            return [float(v)]
        return [float(v[i]) for i in range(len(v))]  # type: ignore[index]
    except (TypeError, ValueError):
        return None


def all_finite(vals: list[float]) -> bool:
    return all(math.isfinite(x) for x in vals)


#: Test-only crash injection: ``"<mode>:<substring>"`` with mode ``raise`` (exception
#: inside a validator), ``segv`` (segmentation fault in the worker), ``abort`` or
#: ``hang`` (sleeps), for assets whose path contains ``substring``. Only the test-suite
#: sets it.
CRASH_HOOK_ENV = "STB_VALIDATE_TEST_CRASH"


def crash_hook(mode: str, path: str) -> None:
    """Crash as configured by :data:`CRASH_HOOK_ENV` (no-op when it is unset)."""
    import os

    spec = os.environ.get(CRASH_HOOK_ENV, "")
    want, _, needle = spec.partition(":")
    if not spec or want != mode or not needle or needle not in path:
        return
    if mode == "raise":
        raise RuntimeError(f"test crash hook ({CRASH_HOOK_ENV}) for {path}")
    if mode == "segv":
        import ctypes

        ctypes.string_at(0)
    if mode == "abort":
        os.abort()
    if mode == "hang":
        import time

        time.sleep(3600)
