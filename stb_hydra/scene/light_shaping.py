"""Light shaping in physical units: UsdLux cone, focus and emission factors over the
light's polar angle (radians from its -Z axis), their solid-angle integrals (what turns
a shaped light's power into its intensity), and IES profiles cached by file and mtime
(``scene/ies.py`` parses them) with their peak and power. Used by the single-light
reader (``scene/lights.py``) and the bulk reader (``scene/lights_bulk.py``).
"""

from __future__ import annotations

import math
import os
from functools import lru_cache

import numpy as np

from . import prims
from .ies import IesProfile, load_ies

# --- IES ------------------------------------------------------------------------------


_ies_cache: dict[tuple[str, float], IesProfile] = {}
_ies_by_path: dict[str, IesProfile] = {}


def load_ies_cached(path: str) -> IesProfile:
    """Load (and cache by path + mtime) an IES profile; raises IesError."""
    try:
        mtime = os.path.getmtime(path)
    except OSError:
        mtime = -1.0
    key = (path, mtime)
    prof = _ies_cache.get(key)
    if prof is None:
        prof = load_ies(path)
        _ies_cache[key] = prof
    _ies_by_path[path] = prof
    return prof


def ies_theta(theta: np.ndarray, angle_scale: float) -> np.ndarray:
    """UsdLux ``shaping:ies:angleScale`` remap of the light-space polar angle
    (radians from -Z). Results outside [0, pi] mean "no emission"."""
    if angle_scale > 0:
        return theta / angle_scale
    if angle_scale < 0:
        return (theta - math.pi) / -angle_scale + math.pi
    return theta


# --- shaping integrals --------------------------------------------------------------------

_NT = 512  # polar quadrature points (midpoint rule, 2D case)
_NGL = 24  # Gauss-Legendre nodes per smooth piece (1D axially symmetric case)
_GL_X, _GL_W = np.polynomial.legendre.leggauss(_NGL)
_NP = 64  # azimuth points for IES / cylinder
_PH = (np.arange(_NP) + 0.5) * (2.0 * math.pi / _NP)
_DPH = 2.0 * math.pi / _NP


def cone_factor(theta: np.ndarray, angle_deg: float, softness: float) -> np.ndarray:
    """UsdLux cone: 1 - smoothstep(start, cutoff, theta); 0 beyond the cutoff."""
    cutoff = math.radians(min(max(angle_deg, 0.0), prims.NO_CONE_ANGLE_DEG))
    s = min(max(softness, 0.0), 1.0)
    start = cutoff * (1.0 - s)
    if cutoff - start > 1e-9:
        t = np.clip((theta - start) / (cutoff - start), 0.0, 1.0)
        f = 1.0 - t * t * (3.0 - 2.0 * t)
    else:
        f = np.ones_like(theta)
    return np.where(theta > cutoff, 0.0, f)


def focus_factor(theta: np.ndarray, focus: float) -> np.ndarray:
    """|cos theta|^focus (focus < 0 ignored)."""
    if focus <= 0.0:
        return np.ones_like(theta)
    return np.abs(np.cos(theta)) ** focus


def emission_factor(emission: int, theta: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Far-field shape about -Z: isotropic, one-sided cosine, or cylinder side."""
    if emission == prims.EMIT_COSINE:
        return np.maximum(np.cos(theta), 0.0)
    if emission == prims.EMIT_CYLINDER:
        # angle to the local X axis: cos(a) = sin(theta) cos(phi)
        c = np.sin(theta) * np.cos(phi)
        return np.sqrt(np.maximum(1.0 - c * c, 0.0))
    return np.ones(np.broadcast(theta, phi).shape)


@lru_cache(maxsize=4096)
def shape_integral(
    emission: int,
    has_cone: bool,
    cone_angle: float,
    softness: float,
    focus: float,
    ies_key: str | None,
    angle_scale: float,
) -> tuple[float, float]:
    """(integral over the sphere of the normalised distribution, its maximum).

    The distribution is emission x cone x focus x IES/IES_max (focusTint taken
    as black: the luminous estimate). Cached: prefab lights share parameters.
    """
    # Integrate only where the cone lets light out: the hard cut-off then falls
    # on the grid's edge and the midpoint rule stays accurate (no 1/N step error).
    tmax = (
        math.radians(min(max(cone_angle, 0.0), prims.NO_CONE_ANGLE_DEG))
        if has_cone
        else prims.NO_CONE_CUTOFF_RAD
    )
    dth = tmax / _NT
    if ies_key is None and emission != prims.EMIT_CYLINDER:
        # Axially symmetric: a 1D integral over theta (x 2 pi), Gauss-Legendre on
        # the pieces between the kinks (cone start, 90 degrees), where f is smooth.
        start = tmax * (1.0 - min(max(softness, 0.0), 1.0)) if has_cone else tmax
        cuts = sorted({0.0, tmax, *(b for b in (start, math.pi / 2) if 0.0 < b < tmax)})
        lo = np.array(cuts[:-1])
        half = (np.array(cuts[1:]) - lo) * 0.5
        t1 = ((lo + half)[:, None] + half[:, None] * _GL_X[None, :]).ravel()
        w1 = (half[:, None] * _GL_W[None, :]).ravel()
        w1 = w1 * np.sin(t1)
        t1 = np.concatenate(([0.0], t1))  # theta = 0 for the peak
        f1 = np.cos(t1) if emission == prims.EMIT_COSINE or focus > 0.0 else None
        if f1 is not None:
            c = f1
            f1 = np.maximum(c, 0.0) if emission == prims.EMIT_COSINE else np.ones_like(c)
            if focus > 0.0:
                f1 = f1 * np.abs(c) ** focus
        if has_cone:
            cf = cone_factor(t1, cone_angle, softness)
            f1 = cf if f1 is None else f1 * cf
        if f1 is None:  # isotropic, no cone, no focus
            return 4.0 * math.pi, 1.0
        return float(np.dot(f1[1:], w1)) * 2.0 * math.pi, float(np.max(f1))
    th = ((np.arange(_NT) + 0.5) * dth)[:, None]
    ph = _PH[None, :]
    f = np.broadcast_to(emission_factor(emission, th, ph), (_NT, _NP))
    if has_cone:
        f = f * cone_factor(th, cone_angle, softness)
    f = f * focus_factor(th, focus)
    if ies_key is not None:
        prof = _ies_cache_lookup(ies_key)
        t = ies_theta(np.broadcast_to(th, f.shape), angle_scale)
        inside = (t >= 0.0) & (t <= math.pi)
        vals = prof.sample(np.clip(t, 0.0, math.pi), np.broadcast_to(ph, f.shape))
        mx = max(float(prof.max_candela()), 1e-30)
        f = f * np.where(inside, vals / mx, 0.0)
    w = np.sin(th) * dth * _DPH
    integral = float(np.sum(f * w))
    return integral, float(np.max(f)) if f.size else 0.0


_ies_stats_cache: dict[tuple[str, int], tuple[float, float]] = {}


def ies_stats(path: str, prof: IesProfile) -> tuple[float, float]:
    """(max candela, power) of a profile, computed once per loaded profile."""
    key = (path, id(prof))
    v = _ies_stats_cache.get(key)
    if v is None:
        v = (float(prof.max_candela()), float(prof.power()))
        _ies_stats_cache[key] = v
    return v


def _ies_cache_lookup(path: str) -> IesProfile:
    """The profile last loaded from ``path`` (loading it if needed)."""
    prof = _ies_by_path.get(path)
    return prof if prof is not None else load_ies_cached(path)
