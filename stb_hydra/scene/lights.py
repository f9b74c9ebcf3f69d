"""UsdLux -> :class:`~stb_hydra.scene.prims.LightPrim` in physical units.

Conventions (STB_SPEC.md "Light units", UsdLux 2025 docs):

* ``L = intensity * 2^exposure * color [* blackbody(T)]`` in nits; blackbody
  RGB is UsdLux's ``BlackbodyTemperatureAsRgb`` divided by its 6500 K value so
  6500 K is exactly white.
* ``normalize`` divides L by the world-space surface area (sphere 4 pi r^2,
  disk pi r^2, rect w h, cylinder 2 pi r l, mesh: its area).
* Far field: sphere I = L pi r^2 (isotropic); disk I0 = L pi r^2 and rect
  I0 = L w h with a one-sided cosine lobe about the -Z axis; cylinder
  I0 = L 2 r l times sin(angle to its X axis); ``treatAsPoint`` keeps the radius.
  Near field (issue 20, shaders/common/area.glsl): sphere, disk, rect and cylinder
  lights are shaded as areas of uniform radiance L (``LightPrim.treat_as_point``
  sphere lights with the point model); the far-field numbers above are their limit.
* ShapingAPI: cone cut-off/softness/focus/focusTint about -Z, IES sampled at the
  light-space polar angle from -Z (nadir) after ``angleScale``; the profile
  value is a factor on L (divided by the profile's mean intensity over the whole
  sphere, flux / 4 pi, when normalised: the light keeps the flux it has without IES,
  also for hemispherical and symmetry-folded files; ``IesProfile.power``).
* DistantLight: ``intensity`` -> illuminance (lux) facing the light:
  ``E = L * pi sin^2(theta_max)`` (theta_max = angle/2), ``E = L`` when the
  angle is 0 or ``normalize`` is on. DomeLight: radiance L (nits) times its
  texture (``scene/dome.py``; ``intensity`` carries L times the texture's
  solid-angle mean); ``normalize`` has no effect on a dome (it has no size).
  RectLight ``inputs:texture:file``: the rect emits L times its texture
  (``scene/rect_texture.py``: first image column on +X, top row on +Y);
  ``intensity`` carries L times the texture's mean.
* Positions/directions/lengths are in the render frame (Y up, metres).

Bad input never raises: the light is disabled and a one-line warning naming the
prim says why.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import lru_cache
from typing import Any

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux

from .. import limits
from ..color import LUMINANCE_REC709
from . import prims
from .ies import IesError, IesProfile
from .light_shaping import (
    ies_stats,
    load_ies_cached,
    shape_integral,
)
from .prims import LightPrim

_LUMA = np.array(LUMINANCE_REC709)

_TYPE_BY_SCHEMA = {
    "SphereLight": prims.SPHERE_LIGHT,
    "DiskLight": prims.DISK_LIGHT,
    "RectLight": prims.RECT_LIGHT,
    "CylinderLight": prims.CYLINDER_LIGHT,
    "DistantLight": prims.DISTANT_LIGHT,
    "DomeLight": prims.DOME_LIGHT,
    "DomeLight_1": prims.DOME_LIGHT,
    "PortalLight": prims.PORTAL_LIGHT,
    "GeometryLight": prims.MESH_LIGHT,
}

#: Light inputs whose pre-21.02 spelling had no "inputs:" prefix.
LEGACY_INPUTS = (
    "intensity",
    "exposure",
    "diffuse",
    "specular",
    "normalize",
    "color",
    "enableColorTemperature",
    "colorTemperature",
    "radius",
    "width",
    "height",
    "length",
    "angle",
    "texture:file",
    "texture:format",
    "shaping:focus",
    "shaping:focusTint",
    "shaping:cone:angle",
    "shaping:cone:softness",
    "shaping:ies:file",
    "shaping:ies:angleScale",
    "shaping:ies:normalize",
    "shadow:enable",
    "shadow:color",
    "shadow:distance",
    "shadow:falloff",
    "shadow:falloffGamma",
)


def light_type_of(prim: Usd.Prim) -> str | None:
    """Hydra light type token for a prim, or None when it is not a light."""
    t = _TYPE_BY_SCHEMA.get(prim.GetTypeName())
    if t is not None:
        return t
    if prim.HasAPI(UsdLux.MeshLightAPI):
        return prims.MESH_LIGHT
    if prim.HasAPI(UsdLux.LightAPI):
        # A third-party light type: treat as a sphere-like point emitter.
        return prims.SPHERE_LIGHT
    return None


#: Colour temperature (K) rendered as exactly white; also UsdLux's colorTemperature fallback.
WHITE_TEMPERATURE_K = 6500.0


@lru_cache(maxsize=512)
def blackbody_rgb(kelvin: float) -> tuple[float, float, float]:
    """Linear Rec.709 RGB of a blackbody, normalised so 6500 K -> (1, 1, 1)."""
    lo, hi = limits.COLOR_TEMPERATURE_RANGE_K
    k = min(max(float(kelvin), lo), hi)
    c = UsdLux.BlackbodyTemperatureAsRgb(k)
    w = UsdLux.BlackbodyTemperatureAsRgb(WHITE_TEMPERATURE_K)
    return (c[0] / w[0], c[1] / w[1], c[2] / w[2])


class LightReadContext:
    """Stage-level state shared by light reads (one per scene index)."""

    def __init__(
        self,
        stage: Usd.Stage,
        render_from_stage: np.ndarray,
        warn: Callable[[str], None],
        warn_once: Callable[[str, str], None],
    ) -> None:
        self.stage = stage
        self.render_from_stage = render_from_stage
        self.warn = warn
        self.warn_once = warn_once
        self.ies_loader: Callable[[str], IesProfile] = load_ies_cached


# --- attribute access ------------------------------------------------------------------


class _Attrs:
    """Authored attribute names of one prim, read once; fallbacks come from the caller.

    Reading only what is authored is several times cheaper than asking for every
    schema attribute, which matters at 10^4-10^5 lights.
    """

    __slots__ = ("_joined", "legacy", "names", "prim", "time")

    def __init__(
        self, prim: Usd.Prim, time: Usd.TimeCode, names: frozenset[str] | None = None
    ) -> None:
        self.prim = prim
        self.names = names if names is not None else frozenset(prim.GetAuthoredPropertyNames())
        self._joined = "\n" + "\n".join(self.names)
        self.time = time
        self.legacy: list[str] = []

    def attr(self, name: str) -> Usd.Attribute | None:
        if name not in self.names:
            return None
        a = self.prim.GetAttribute(name)
        return a if a else None

    def get(self, name: str, default: Any) -> Any:
        """Value of ``name`` at the read time (or its legacy un-namespaced spelling,
        recorded in ``legacy``); ``default`` when neither is authored."""
        if name in self.names:
            a = self.prim.GetAttribute(name)
            v = a.Get(self.time) if a else None
            if v is not None:
                return v
        if name.startswith("inputs:"):
            bare = name[7:]
            if bare in self.names and bare in LEGACY_INPUTS:
                a = self.prim.GetAttribute(bare)
                v = a.Get(self.time) if a else None
                if v is not None:
                    self.legacy.append(bare)
                    return v
        return default

    def any_prefix(self, *prefixes: str) -> bool:
        """True when an authored property name starts with one of ``prefixes``."""
        return any("\n" + p in self._joined for p in prefixes)

    def has(self, name: str) -> bool:
        return name in self.names or (name.startswith("inputs:") and name[7:] in self.names)


def _finite(x: Any) -> bool:
    """True for a finite number or a sequence of finite numbers (pure Python: hot path)."""
    try:
        if isinstance(x, (int, float)):
            return math.isfinite(x)
        # Index, never iterate: iterating a Gf.Vec ends in a (slow) boost IndexError.
        return all(math.isfinite(float(x[i])) for i in range(len(x)))
    except (TypeError, ValueError):
        return False


def _colour(x: Any) -> bool:
    """A finite RGB triple (a Gf vector or a tuple): not a string, not an int array
    (wrong-typed attributes, found by tools/fuzz.py)."""
    return isinstance(x, (Gf.Vec3f, Gf.Vec3d, Gf.Vec3h, tuple)) and len(x) == 3 and _finite(x)


def _number(x: Any) -> float:
    """``x`` as a float; NaN when it is not a number (a wrong-typed attribute)."""
    if isinstance(x, (int, float)):
        return float(x)
    return math.nan


def _vec3(v: Any) -> np.ndarray:
    return np.array([float(v[0]), float(v[1]), float(v[2])], dtype=np.float64)


def _row_norm(m: np.ndarray, i: int) -> float:
    return math.hypot(float(m[i, 0]), float(m[i, 1]), float(m[i, 2]))


# --- the reader ------------------------------------------------------------------------


def read_light(
    prim: Usd.Prim,
    ctx: LightReadContext,
    time: Usd.TimeCode,
    world: np.ndarray,
    visible: bool = True,
    path: str | None = None,
    names: frozenset[str] | None = None,
) -> LightPrim:
    """Read one UsdLux light. ``world`` is the light's local-to-render matrix
    (row-vector convention, metres); ``names``, when known, the prim's authored
    property names. Never raises for bad data."""
    ltype = light_type_of(prim) or prims.SPHERE_LIGHT
    lp = LightPrim(path=path or str(prim.GetPath()), type=ltype)
    try:
        _read_light_into(lp, prim, ctx, time, world, visible, names)
    except Exception as exc:  # noqa: BLE001 - bad input must never crash
        lp.enabled = lp.valid = False
        _warn(lp, ctx, f"could not be read ({type(exc).__name__}: {exc}); light disabled")
    return lp


def _warn(lp: LightPrim, ctx: LightReadContext, msg: str) -> None:
    text = " ".join(f"light <{lp.path}>: {msg}".split())  # one line, whatever the value
    lp.warnings.append(text)
    ctx.warn(text)


_DOWN = np.array([0.0, -1.0, 0.0])
_XAXIS = np.array([1.0, 0.0, 0.0])


def set_transform(lp: LightPrim, world: np.ndarray) -> None:
    """Position, axes and world scale from a local-to-render matrix."""
    m = np.asarray(world, dtype=np.float64)
    lp.transform = m
    r = m.tolist()  # scalar maths in Python floats: several times cheaper than numpy here
    lp.position = np.array(r[3][:3])
    n0 = math.hypot(*r[0][:3])
    n1 = math.hypot(*r[1][:3])
    n2 = math.hypot(*r[2][:3])
    if n2 > 1e-12 and math.isfinite(n2):
        lp.direction = np.array([-r[2][0] / n2, -r[2][1] / n2, -r[2][2] / n2])
    else:
        lp.direction = _DOWN.copy()
    if n0 > 1e-12 and math.isfinite(n0):
        lp.tangent = np.array([v / n0 for v in r[0][:3]])
    else:
        lp.tangent = _XAXIS.copy()
    s = (n0 + n1 + n2) / 3.0
    lp.world_scale = s if math.isfinite(s) and s > 0 else 1.0


def _read_light_into(
    lp: LightPrim,
    prim: Usd.Prim,
    ctx: LightReadContext,
    time: Usd.TimeCode,
    world: np.ndarray,
    visible: bool,
    names: frozenset[str] | None = None,
) -> None:
    """Fill ``lp`` from ``prim``, one group of inputs per step (in warning order).

    A step that finds bad input warns and returns False; the light then ends up
    invalid and disabled (``valid``/``enabled``), but every step still runs so the
    user sees every problem at once.
    """
    a = _Attrs(prim, time, names)
    set_transform(lp, world)
    if not float(np.abs(world).sum()) <= limits.MAX_COORDINATE_M:  # one reduction: hot path
        lp.enabled = False
        lp.flux, lp.intensity, lp.peak_intensity = 0.0, np.zeros(3), 0.0
        _warn(
            lp,
            ctx,
            f"transform not finite or beyond {limits.MAX_COORDINATE_M:.0e} m; light disabled",
        )
        return
    radiance, normalize, ok = _read_radiance(lp, a, ctx)
    size_ok = _read_size(lp, a, ctx, world)
    ok &= size_ok
    proj, area = _emission_and_area(lp, prim, ctx, world)
    if normalize and lp.type in prims.LOCAL_LIGHT_TYPES:
        radiance = _normalize_by_area(lp, ctx, radiance, area)
    elif size_ok and proj <= 0.0 and lp.type in prims.LOCAL_LIGHT_TYPES:
        _warn(lp, ctx, f"zero-area {lp.type} (size {_size_text(lp)}) emits nothing")
    ok &= _read_shaping(lp, prim, a, ctx)
    ok &= _set_intensity(lp, prim, a, ctx, radiance, proj, normalize)
    _read_shadows(lp, a, ctx)
    _finish_photometry(lp, a)
    if a.legacy:
        legacy = ", ".join(sorted(set(a.legacy)))
        _warn(lp, ctx, f"legacy un-namespaced attributes ({legacy}); use 'inputs:<name>'")
    ok &= _check_peak_intensity(lp, ctx)
    lp.valid = bool(ok)
    lp.enabled = bool(ok and visible)
    if not ok:  # a rejected light emits nothing (and 1e38 cd must not overflow float32)
        lp.flux, lp.intensity, lp.peak_intensity = 0.0, np.zeros(3), 0.0


def _size_text(lp: LightPrim) -> str:
    if lp.type == prims.RECT_LIGHT:
        return f"{lp.width:g} x {lp.height:g} m"
    if lp.type == prims.CYLINDER_LIGHT:
        return f"radius {lp.radius:g} m, length {lp.length:g} m"
    if lp.type == prims.MESH_LIGHT:
        return "mesh area 0"
    return f"radius {lp.radius:g} m"


# --- reader steps -------------------------------------------------------------------------


def _read_radiance(
    lp: LightPrim, a: _Attrs, ctx: LightReadContext
) -> tuple[np.ndarray, bool, bool]:
    """Radiance ``L = intensity * 2^exposure * colour [* blackbody(T)]`` (nits, RGB),
    ``inputs:normalize`` and ok; also reads the diffuse/specular multipliers.

    Bad intensity, exposure, colour or multipliers make L zero (and ok False)."""
    intensity = a.get("inputs:intensity", 50000.0 if lp.type == prims.DISTANT_LIGHT else 1.0)
    exposure = a.get("inputs:exposure", 0.0)
    color = a.get("inputs:color", (1.0, 1.0, 1.0))
    normalize = bool(a.get("inputs:normalize", False))
    lp.diffuse = _number(a.get("inputs:diffuse", 1.0))
    lp.specular = _number(a.get("inputs:specular", 1.0))
    ok = _check_emission_inputs(lp, ctx, intensity, exposure, color)
    rgb = _light_rgb(lp, a, ctx, color, ok)
    scalar = float(intensity) * 2.0 ** float(exposure) if ok else 0.0
    return scalar * rgb, normalize, ok


def _check_emission_inputs(
    lp: LightPrim, ctx: LightReadContext, intensity: Any, exposure: Any, color: Any
) -> bool:
    """Warn about each unusable emission input; True when all are usable."""
    ok = True
    if not _finite(intensity) or float(intensity) < 0:
        _warn(lp, ctx, f"intensity {intensity} is not a finite non-negative number; light disabled")
        ok = False
    if not _finite(exposure) or abs(exposure) > limits.MAX_ABS_EXPOSURE:
        _warn(
            lp,
            ctx,
            f"exposure {exposure} outside +-{limits.MAX_ABS_EXPOSURE:g} stops; light disabled",
        )
        ok = False
    if not _colour(color):
        _warn(lp, ctx, f"inputs:color {color} is not a finite colour (3 numbers); light disabled")
        ok = False
    for name, val in (("diffuse", lp.diffuse), ("specular", lp.specular)):
        if not math.isfinite(val):
            _warn(lp, ctx, f"inputs:{name} {val} is not a finite number; light disabled")
            ok = False
    return ok


def _light_rgb(lp: LightPrim, a: _Attrs, ctx: LightReadContext, color: Any, ok: bool) -> np.ndarray:
    """Linear RGB factor: ``inputs:color`` (negatives clamped) times the blackbody colour
    when ``enableColorTemperature`` is on; zero for a non-finite colour."""
    rgb = _vec3(color) if _colour(color) else np.zeros(3)
    if ok and min(float(color[0]), float(color[1]), float(color[2])) < 0:
        _warn(lp, ctx, f"negative colour {tuple(rgb)} clamped to 0")
        rgb = np.maximum(rgb, 0.0)
    if a.get("inputs:enableColorTemperature", False):
        t = a.get("inputs:colorTemperature", WHITE_TEMPERATURE_K)
        if _finite(t):
            rgb = rgb * np.array(blackbody_rgb(float(t)))
        else:
            _warn(lp, ctx, f"colorTemperature {t} is not finite; ignored")
    return rgb


def _read_size(lp: LightPrim, a: _Attrs, ctx: LightReadContext, world: np.ndarray) -> bool:
    """Radius / width x height / length in metres (world scale applied); False (size 0)
    for a negative or non-finite one."""
    ok = True
    t = lp.type
    if t in (prims.SPHERE_LIGHT, prims.DISK_LIGHT, prims.CYLINDER_LIGHT):
        r = a.get("inputs:radius", 0.5)
        if not _finite(r) or r < 0:
            _warn(lp, ctx, f"radius {r} is negative or not finite; light disabled")
            ok, r = False, 0.0
        lp.radius = float(r) * lp.world_scale
    if t == prims.RECT_LIGHT:
        w, h = a.get("inputs:width", 1.0), a.get("inputs:height", 1.0)
        if not (_finite(w) and _finite(h)) or w < 0 or h < 0:
            _warn(lp, ctx, f"width/height {w}x{h} negative or not finite; light disabled")
            ok, w, h = False, 0.0, 0.0
        sx, sy = _row_norm(world, 0), _row_norm(world, 1)
        lp.width, lp.height = float(w) * sx, float(h) * sy
    if t == prims.CYLINDER_LIGHT:
        ln = a.get("inputs:length", 1.0)
        if not _finite(ln) or ln < 0:
            _warn(lp, ctx, f"length {ln} negative or not finite; light disabled")
            ok, ln = False, 0.0
        lp.length = float(ln) * _row_norm(world, 0)
    return ok


def _emission_and_area(
    lp: LightPrim, prim: Usd.Prim, ctx: LightReadContext, world: np.ndarray
) -> tuple[float, float]:
    """Set the far-field emission model; return (projected area along the axis, surface
    area), m^2. Mesh lights move to their mesh's centre; approximations warn once."""
    t = lp.type
    area = 1.0
    if t == prims.SPHERE_LIGHT:
        lp.treat_as_point = bool(prim.GetAttribute("treatAsPoint").Get() or False)
        lp.emission = prims.EMIT_ISOTROPIC
        proj = math.pi * lp.radius**2
        area = 4.0 * math.pi * lp.radius**2
    elif t == prims.DISK_LIGHT:
        lp.emission = prims.EMIT_COSINE
        proj = area = math.pi * lp.radius**2
    elif t == prims.RECT_LIGHT:
        lp.emission = prims.EMIT_COSINE
        proj = area = lp.width * lp.height
    elif t == prims.CYLINDER_LIGHT:
        lp.emission = prims.EMIT_CYLINDER
        proj = 2.0 * lp.radius * lp.length
        area = 2.0 * math.pi * lp.radius * lp.length
    elif t == prims.MESH_LIGHT:
        lp.emission = prims.EMIT_ISOTROPIC
        area = _mesh_area(prim, world)
        proj = area / 4.0  # mean projected area of a closed convex emitter
        ctx.warn_once(
            "meshlight",
            f"light <{lp.path}>: mesh lights are approximated by an isotropic point "
            "emitter at the mesh centre (one warning per stage)",
        )
        c = _mesh_center(prim, world)
        if c is not None:
            lp.position = c
    else:
        proj = 1.0
    return proj, area


def _normalize_by_area(
    lp: LightPrim, ctx: LightReadContext, radiance: np.ndarray, area: float
) -> np.ndarray:
    """``inputs:normalize`` on a local light: radiance divided by the surface area."""
    if area > 0:
        return radiance / area
    _warn(lp, ctx, "normalize on a zero-area light; emits nothing")
    return radiance * 0.0


def _read_shaping(lp: LightPrim, prim: Usd.Prim, a: _Attrs, ctx: LightReadContext) -> bool:
    """ShapingAPI of a local light: cone, focus, focus tint and IES profile. False for a
    cone angle outside [0, 180] degrees."""
    has_shaping = (
        a.any_prefix("inputs:shaping:", "shaping:") or "ShapingAPI" in prim.GetAppliedSchemas()
    )
    if not has_shaping or lp.type not in prims.LOCAL_LIGHT_TYPES:
        return True
    ok = True
    ang = a.get("inputs:shaping:cone:angle", 90.0)
    soft = a.get("inputs:shaping:cone:softness", 0.0)
    focus = a.get("inputs:shaping:focus", 0.0)
    tint = a.get("inputs:shaping:focusTint", (0.0, 0.0, 0.0))
    if not _finite(ang) or ang < 0 or ang > prims.NO_CONE_ANGLE_DEG:
        _warn(lp, ctx, f"cone angle {ang} outside [0, 180] degrees; light disabled")
        ok, ang = False, prims.NO_CONE_ANGLE_DEG
    if not _finite(soft):
        _warn(lp, ctx, f"cone softness {soft} is not finite; using 0")
        soft = 0.0
    if not _finite(focus):
        _warn(lp, ctx, f"focus {focus} is not finite; using 0")
        focus = 0.0
    lp.has_cone = float(ang) < prims.NO_CONE_ANGLE_DEG
    lp.cone_angle = float(ang)
    lp.cone_softness = float(min(max(soft, 0.0), 1.0))
    lp.focus = float(max(focus, 0.0))
    if not _colour(tint):
        _warn(lp, ctx, f"inputs:shaping:focusTint {tint} is not a finite colour; using black")
    lp.focus_tint = _vec3(tint) if _colour(tint) else np.zeros(3)
    _read_ies(lp, a, ctx)
    if lp.ies_file is not None and lp.has_cone:
        # STB_SPEC: the cone does not clip the IES profile (Arnold test_1316: IES wins).
        lp.has_cone = False
    return ok


def _set_intensity(
    lp: LightPrim,
    prim: Usd.Prim,
    a: _Attrs,
    ctx: LightReadContext,
    radiance: np.ndarray,
    proj: float,
    normalize: bool,
) -> bool:
    """``lp.intensity`` by light kind: cd along the axis (local, before IES), lux
    (distant), nits (dome). False for an unsupported kind (PortalLight)."""
    lp.intensity = radiance * proj
    t = lp.type
    if t == prims.DISTANT_LIGHT:
        lp.intensity = radiance * _read_distant_angle(lp, a, ctx, normalize)
    elif t == prims.RECT_LIGHT and a.has("inputs:texture:file"):
        lp.intensity = lp.intensity * _rect_texture_mean(lp, a, ctx)
    elif t == prims.DOME_LIGHT:
        lp.dome_scale = radiance
        lp.intensity = radiance * _dome_texture_average(lp, a, ctx)
    elif t == prims.PORTAL_LIGHT:
        ctx.warn_once("portal", f"light <{lp.path}>: PortalLight is not supported; ignored")
        return False
    return True


def _read_distant_angle(lp: LightPrim, a: _Attrs, ctx: LightReadContext, normalize: bool) -> float:
    """Set ``lp.angle`` (degrees); return the radiance -> illuminance factor
    ``pi sin^2(theta_max)`` (1 for a zero angle; divided by the disc's solid-angle
    measure when normalised)."""
    ang = a.get("inputs:angle", 0.53)
    if not _finite(ang) or ang < 0:
        _warn(lp, ctx, f"angle {ang} negative or not finite; using 0")
        ang = 0.0
    lp.angle = float(min(ang, 360.0))
    tmax = min(math.radians(lp.angle) / 2.0, math.pi)
    if tmax <= 0.0:
        size = 1.0
    elif tmax <= math.pi / 2:
        size = math.sin(tmax) ** 2 * math.pi
    else:
        size = (2.0 - math.sin(tmax) ** 2) * math.pi
    received = math.pi * math.sin(min(tmax, math.pi / 2)) ** 2 if tmax > 0 else 1.0
    return received / size if normalize else received


def _read_shadows(lp: LightPrim, a: _Attrs, ctx: LightReadContext) -> None:
    """ShadowAPI inputs (lengths in metres) and ``stb:shadow:update``; fallbacks unless
    something is authored (the common case)."""
    s = lp.world_scale
    if a.any_prefix("inputs:shadow:", "shadow:"):
        lp.shadow_enable = bool(a.get("inputs:shadow:enable", True))
        sc = a.get("inputs:shadow:color", (0.0, 0.0, 0.0))
        sd = a.get("inputs:shadow:distance", -1.0)
        sf = a.get("inputs:shadow:falloff", -1.0)
        sg = a.get("inputs:shadow:falloffGamma", 1.0)
    else:
        lp.shadow_enable, sc, sd, sf, sg = True, (0.0, 0.0, 0.0), -1.0, -1.0, 1.0
    if _colour(sc):
        lp.shadow_color = np.array([min(max(float(sc[i]), 0.0), 1.0) for i in range(3)])
    else:
        lp.shadow_color = np.zeros(3)
    lp.shadow_distance = float(sd) * s if _finite(sd) and sd > 0 else -1.0
    lp.shadow_falloff = float(sf) * s if _finite(sf) and sf > 0 else -1.0
    if lp.shadow_distance > 0 and lp.shadow_falloff > lp.shadow_distance:
        lp.shadow_falloff = lp.shadow_distance
    lp.shadow_falloff_gamma = float(sg) if _finite(sg) and sg > 0 else 1.0
    if not _colour(sc):  # an int[] or a string is not a colour (found by tools/fuzz.py)
        _warn(lp, ctx, f"inputs:shadow:color {sc} is not a finite colour; using black")
    for name, v in (("distance", sd), ("falloff", sf), ("falloffGamma", sg)):
        if not _finite(v):  # non-finite or not a number (found by tools/fuzz.py)
            _warn(lp, ctx, f"inputs:shadow:{name} {v} is not a finite number; ignored")
    upd = a.get("stb:shadow:update", prims.SHADOW_STATIC)
    if upd not in (prims.SHADOW_STATIC, prims.SHADOW_DYNAMIC):
        _warn(lp, ctx, f"stb:shadow:update '{upd}' is not static|dynamic; using static")
        upd = prims.SHADOW_STATIC
    lp.shadow_update = str(upd)
    # stb:mobility / stb:baked (issue 17, `stb bake`).
    mob = a.get("stb:mobility", prims.MOBILITY_DYNAMIC)
    if mob not in (prims.MOBILITY_STATIC, prims.MOBILITY_DYNAMIC):
        _warn(lp, ctx, f"stb:mobility '{mob}' is not static|dynamic; using dynamic")
        mob = prims.MOBILITY_DYNAMIC
    lp.mobility = str(mob)
    lp.baked = bool(a.get("stb:baked", False)) and lp.mobility == prims.MOBILITY_STATIC


def _check_peak_intensity(lp: LightPrim, ctx: LightReadContext) -> bool:
    """False (with a warning) when the intensity overflowed or a local light's peak
    exceeds ``limits.MAX_INTENSITY_CD``."""
    imax = max(float(lp.intensity[0]), float(lp.intensity[1]), float(lp.intensity[2]))
    if not (math.isfinite(imax) and imax >= 0):
        _warn(lp, ctx, "intensity overflowed to a non-finite value; light disabled")
        return False
    if lp.type in prims.LOCAL_LIGHT_TYPES and imax * lp.ies_scale > limits.MAX_INTENSITY_CD:
        _warn(
            lp,
            ctx,
            f"peak intensity {imax * lp.ies_scale:.3g} cd exceeds "
            f"{limits.MAX_INTENSITY_CD:.0e} cd; light disabled",
        )
        return False
    return True


def _read_ies(lp: LightPrim, a: _Attrs, ctx: LightReadContext) -> None:
    asset = a.get("inputs:shaping:ies:file", None)
    lp.ies_angle_scale = float(a.get("inputs:shaping:ies:angleScale", 0.0))
    if not math.isfinite(lp.ies_angle_scale):
        _warn(lp, ctx, "ies:angleScale is not finite; using 0")
        lp.ies_angle_scale = 0.0
    lp.ies_normalize = bool(a.get("inputs:shaping:ies:normalize", False))
    if asset is None:
        return
    authored = asset.path if isinstance(asset, Sdf.AssetPath) else str(asset)
    if not authored:
        return
    lp.ies_asset = authored
    resolved = asset.resolvedPath if isinstance(asset, Sdf.AssetPath) else ""
    if not resolved:
        _warn(lp, ctx, f"IES file '{authored}' not found; rendering without a profile")
        return
    try:
        prof = ctx.ies_loader(resolved)
    except IesError as exc:
        _warn(lp, ctx, f"IES file unusable ({exc}); rendering without a profile")
        return
    mx, power = ies_stats(resolved, prof)
    if not (math.isfinite(mx) and mx > 0):
        _warn(lp, ctx, f"IES file '{authored}' has zero power; rendering without a profile")
        return
    lp.ies_file = resolved
    lp.ies_power = power
    # candela = intensity * ies_scale * table/table_max
    lp.ies_scale = mx / power if lp.ies_normalize else mx


def influence_range(peak_cd: float | np.ndarray, exposure_scale: float = 1.0):
    """Automatic influence radius (m) of a light of peak intensity ``peak_cd``: where
    its illuminance, times the camera's linear ``exposure_scale``, falls to
    ``limits.LIGHT_CUTOFF_LUX`` -- so a dim scene shot with a long exposure keeps the
    same lights in range as a bright one (the display image does not depend on the
    unit scale). Clamped to [MIN_LIGHT_RANGE_M, MAX_LIGHT_RANGE_M]; vectorised."""
    e = np.maximum(np.asarray(peak_cd, dtype=np.float64), 0.0) * float(exposure_scale)
    r = np.clip(
        np.sqrt(e / limits.LIGHT_CUTOFF_LUX), limits.MIN_LIGHT_RANGE_M, limits.MAX_LIGHT_RANGE_M
    )
    return float(r) if r.ndim == 0 else r


def _finish_photometry(lp: LightPrim, a: _Attrs) -> None:
    """Luminous flux estimate and influence radius (``stb:range`` when authored)."""
    iy = float(_LUMA @ lp.intensity)
    if lp.type in prims.LOCAL_LIGHT_TYPES:
        integ, peak = shape_integral(
            lp.emission,
            lp.has_cone,
            lp.cone_angle,
            lp.cone_softness,
            lp.focus,
            lp.ies_file,
            lp.ies_angle_scale,
        )
        lp.flux = iy * lp.ies_scale * integ
        lp.peak_intensity = max(iy * lp.ies_scale * peak, 0.0)
        r_auto = influence_range(lp.peak_intensity)
        rng = a.get("stb:range", -1.0)
        if _finite(rng) and rng > 0:
            lp.range = float(rng) * lp.world_scale
            lp.range_authored = True
        else:
            lp.range = r_auto
    else:
        lp.flux = 0.0
        lp.range = math.inf


def _mesh_area(prim: Usd.Prim, world: np.ndarray) -> float:
    from .geometry import read_mesh_geometry

    g = read_mesh_geometry(prim, Usd.TimeCode.Default())
    if g is None:
        return 0.0
    p = (np.c_[g.points, np.ones(len(g.points))] @ world)[:, :3]
    tri = p[g.indices.astype(np.int64)]
    return float(
        0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1).sum()
    )


def _mesh_center(prim: Usd.Prim, world: np.ndarray) -> np.ndarray | None:
    from .geometry import read_mesh_geometry

    g = read_mesh_geometry(prim, Usd.TimeCode.Default())
    if g is None or len(g.points) == 0:
        return None
    c = g.points.astype(np.float64).mean(axis=0)
    return (np.r_[c, 1.0] @ world)[:3]


def _dome_texture_average(lp: LightPrim, a: _Attrs, ctx: LightReadContext) -> np.ndarray:
    """Read a dome's texture into ``lp.dome_map`` (``scene/dome.py``: every UsdLux
    format resampled into a render-frame lat-long map, ``poleAxis`` / the stage's up
    axis and the light's rotation folded in) and return its solid-angle mean RGB (1
    without a texture; a missing or unreadable file warns once and the dome stays
    uniform white). Also reads ``visibleInPrimaryRay`` (camera visibility)."""
    from . import dome

    lp.camera_visible = bool(a.get("visibleInPrimaryRay", True))
    asset, resolved = _light_texture(lp, a, ctx, "dome", "using a uniform white dome")
    if not resolved:
        return np.ones(3)
    fmt = str(a.get("inputs:texture:format", "automatic"))
    if fmt not in dome.FORMATS:
        _warn(lp, ctx, f"texture:format '{fmt}' unknown; reading it as latlong")
        fmt = "latlong"
    pole = "Y"
    if a.prim.GetTypeName() == "DomeLight_1":
        pole = str(a.get("poleAxis", "scene"))
        if pole not in dome.POLE_AXES:
            _warn(lp, ctx, f"poleAxis '{pole}' is not scene|Y|Z; using scene")
            pole = "scene"
    up_z = UsdGeom.GetStageUpAxis(ctx.stage) == UsdGeom.Tokens.z
    rot = dome.dome_rotation(lp.transform, pole, up_z)
    attr = a.attr("inputs:texture:file") or a.attr("texture:file")
    space = str(attr.GetColorSpace() or "") if attr is not None else ""
    try:
        lp.dome_map = dome.load_dome_map(resolved, fmt, rot, space)
    except Exception as exc:  # noqa: BLE001 - bad input must never crash
        _warn(lp, ctx, f"dome texture '{asset.path}' unreadable ({exc}); using white")
        return np.ones(3)
    return np.asarray(lp.dome_map.mean, dtype=np.float64)


def _light_texture(
    lp: LightPrim, a: _Attrs, ctx: LightReadContext, what: str, fallback: str
) -> tuple[Any, str]:
    """(asset, resolved path) of a light's ``inputs:texture:file`` ("" when none is
    authored or it does not resolve: the latter warns, naming ``what`` and ``fallback``);
    records the resolved path on ``lp.texture_file``."""
    asset = a.get("inputs:texture:file", None)
    if asset is None or not getattr(asset, "path", ""):
        return asset, ""
    resolved = str(asset.resolvedPath or "")
    lp.texture_file = resolved or None
    if not resolved:
        _warn(lp, ctx, f"{what} texture '{asset.path}' not found; {fallback}")
    return asset, resolved


def _rect_texture_mean(lp: LightPrim, a: _Attrs, ctx: LightReadContext) -> np.ndarray:
    """Mean RGB of a RectLight's ``inputs:texture:file`` (decoded like material
    textures, ``scene/rect_texture.py``), recorded on ``lp.rect_texture`` so the rect
    emits the texture itself (``lp.intensity`` keeps the mean: the single colour); 1
    without a usable texture (a missing or unreadable one warns once: uniform white).
    Also reads ``visibleInPrimaryRay`` (the camera sees the textured face)."""
    from .rect_texture import load_rect_texture

    lp.camera_visible = bool(a.get("visibleInPrimaryRay", True))
    asset, resolved = _light_texture(lp, a, ctx, "rect", "emitting uniform white")
    if not resolved:
        return np.ones(3)
    attr = a.attr("inputs:texture:file") or a.attr("texture:file")
    space = str(attr.GetColorSpace() or "") if attr is not None else ""
    try:
        tex = load_rect_texture(resolved, space)
    except Exception as exc:  # noqa: BLE001 - bad input must never crash
        _warn(lp, ctx, f"rect texture '{asset.path}' unreadable ({exc}); emitting white")
        return np.ones(3)
    lp.rect_texture = (resolved, space)
    return np.asarray(tex.mean, dtype=np.float64)


def area_half_extent(lp: LightPrim) -> float:
    """Half extent (m) of a light shaded as an area (issue 20, shaders/common/area.glsl):
    radius of a sphere or disk, half the diagonal of a rect, the larger of a cylinder's
    half length and radius; 0 for the point model (``treatAsPoint``, mesh, distant and
    dome lights)."""
    t = lp.type
    if t == prims.SPHERE_LIGHT:
        return 0.0 if lp.treat_as_point else float(lp.radius)
    if t == prims.DISK_LIGHT:
        return float(lp.radius)
    if t == prims.RECT_LIGHT:
        return 0.5 * math.hypot(lp.width, lp.height)
    if t == prims.CYLINDER_LIGHT:
        return max(0.5 * lp.length, float(lp.radius))
    return 0.0
