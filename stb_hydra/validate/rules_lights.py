"""Per-light rules (prim validators on ``UsdLuxLightAPI`` prims).

``LightValues``: intensity, exposure, colour, sizes, cone angle and focus are checked
at the default time *and every authored time sample*, under the modern ``inputs:``
name or the legacy un-namespaced one (which is itself reported).
``IesProfile``: every authored value of ``inputs:shaping:ies:file`` (default and time
samples) must resolve and parse, emit something, and not be inverted by
``ies:angleScale``.
"""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Callable

import numpy as np
from pxr import Sdf, Usd

from .. import limits
from ..scene import prims
from ..scene.ies import IesError, IesProfile
from ..scene.light_shaping import ies_theta, load_ies_cached
from ..scene.lights import LEGACY_INPUTS
from .common import all_finite, authored_values, components, finding, fmt_times, fmt_value
from .findings import Finding

# (attribute without "inputs:", rule, predicate(value components) -> problem text or None)
_Check = Callable[[list[float]], str | None]


def _nonneg(what: str) -> _Check:
    def check(c: list[float]) -> str | None:
        if not all_finite(c):
            return f"{what} is not finite"
        if min(c) < 0:
            return f"{what} is negative"
        return None

    return check


def _exposure(c: list[float]) -> str | None:
    if not all_finite(c):
        return "exposure is not finite"
    if abs(c[0]) > limits.MAX_ABS_EXPOSURE:
        return f"exposure beyond +-{limits.MAX_ABS_EXPOSURE:g} stops"
    return None


def _finite(what: str) -> _Check:
    def check(c: list[float]) -> str | None:
        return None if all_finite(c) else f"{what} is not finite"

    return check


def _cone(c: list[float]) -> str | None:
    a = c[0]
    if not math.isfinite(a) or a <= 0.0 or a > prims.NO_CONE_ANGLE_DEG:
        return "cone angle outside (0, 180] degrees"
    return None


def _focus(c: list[float]) -> str | None:
    if not all_finite(c):
        return "focus is not finite"
    if c[0] < 0:
        return "focus is negative"
    return None


_CHECKS: tuple[tuple[str, str, _Check], ...] = (
    ("intensity", "intensity_invalid", _nonneg("intensity")),
    ("exposure", "exposure_invalid", _exposure),
    ("color", "color_invalid", _nonneg("colour")),
    ("colorTemperature", "color_invalid", _finite("colour temperature")),
    ("radius", "shape_invalid", _nonneg("radius")),
    ("width", "shape_invalid", _nonneg("width")),
    ("height", "shape_invalid", _nonneg("height")),
    ("length", "shape_invalid", _nonneg("length")),
    ("angle", "shape_invalid", _nonneg("angle")),
    ("shaping:cone:angle", "cone_angle_invalid", _cone),
    ("shaping:focus", "focus_invalid", _focus),
)


def _attr(prim: Usd.Prim, names: set[str], base: str) -> Usd.Attribute | None:
    """The authored modern ``inputs:<base>`` attribute, else the legacy ``<base>``."""
    for n in (f"inputs:{base}", base):
        if n in names:
            a = prim.GetAttribute(n)
            if a and a.HasAuthoredValue():
                return a
    return None


def check_light_values(prim: Usd.Prim) -> list[Finding]:
    """LightValues validator body."""
    out: list[Finding] = []
    path = str(prim.GetPath())
    names = set(prim.GetAuthoredPropertyNames())
    for base, rule, check in _CHECKS:
        a = _attr(prim, names, base)
        if a is None:
            continue
        bad: dict[str, list[tuple[float | None, object]]] = defaultdict(list)
        for t, v in authored_values(a):
            c = components(v)
            if c is None:
                continue
            problem = check(c)
            if problem:
                bad[problem].append((t, v))
        for problem, hits in bad.items():
            _, v0 = hits[0]
            more = f" ({len(hits)} values)" if len(hits) > 1 else ""
            out.append(
                finding(
                    rule,
                    path,
                    f"{a.GetName()} = {fmt_value(v0)}: {problem} at {fmt_times(t for t, _ in hits)}"
                    f"{more}",
                )
            )
    out.extend(_check_light_texture(prim, names, path))
    legacy = sorted(n for n in names if n in LEGACY_INPUTS)
    if legacy:
        pairs = ", ".join(f"'{n}' -> 'inputs:{n}'" for n in legacy)
        out.append(
            finding(
                "legacy_attribute",
                path,
                f"legacy un-namespaced light attribute{'s' if len(legacy) > 1 else ''}: {pairs}",
            )
        )
    return out


def _check_light_texture(prim: Usd.Prim, names: set[str], path: str) -> list[Finding]:
    """``dome_texture_missing``: a named dome / rect texture that does not resolve."""
    if prim.GetTypeName() not in ("DomeLight", "DomeLight_1", "RectLight"):
        return []
    fa = _attr(prim, names, "texture:file")
    if fa is None:
        return []
    missing = [(t, a) for t, a, resolved in _asset_values(fa) if not resolved]
    if not missing:
        return []
    return [
        finding(
            "dome_texture_missing",
            path,
            f"{fa.GetName()} '{missing[0][1]}' does not resolve "
            f"({fmt_times(t for t, _ in missing)})",
        )
    ]


# --- IES ------------------------------------------------------------------------------

_NT, _NP = 256, 32


def _downwardness(prof: IesProfile, angle_scale: float) -> tuple[float, float, float]:
    """(share of the raw profile's flux below the horizon, flux-weighted mean of
    cos(theta from nadir) of the raw profile, the same after the angleScale remap).

    Midpoint rule on a (theta, phi) grid in the luminaire frame, sin-weighted."""
    th = (np.arange(_NT) + 0.5) * (math.pi / _NT)
    ph = (np.arange(_NP) + 0.5) * (2.0 * math.pi / _NP)
    w = np.sin(th)[:, None]
    cos = np.cos(th)[:, None]
    raw = prof.sample(th[:, None], ph[None, :]) * w
    t2 = ies_theta(np.broadcast_to(th[:, None], raw.shape), angle_scale)
    inside = (t2 >= 0.0) & (t2 <= math.pi)
    remap = np.where(inside, prof.sample(np.clip(t2, 0.0, math.pi), ph[None, :]), 0.0) * w
    total, total2 = float(raw.sum()), float(remap.sum())
    if total <= 0.0:
        return 0.0, 0.0, 0.0
    share = float(raw[th < math.pi / 2].sum()) / total
    mean_raw = float((raw * cos).sum()) / total
    mean_remap = float((remap * cos).sum()) / total2 if total2 > 0 else 0.0
    return share, mean_raw, mean_remap


def _asset_values(a: Usd.Attribute) -> list[tuple[float | None, str, str]]:
    """(time, authored path, resolved path) of every authored non-empty asset value."""
    out = []
    for t, v in authored_values(a):
        if isinstance(v, Sdf.AssetPath) and v.path:
            out.append((t, v.path, v.resolvedPath))
        elif isinstance(v, str) and v:
            out.append((t, v, ""))
    return out


def check_ies(prim: Usd.Prim) -> list[Finding]:
    """IesProfile validator body."""
    names = set(prim.GetAuthoredPropertyNames())
    fa = _attr(prim, names, "shaping:ies:file")
    if fa is None:
        return []
    path = str(prim.GetPath())
    out: list[Finding] = []
    sa = _attr(prim, names, "shaping:ies:angleScale")
    values = _asset_values(fa)
    by_file: dict[tuple[str, str], list[float | None]] = defaultdict(list)
    for t, authored, resolved in values:
        by_file[(authored, resolved)].append(t)
    for (authored, resolved), times in by_file.items():
        when = fmt_times(times)
        if not resolved:
            out.append(
                finding(
                    "ies_missing",
                    path,
                    f"{fa.GetName()} '{authored}' does not resolve ({when})",
                )
            )
            continue
        try:
            prof = load_ies_cached(resolved)
        except IesError as exc:
            out.append(finding("ies_malformed", path, f"IES file '{authored}': {exc}"))
            continue
        mx = float(prof.max_candela())
        if not (math.isfinite(mx) and mx > 0.0 and prof.power() > 0.0):
            out.append(
                finding("ies_zero_power", path, f"IES file '{authored}' has zero power ({when})")
            )
            continue
        if sa is not None:
            out.extend(_check_angle_scale(path, fa, sa, authored, resolved, times, prof))
    return out


def _scale_at(sa: Usd.Attribute, t: float | None) -> float:
    v = sa.Get(Usd.TimeCode.Default() if t is None else Usd.TimeCode(t))
    return float(v) if v is not None else 0.0


def _check_angle_scale(
    path: str,
    fa: Usd.Attribute,
    sa: Usd.Attribute,
    authored: str,
    resolved: str,
    file_times: list[float | None],
    prof: IesProfile,
) -> list[Finding]:
    """Pairs (file, angleScale) at every time either is authored."""
    scale_times = [t for t, _ in authored_values(sa)]
    file_t = set(file_times)
    times = set(scale_times) | file_t
    degrees: list[tuple[float | None, float]] = []
    inverted: list[tuple[float | None, float]] = []
    share_cache: dict[float, tuple[float, float, float]] = {}
    for t in times:
        ft = fa.Get(Usd.TimeCode.Default() if t is None else Usd.TimeCode(t))
        if not isinstance(ft, Sdf.AssetPath) or ft.resolvedPath != resolved:
            continue
        s = _scale_at(sa, t)
        if not math.isfinite(s):
            continue
        if abs(s) > limits.VALIDATE_IES_ANGLE_SCALE_MAX:
            degrees.append((t, s))
        elif s < 0.0:
            if s not in share_cache:
                share_cache[s] = _downwardness(prof, s)
            share, before, after = share_cache[s]
            if share >= limits.VALIDATE_IES_DOWNLIGHT_SHARE and after < (
                limits.VALIDATE_IES_DOWNLIGHT_KEEP_MIN * before
            ):
                inverted.append((t, s))
    out: list[Finding] = []
    if inverted:
        _, s0 = max(inverted, key=lambda x: x[1])
        share, before, after = share_cache[s0]
        out.append(
            finding(
                "ies_angle_scale",
                path,
                f"{sa.GetName()} = {s0:g} turns downlight profile '{authored}' ({share:.0%} of "
                f"its flux below the horizon) sideways/up: mean downward cosine {before:.2f} -> "
                f"{after:.2f}; a negative angleScale rescales about the zenith "
                f"({fmt_times(t for t, _ in inverted)})",
            )
        )
    if degrees:
        _, s0 = degrees[0]
        out.append(
            finding(
                "ies_angle_scale",
                path,
                f"{sa.GetName()} = {s0:g} looks like degrees, not a scale factor "
                f"(|angleScale| > {limits.VALIDATE_IES_ANGLE_SCALE_MAX:g}; "
                f"{fmt_times(t for t, _ in degrees)})",
            )
        )
    return out
