"""IES LM-63 photometric files (1986, 1991, 1995, 2002, 2019): parser and sampler.

Luminaire frame, shared by every photometric type and by ``sample`` / ``bake_table``:
``-Z`` is the photometric axis pointing at nadir (photometric zero), ``+X`` is the
photometric horizontal (horizontal angle 0: the C0 plane), ``+Y`` the C90 plane
(counter-clockwise from ``+X`` seen from above), ``+Z`` up. A direction given as
``(theta, phi)`` in radians is ``d = (sin t cos p, sin t sin p, -cos t)``: ``theta`` from
nadir in [0, pi] (clamped), ``phi`` from ``+X`` towards ``+Y``, periodic. For a UsdLux
light this is light-local space: the profile's nadir is the light's ``-Z`` axis.

Native angles of the three types in that frame (LM-63-2002 definitions: photometric
zero is (H 0, V 0) for Types B/C and (H 0, V -90) for Type A; horizontal angles run
counter-clockwise for Type C and clockwise for Types A and B):

* Type C (1): V = theta, H = phi (degrees). Planes share the vertical axis.
* Type B (2): the polar axis is the luminaire's horizontal Y axis. V is the rotation
  of the plane about Y, from nadir (0) towards +X (90); H is the latitude within that
  plane, positive towards -Y: ``V = atan2(d.x, -d.z)``, ``H = asin(-d.y)``.
* Type A (3): the polar axis is the vertical Z axis. H is the longitude from +X,
  positive towards -Y; V the latitude above the horizontal plane (-90 = nadir):
  ``H = atan2(-d.y, d.x)``, ``V = asin(d.z)``.

Values are bilinear in (H, V) degrees on the file's (possibly non-uniform) grid after
the symmetry is unfolded. Type C: one horizontal angle = axially symmetric; 0..90 =
quadrants (mirrored about the 0 and 90 planes); 0..180 = bilateral (phi -> 360 - phi);
90..270 = bilateral about the 90-270 plane (phi -> 180 - phi); any other range is
periodic over 360 (a listed 360 duplicates 0, a missing one is interpolated across the
seam). Types A/B: an angle list starting at 0 is mirrored about 0; one horizontal angle
is constant along H. Outside the (unfolded) range the intensity is 0: above 90 for a
Type C 0..90 file, below 90 for 90..180, behind |H| > 90 for Type A, above the
horizon (|V| > 90) for Type B.
Candela values: ``candela = candela_raw * multiplier * ballast_factor``; ``n_lamps`` and
the 2nd number of the ballast line (ballast-lamp factor / file generation type) are
*not* multiplied in. TILT data is recorded, never applied.
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import numpy.typing as npt

from stb_hydra.limits import (
    IES_MAX_ANGLES,
    IES_MAX_CANDELA_VALUES,
    IES_MAX_FILE_BYTES,
    IES_MAX_TILT_PAIRS,
    IES_MIN_ANGLE_STEP_DEG,
    IES_TABLE_PHI,
    IES_TABLE_THETA,
    MAX_INTENSITY_CD,
)

__all__ = ["IesError", "IesProfile", "load_ies", "parse_ies"]

TYPE_C, TYPE_B, TYPE_A = 1, 2, 3

#: Angle comparisons for symmetry classification (degrees).
_CLASSIFY_TOL = 1.0e-3
#: Slack on range ends when sampling (degrees): a query at exactly 180 hits a 180 row.
_RANGE_EPS = 1.0e-7
#: hdEmbree ``PxrIESFile::power`` test: a profile is a hemisphere when its vertical
#: angles span at most 90 degrees plus this fudge (0.1 rad).
_HEMISPHERE_FUDGE_DEG = math.degrees(0.1)

_VERSIONS = {
    1986: "LM-63-1986",
    1991: "LM-63-1991",
    1995: "LM-63-1995",
    2002: "LM-63-2002",
    2019: "LM-63-2019",
}
_LINE_SPLIT = re.compile(r"\r\n|\r|\n")
_TOKEN_SPLIT = re.compile(r"[\s,]+")
_NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")
_KEYWORD = re.compile(r"\s*\[([^\]]*)\]\s*(.*?)\s*")
_TILT = re.compile(r"\s*TILT\s*=\s*(.*?)\s*", re.IGNORECASE)
_VERSION = re.compile(r"\s*IES(?:NA)?\s*:?\s*LM-63-(\d{4}|\d{2})\b", re.IGNORECASE)
_GL_X, _GL_W = np.polynomial.legendre.leggauss(8)


class IesError(ValueError):
    """Unreadable or malformed IES file; the one-line message names the file."""


@dataclass(eq=False)
class IesProfile:
    """One parsed LM-63 profile. Angles in degrees, intensities in candela (cd).

    Treat as immutable: the unfolded sampling grid is cached on first use.
    """

    name: str
    version: str
    keywords: dict[str, str]
    labels: list[str]
    tilt: str
    tilt_geometry: int | None
    tilt_angles: np.ndarray | None
    tilt_factors: np.ndarray | None
    n_lamps: int
    lumens_per_lamp: float
    multiplier: float
    photometric_type: int
    units_type: int
    width: float
    length: float
    height: float
    ballast_factor: float
    file_generation_type: float
    input_watts: float
    vertical_angles: np.ndarray
    horizontal_angles: np.ndarray
    candela_raw: np.ndarray
    warnings: list[str] = field(default_factory=list)

    @property
    def candela(self) -> np.ndarray:
        """(n_horizontal, n_vertical) cd: raw values * multiplier * ballast factor."""
        return self.candela_raw * (self.multiplier * self.ballast_factor)

    @property
    def symmetry(self) -> str:
        """Type C: 'axial' | 'quadrant' | 'bilateral' (0-180) | 'bilateral_90_270' |
        'full' | 'nonstandard'. Types A/B: 'lateral' (H from 0) | 'none'."""
        return _symmetry(self.photometric_type, self.horizontal_angles)

    @property
    def is_hemispherical(self) -> bool:
        """Vertical angles (unfolded) span <= 90 deg (+0.1 rad, as hdEmbree): power / 2pi."""
        v = self._grid.v
        return bool(v[-1] - v[0] <= 90.0 + _HEMISPHERE_FUDGE_DEG)

    @cached_property
    def _grid(self) -> _Grid:
        return _unfold(
            self.photometric_type, self.horizontal_angles, self.vertical_angles, self.candela
        )

    def sample(self, theta: npt.ArrayLike, phi: npt.ArrayLike) -> np.ndarray:
        """Intensity (cd, multiplier and ballast applied) towards ``(theta, phi)``.

        Radians in the luminaire frame of the module docstring (theta from nadir,
        clamped to [0, pi]; phi periodic). Broadcasts like numpy; returns float64.
        """
        t = np.clip(np.asarray(theta, dtype=np.float64), 0.0, math.pi)
        p = np.asarray(phi, dtype=np.float64)
        t, p = np.broadcast_arrays(t, p)
        if self.photometric_type == TYPE_C:
            h, v = np.degrees(p), np.degrees(t)
        else:
            st = np.sin(t)
            dx, dy, dz = st * np.cos(p), st * np.sin(p), -np.cos(t)
            if self.photometric_type == TYPE_B:
                h = np.degrees(np.arcsin(np.clip(-dy, -1.0, 1.0)))
                v = np.degrees(np.arctan2(dx, -dz))
            else:
                h = np.degrees(np.arctan2(-dy, dx))
                v = np.degrees(np.arcsin(np.clip(dz, -1.0, 1.0)))
        return self._grid.eval(h, v)

    def flux(self) -> float:
        """Total luminous flux (lm): integral of the interpolated intensity over the
        sphere, to machine precision for the bilinear interpolant: hat functions times
        the solid-angle Jacobian of the type's angles, 8-point Gauss-Legendre per interval."""
        g = self._grid
        return float(_hat_integrals(g.h, g.h_weight) @ g.cd @ _hat_integrals(g.v, g.v_weight))

    def power(self) -> float:
        """Mean intensity (cd) over the whole sphere, flux / 4pi, by which
        ``shaping:ies:normalize`` divides the profile: the normalised light emits the
        flux of the same light without IES ("shapes the light, preserves its energy"),
        whatever part of the sphere the file covers and whatever symmetry it folds.

        hdEmbree divides a hemispherical profile's flux by 2pi (and integrates only the
        file's own horizontal range, so a quadrant-symmetric file counts a quarter of
        its flux): a hemispherical light then emits half the unshaped light's flux.
        We do not follow it there (issue 33, docs in ``scene/lights.py``)."""
        return self.flux() / (4.0 * math.pi)

    def max_candela(self) -> float:
        """Largest intensity (cd) in the file; interpolation never exceeds it."""
        return float(self.candela.max())

    def bake_table(self, n_theta: int = IES_TABLE_THETA, n_phi: int = IES_TABLE_PHI) -> np.ndarray:
        """float32 (n_theta, n_phi) table in cd: row i is theta = pi*i/(n_theta-1) (both
        ends exact), column j is phi = 2pi*j/n_phi (periodic, no duplicate column)."""
        if n_theta < 2 or n_phi < 1:
            raise ValueError(f"bake_table needs n_theta >= 2, n_phi >= 1; got {n_theta}, {n_phi}")
        theta = np.linspace(0.0, math.pi, n_theta)
        phi = 2.0 * math.pi * np.arange(n_phi) / n_phi
        return self.sample(theta[:, None], phi[None, :]).astype(np.float32)


# --- sampling grid ------------------------------------------------------------------------


@dataclass(frozen=True)
class _Grid:
    """Unfolded profile: cd[i, j] at (h[i], v[j]) degrees, both ascending.

    A periodic axis is closed (last == first + 360, same values at both ends)."""

    h: np.ndarray
    v: np.ndarray
    cd: np.ndarray
    h_periodic: bool
    v_periodic: bool
    h_weight: str  # solid-angle Jacobian factor along the axis: "one" | "sin" | "cos"
    v_weight: str

    def eval(self, h: np.ndarray, v: np.ndarray) -> np.ndarray:
        ih, th, okh = _locate(self.h, h, self.h_periodic)
        iv, tv, okv = _locate(self.v, v, self.v_periodic)
        ih1 = np.minimum(ih + 1, self.h.size - 1)
        iv1 = np.minimum(iv + 1, self.v.size - 1)
        c = self.cd
        lo = (1.0 - tv) * c[ih, iv] + tv * c[ih, iv1]
        hi = (1.0 - tv) * c[ih1, iv] + tv * c[ih1, iv1]
        return np.where(okh & okv, (1.0 - th) * lo + th * hi, 0.0)


def _locate(grid: np.ndarray, x: np.ndarray, periodic: bool):
    """Interval index, fraction in [0, 1] and in-range mask of ``x`` on ``grid``."""
    if periodic:
        x = grid[0] + np.mod(x - grid[0], grid[-1] - grid[0])
    if grid.size == 1:
        zero = np.zeros(x.shape, dtype=np.intp)
        return zero, np.zeros(x.shape), np.abs(x - grid[0]) <= _RANGE_EPS
    i = np.clip(np.searchsorted(grid, x, side="right") - 1, 0, grid.size - 2)
    t = np.clip((x - grid[i]) / (grid[i + 1] - grid[i]), 0.0, 1.0)
    if periodic:
        ok = np.ones(x.shape, dtype=bool)
    else:
        ok = (x >= grid[0] - _RANGE_EPS) & (x <= grid[-1] + _RANGE_EPS)
    return i, t, ok


def _hat_integrals(grid_deg: np.ndarray, weight: str) -> np.ndarray:
    """Integral over the grid range (radians) of each node's hat function times the
    Jacobian factor ``weight``; a single node has zero measure."""
    out = np.zeros(grid_deg.size)
    if grid_deg.size < 2:
        return out
    g = np.radians(grid_deg)
    a, b = g[:-1, None], g[1:, None]
    x = a + (b - a) * (_GL_X + 1.0) * 0.5
    w = (b - a) * 0.5 * _GL_W * {"one": np.ones_like, "sin": np.sin, "cos": np.cos}[weight](x)
    right = (x - a) / (b - a)
    out[:-1] += np.sum(w * (1.0 - right), axis=1)
    out[1:] += np.sum(w * right, axis=1)
    return out


def _near(a: float, b: float) -> bool:
    return abs(a - b) < _CLASSIFY_TOL


def _symmetry(ptype: int, h: np.ndarray) -> str:
    first, last = float(h[0]), float(h[-1])
    if ptype != TYPE_C:
        return "lateral" if h.size > 1 and _near(first, 0.0) else "none"
    if h.size == 1:
        return "axial"
    if _near(first, 0.0) and _near(last, 90.0):
        return "quadrant"
    if _near(first, 0.0) and _near(last, 180.0):
        return "bilateral"
    if _near(first, 90.0) and _near(last, 270.0):
        return "bilateral_90_270"
    if _near(last - first, 360.0):
        return "full"
    return "nonstandard"


def _mirror_tail(a: np.ndarray, c: np.ndarray, pivot: float, axis: int):
    """Append the reflection of ``a`` (without its last node) about ``pivot`` (the last
    node): angles ``2*pivot - a``, values mirrored along ``axis``."""
    a2 = np.concatenate([a, 2.0 * pivot - a[-2::-1]])
    rev = np.flip(np.take(c, np.arange(a.size - 1), axis=axis), axis=axis)
    return a2, np.concatenate([c, rev], axis=axis)


def _mirror_zero(a: np.ndarray, c: np.ndarray, axis: int):
    """Angles starting at 0 -> symmetric about 0: prepend -a (reversed)."""
    if a.size < 2 or not _near(float(a[0]), 0.0):
        return a, c
    a2 = np.concatenate([-a[:0:-1], a])
    head = np.flip(np.take(c, np.arange(1, a.size), axis=axis), axis=axis)
    return a2, np.concatenate([head, c], axis=axis)


def _close_periodic(a: np.ndarray, c: np.ndarray, axis: int):
    """Append first+360 (copy of the first slice) unless the axis already spans 360."""
    if a[-1] - a[0] >= 360.0 - _CLASSIFY_TOL:
        return a, c
    first = np.take(c, [0], axis=axis)
    return np.append(a, a[0] + 360.0), np.concatenate([c, first], axis=axis)


def _unfold(ptype: int, h: np.ndarray, v: np.ndarray, cd: np.ndarray) -> _Grid:
    h = np.asarray(h, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    cd = np.asarray(cd, dtype=np.float64)
    if ptype == TYPE_C:
        sym = _symmetry(ptype, h)
        if sym == "axial":
            h, cd = np.array([0.0, 360.0]), np.concatenate([cd, cd], axis=0)
        elif sym == "quadrant":
            h, cd = _mirror_tail(h, cd, 90.0, 0)
            h, cd = _mirror_tail(h, cd, 180.0, 0)
        elif sym == "bilateral":
            h, cd = _mirror_tail(h, cd, 180.0, 0)
        elif sym == "bilateral_90_270":
            h, cd = _mirror_tail(h, cd, 270.0, 0)  # 90..450: phi -> 180 - phi
        else:
            h, cd = _close_periodic(h, cd, 0)
        return _Grid(h, v, cd, True, False, "one", "sin")
    if h.size == 1:  # one plane: constant across the horizontal axis
        span = (-180.0, 180.0) if ptype == TYPE_A else (-90.0, 90.0)
        h, cd = np.array(span), np.concatenate([cd, cd], axis=0)
    h, cd = _mirror_zero(h, cd, 0)
    v, cd = _mirror_zero(v, cd, 1)
    if ptype == TYPE_A:  # H longitude about Z, V latitude
        return _Grid(h, v, cd, bool(h[-1] - h[0] >= 360.0 - _CLASSIFY_TOL), False, "one", "cos")
    # Type B: H latitude, V longitude about Y
    return _Grid(h, v, cd, False, bool(v[-1] - v[0] >= 360.0 - _CLASSIFY_TOL), "cos", "one")


# --- parser -------------------------------------------------------------------------------


class _Tokens:
    """Numbers after the TILT line, consumed in order; errors name the file and field."""

    def __init__(self, tokens: list[str], name: str) -> None:
        self.tokens, self.pos, self.name = tokens, 0, name

    def error(self, msg: str) -> IesError:
        return IesError(f"{self.name}: {msg}")

    def _value(self, tok: str, what: str) -> float:
        if not _NUMBER.fullmatch(tok):
            raise self.error(f"{what}: {tok[:40]!r} is not a number")
        x = float(tok)
        if not math.isfinite(x):
            raise self.error(f"{what}: {tok[:40]!r} is not finite")
        return x

    def array(self, n: int, what: str) -> np.ndarray:
        toks = self.tokens[self.pos : self.pos + n]
        if len(toks) < n:
            raise self.error(f"truncated: file ends after {len(toks)} of {n} {what}")
        self.pos += n
        return np.array([self._value(t, what) for t in toks], dtype=np.float64)

    def number(self, what: str) -> float:
        return float(self.array(1, what)[0])

    def integer(self, what: str, lo: int | None = None, hi: int | None = None) -> int:
        x = self.number(what)
        if not x.is_integer():
            raise self.error(f"{what} must be an integer, got {x:g}")
        if (lo is not None and x < lo) or (hi is not None and x > hi):
            raise self.error(f"{what} = {x:g} outside [{lo}, {hi}]")
        return int(x)


def _detect_version(line: str) -> tuple[str | None, str | None]:
    """(version, warning) of a first line, or (None, None) for an LM-63-1986 label."""
    s = line.strip().upper()
    if s.startswith("IESNA91"):
        return _VERSIONS[1991], None
    m = _VERSION.match(line)
    if not m:
        return None, None
    year = int(m.group(1))
    if year < 100:
        year += 1900 if year >= 86 else 2000
    if year in _VERSIONS:
        return _VERSIONS[year], None
    known = max((y for y in _VERSIONS if y <= year), default=1986)
    return _VERSIONS[known], f"unknown version {line.strip()[:40]!r} read as {_VERSIONS[known]}"


def _check_increasing(t: _Tokens, a: np.ndarray, what: str) -> None:
    """Strictly increasing by at least ``IES_MIN_ANGLE_STEP_DEG``: a step of 1e-320
    degrees passed ``> 0`` and divided to NaN flux (found by tools/fuzz.py)."""
    step = np.diff(a)
    if a.size > 1 and not np.all(step >= IES_MIN_ANGLE_STEP_DEG):
        k = int(np.argmin(step >= IES_MIN_ANGLE_STEP_DEG))
        raise t.error(
            f"{what} not strictly increasing by >= {IES_MIN_ANGLE_STEP_DEG:g} degrees at "
            f"#{k + 1} ({a[k]:g} -> {a[k + 1]:g})"
        )


def _check_range(t: _Tokens, a: np.ndarray, lo: float, hi: float, what: str) -> None:
    if a.size and (a[0] < lo - _CLASSIFY_TOL or a[-1] > hi + _CLASSIFY_TOL):
        raise t.error(f"{what} {a[0]:g}..{a[-1]:g} outside {lo:g}..{hi:g}")


def parse_ies(data: bytes | str, name: str = "<string>") -> IesProfile:
    """Parse LM-63 text (bytes are decoded as Latin-1). Raises ``IesError`` only."""
    name = str(name).replace("\r", " ").replace("\n", " ")
    try:
        return _parse(data, name)
    except IesError:
        raise
    except (ValueError, TypeError, IndexError, ArithmeticError, MemoryError) as e:
        # Safety net; fuzz tests assert this message never appears.
        raise IesError(f"{name}: internal parser error: {type(e).__name__}: {e}") from e


def _parse(data: bytes | str, name: str) -> IesProfile:
    """Parse LM-63 text: header lines, TILT block, luminaire numbers, angle and candela
    tables; each step checks its own fields and collects non-fatal warnings."""
    lines = _decode_lines(data, name)
    tilt_at = next((i for i, ln in enumerate(lines) if _TILT.fullmatch(ln)), None)
    if tilt_at is None:
        raise IesError(f"{name}: no TILT= line (not an LM-63 file)")
    warnings: list[str] = []
    version, keywords, labels = _parse_header(lines[:tilt_at], warnings)
    tilt_value = _TILT.fullmatch(lines[tilt_at]).group(1)
    if not tilt_value:
        raise IesError(f"{name}: empty TILT= value")
    tilt = tilt_value.upper() if tilt_value.upper() in ("NONE", "INCLUDE") else tilt_value
    t = _Tokens([s for s in _TOKEN_SPLIT.split("\n".join(lines[tilt_at + 1 :])) if s], name)
    tilt_geometry, tilt_angles, tilt_factors = _parse_tilt(t, tilt, warnings)
    lum = _parse_luminaire(t, warnings)
    vertical = t.array(lum.n_v, "vertical angles")
    horizontal = t.array(lum.n_h, "horizontal angles")
    candela_raw = t.array(lum.n_v * lum.n_h, "candela values").reshape(lum.n_h, lum.n_v)
    _check_angles(t, lum.ptype, vertical, horizontal, warnings)
    _check_candela(t, candela_raw, lum.multiplier, lum.ballast)
    if t.pos < len(t.tokens):
        warnings.append(f"{len(t.tokens) - t.pos} extra token(s) after the candela table ignored")

    return IesProfile(
        name=name,
        version=version,
        keywords=keywords,
        labels=labels,
        tilt=tilt,
        tilt_geometry=tilt_geometry,
        tilt_angles=tilt_angles,
        tilt_factors=tilt_factors,
        n_lamps=lum.n_lamps,
        lumens_per_lamp=lum.lumens,
        multiplier=lum.multiplier,
        photometric_type=lum.ptype,
        units_type=lum.units,
        width=lum.width,
        length=lum.length,
        height=lum.height,
        ballast_factor=lum.ballast,
        file_generation_type=lum.generation,
        input_watts=lum.watts,
        vertical_angles=vertical,
        horizontal_angles=horizontal,
        candela_raw=candela_raw,
        warnings=warnings,
    )


def _decode_lines(data: bytes | str, name: str) -> list[str]:
    """Size-checked text (bytes as Latin-1, BOM dropped) split at any line ending."""
    if len(data) > IES_MAX_FILE_BYTES:
        raise IesError(f"{name}: {len(data)} bytes exceeds the {IES_MAX_FILE_BYTES}-byte limit")
    if isinstance(data, (bytes, bytearray, memoryview)):
        text = bytes(data).removeprefix(b"\xef\xbb\xbf").decode("latin-1")
    else:
        text = str(data).removeprefix("\ufeff")
    return _LINE_SPLIT.split(text)


def _parse_header(lines: list[str], warnings: list[str]) -> tuple[str, dict[str, str], list[str]]:
    """(version, keywords, labels) from the lines before TILT=. Repeated keywords and
    ``[MORE]`` continue the previous value on a new line; other lines are labels."""
    header = [ln for ln in lines if ln.strip()]
    version = None
    if header:
        version, warn = _detect_version(header[0])
        if warn:
            warnings.append(warn)
        if version:
            header = header[1:]
    version = version or _VERSIONS[1986]

    keywords: dict[str, str] = {}
    labels: list[str] = []
    last_key: str | None = None
    for ln in header:
        m = _KEYWORD.fullmatch(ln)
        if m is None:
            labels.append(ln.strip())
            if version != _VERSIONS[1986]:
                warnings.append(f"header line without [KEYWORD] kept as label: {ln.strip()[:40]!r}")
            continue
        key, value = m.group(1).strip(), m.group(2)
        if key.upper() == "MORE":
            if last_key is None:
                warnings.append("[MORE] without a preceding keyword stored as MORE")
                last_key = "MORE"
                keywords[last_key] = value
            else:
                keywords[last_key] += "\n" + value
            continue
        keywords[key] = keywords[key] + "\n" + value if key in keywords else value
        last_key = key
    return version, keywords, labels


def _parse_tilt(
    t: _Tokens, tilt: str, warnings: list[str]
) -> tuple[int | None, np.ndarray | None, np.ndarray | None]:
    """(lamp-to-luminaire geometry, angles, factors) of ``TILT=INCLUDE`` data; Nones for
    ``NONE`` or a TILT file name (not read)."""
    if tilt != "INCLUDE":
        if tilt != "NONE":
            warnings.append(f"TILT file {tilt[:60]!r} not read: tilt factors ignored")
        return None, None, None
    geometry = t.integer("TILT lamp-to-luminaire geometry")
    if geometry not in (1, 2, 3):
        warnings.append(f"TILT lamp-to-luminaire geometry {geometry} is not 1, 2 or 3")
    n_tilt = t.integer("TILT pair count", 1, IES_MAX_TILT_PAIRS)
    angles = t.array(n_tilt, "TILT angles")
    factors = t.array(n_tilt, "TILT factors")
    _check_increasing(t, angles, "TILT angles")
    if np.any(factors < 0.0):
        raise t.error("negative TILT multiplying factor")
    return geometry, angles, factors


@dataclass(frozen=True)
class _Luminaire:
    """The 13 numbers between the TILT block and the angle lists."""

    n_lamps: int
    lumens: float
    multiplier: float
    n_v: int
    n_h: int
    ptype: int
    units: int
    width: float
    length: float
    height: float
    ballast: float
    generation: float
    watts: float


def _parse_luminaire(t: _Tokens, warnings: list[str]) -> _Luminaire:
    """Lamp, photometric-type, size and ballast numbers, range-checked."""
    n_lamps = t.integer("number of lamps", 1, 1_000_000)
    lumens = t.number("lumens per lamp")
    multiplier = t.number("candela multiplier")
    n_v = t.integer("number of vertical angles", 1, IES_MAX_ANGLES)
    n_h = t.integer("number of horizontal angles", 1, IES_MAX_ANGLES)
    ptype = t.integer("photometric type", 1, 3)
    units = t.integer("units type")
    width, length, height = (t.number(w) for w in ("width", "length", "height"))
    ballast = t.number("ballast factor")
    generation = t.number("ballast-lamp factor / file generation type")
    watts = t.number("input watts")
    if n_v * n_h > IES_MAX_CANDELA_VALUES:
        raise t.error(f"{n_v} x {n_h} candela values exceed the limit {IES_MAX_CANDELA_VALUES}")
    if units not in (1, 2):
        warnings.append(f"units type {units} is neither 1 (feet) nor 2 (metres)")
    if multiplier < 0.0 or ballast < 0.0:
        raise t.error(f"negative candela multiplier ({multiplier:g}) or ballast ({ballast:g})")
    return _Luminaire(
        n_lamps,
        lumens,
        multiplier,
        n_v,
        n_h,
        ptype,
        units,
        width,
        length,
        height,
        ballast,
        generation,
        watts,
    )


def _check_angles(
    t: _Tokens, ptype: int, vertical: np.ndarray, horizontal: np.ndarray, warnings: list[str]
) -> None:
    """Angle lists strictly increasing and within the photometric type's ranges; warn
    about non-standard (but usable) spans."""
    _check_increasing(t, vertical, "vertical angles")
    _check_increasing(t, horizontal, "horizontal angles")
    if ptype == TYPE_C:
        _check_range(t, vertical, 0.0, 180.0, "Type C vertical angles")
        _check_range(t, horizontal, -360.0, 360.0, "Type C horizontal angles")
        if horizontal[-1] - horizontal[0] > 360.0 + _CLASSIFY_TOL:
            raise t.error("Type C horizontal angles span more than 360 degrees")
        if _symmetry(ptype, horizontal) == "nonstandard":
            warnings.append(
                f"horizontal angles {horizontal[0]:g}..{horizontal[-1]:g} are no "
                "LM-63 symmetry; interpolated periodically"
            )
    else:
        kind = "Type A" if ptype == TYPE_A else "Type B"
        lat, lon = (vertical, horizontal) if ptype == TYPE_A else (horizontal, vertical)
        _check_range(t, lat, -90.0, 90.0, f"{kind} latitude angles")
        _check_range(t, lon, -180.0, 180.0, f"{kind} longitude angles")
        for a, what in ((horizontal, "horizontal"), (vertical, "vertical")):
            standard = _near(a[-1], 90.0) and (_near(a[0], 0.0) or _near(a[0], -90.0))
            if not standard:
                warnings.append(f"{kind} {what} angles {a[0]:g}..{a[-1]:g} are not -90|0..90")
    if vertical.size == 1:
        warnings.append("single vertical angle: the profile is zero almost everywhere")


def _check_candela(t: _Tokens, candela_raw: np.ndarray, multiplier: float, ballast: float) -> None:
    """No negative value; the peak (multiplier and ballast applied) within
    ``MAX_INTENSITY_CD``."""
    if np.any(candela_raw < 0.0):
        raise t.error(f"negative candela value {candela_raw.min():g}")
    peak = float(candela_raw.max()) * multiplier * ballast
    if not peak <= MAX_INTENSITY_CD:
        raise t.error(f"peak intensity {peak:g} cd exceeds {MAX_INTENSITY_CD:g} cd")


def load_ies(path: str | os.PathLike) -> IesProfile:
    """Read and parse an IES file; missing/unreadable files raise ``IesError`` too."""
    name = os.fsdecode(path)
    try:
        with open(path, "rb") as f:
            data = f.read(IES_MAX_FILE_BYTES + 1)
    except OSError as e:
        raise IesError(f"{name}: cannot read file: {e.strerror or e}") from e
    return parse_ies(data, name)
