"""Many UsdLux lights read at once: values gathered into arrays, maths in numpy.

:func:`read_lights` gives the same :class:`~stb_hydra.scene.prims.LightPrim` records
as :func:`stb_hydra.scene.lights.read_light` called light by light (same units and
conventions: see that module), at a fraction of the Python cost: each authored input
is fetched once per light (one ``GetAttribute().Get()``), then every check, unit
conversion and photometric integral runs on whole columns (the shaping integral once
per distinct cone / focus / IES set-up). A light the bulk path does not model --
mesh, distant, dome and portal lights, third-party light types, legacy un-namespaced
inputs, a textured RectLight, and any light with an input that would warn (a wrong
type, a non-finite or out-of-range value, an unresolvable or unusable IES file, a zero
area, an overflowing intensity) -- is read by ``read_light``, so its warnings and
fallbacks stay exactly those of the single-light reader.

Positions / directions are in the render frame (Y up, metres); intensities in cd
along the axis; ranges in metres at camera exposure scale 1.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from pxr import Gf, Sdf, Usd

from .. import limits
from . import prims
from .ies import IesError
from .light_shaping import ies_stats, shape_integral
from .lights import (
    _LUMA,
    LEGACY_INPUTS,
    LightReadContext,
    blackbody_rgb,
    influence_range,
    read_light,
)
from .prims import LightPrim

#: UsdLux schema type name -> (Hydra light type, far-field emission code).
_BULK_TYPES = {
    "SphereLight": (prims.SPHERE_LIGHT, prims.EMIT_ISOTROPIC),
    "DiskLight": (prims.DISK_LIGHT, prims.EMIT_COSINE),
    "RectLight": (prims.RECT_LIGHT, prims.EMIT_COSINE),
    "CylinderLight": (prims.CYLINDER_LIGHT, prims.EMIT_CYLINDER),
}

_LEGACY = frozenset(LEGACY_INPUTS)
_COLOUR_TYPES = (Gf.Vec3f, Gf.Vec3d, Gf.Vec3h, tuple)

#: The inputs the bulk path reads (``read_light``'s, for the four analytic types).
_INPUTS = frozenset(
    (
        "inputs:intensity",
        "inputs:exposure",
        "inputs:color",
        "inputs:normalize",
        "inputs:diffuse",
        "inputs:specular",
        "inputs:enableColorTemperature",
        "inputs:colorTemperature",
        "inputs:radius",
        "inputs:width",
        "inputs:height",
        "inputs:length",
        "inputs:shaping:cone:angle",
        "inputs:shaping:cone:softness",
        "inputs:shaping:focus",
        "inputs:shaping:focusTint",
        "inputs:shaping:ies:file",
        "inputs:shaping:ies:angleScale",
        "inputs:shaping:ies:normalize",
        "inputs:shadow:enable",
        "inputs:shadow:color",
        "inputs:shadow:distance",
        "inputs:shadow:falloff",
        "inputs:shadow:falloffGamma",
        "stb:shadow:update",
        "stb:mobility",
        "stb:baked",
        "stb:range",
    )
)

#: Below this many lights the single-light reader is as fast.
MIN_BULK_LIGHTS = 8


@dataclass(slots=True)
class LightItem:
    """One light to read: its prim, render path, local-to-render matrix (row vectors,
    metres), visibility and (when known) authored property names."""

    prim: Usd.Prim
    path: str
    world: np.ndarray
    visible: bool = True
    names: frozenset[str] | None = None


class _Columns:
    """Authored input values of a group of lights, one column per input name."""

    def __init__(
        self, items: Sequence[LightItem], names: list[frozenset[str]], time: Usd.TimeCode
    ) -> None:
        self.items = items
        self.names = names
        self.time = time
        self.n = len(items)
        #: Lights the bulk path hands to ``read_light`` (bad or unusual input).
        self.bad = np.zeros(self.n, dtype=bool)
        self._values = self._fetch()

    def raw(self, name: str) -> tuple[np.ndarray, list[Any]]:
        """(row indices where ``name`` is authored with a value, those values)."""
        got = self._values.get(name)
        if got is None:
            return np.zeros(0, dtype=np.int64), []
        return np.asarray(got[0], dtype=np.int64), got[1]

    def _fetch(self) -> dict[str, tuple[list[int], list[Any]]]:
        """Every authored input in ``_INPUTS``, one pass over the lights (one
        ``GetAttribute().Get()`` each)."""
        out: dict[str, tuple[list[int], list[Any]]] = {}
        t = self.time
        wanted: dict[frozenset[str], tuple[str, ...]] = {}
        for i, (it, nm) in enumerate(zip(self.items, self.names, strict=True)):
            prim = it.prim
            names = wanted.get(nm)
            if names is None:
                names = wanted[nm] = tuple(sorted(nm & _INPUTS))
            for name in names:
                a = prim.GetAttribute(name)
                v = a.Get(t) if a else None
                if v is not None:
                    rows, vals = out.setdefault(name, ([], []))
                    rows.append(i)
                    vals.append(v)
        return out

    def number(self, name: str, default: float) -> np.ndarray:
        """Float column (``default`` where unauthored); rows with a non-number or a
        non-finite value are marked bad."""
        out = np.full(self.n, default, dtype=np.float64)
        rows, vals = self.raw(name)
        if len(rows):
            ok = np.array([isinstance(v, (int, float)) for v in vals], dtype=bool)
            num = np.array([float(v) if k else math.nan for v, k in zip(vals, ok, strict=True)])
            out[rows] = num
            self.bad[rows[~np.isfinite(num)]] = True
        return out

    def flag(self, name: str, default: bool) -> np.ndarray:
        """Boolean column (Python truthiness, as ``bool(value)``)."""
        out = np.full(self.n, default, dtype=bool)
        rows, vals = self.raw(name)
        if len(rows):
            out[rows] = [bool(v) for v in vals]
        return out

    def colour(self, name: str, default: tuple[float, float, float]) -> np.ndarray:
        """(n, 3) float column; rows whose value is not a finite RGB triple are bad."""
        out = np.tile(np.asarray(default, dtype=np.float64), (self.n, 1))
        rows, vals = self.raw(name)
        if len(rows):
            ok = [isinstance(v, _COLOUR_TYPES) and len(v) == 3 for v in vals]
            good = [i for i, k in enumerate(ok) if k]
            if good:
                try:
                    arr = np.array([vals[i] for i in good], dtype=np.float64).reshape(-1, 3)
                except (TypeError, ValueError):
                    arr = np.full((len(good), 3), math.nan)
                out[rows[good]] = arr
            badrows = rows[[i for i, k in enumerate(ok) if not k]]
            self.bad[badrows] = True
            self.bad[rows[~np.isfinite(out[rows]).all(axis=1)]] = True
        return out

    def token(self, name: str, default: str, allowed: tuple[str, ...]) -> np.ndarray:
        """String column; rows with a value outside ``allowed`` are bad."""
        out = np.full(self.n, default, dtype=object)
        rows, vals = self.raw(name)
        if len(rows):
            out[rows] = vals
            self.bad[rows[[v not in allowed for v in vals]]] = True
        return out

    def has_prefix(self, *prefixes: str) -> np.ndarray:
        """Rows with an authored property name starting with one of ``prefixes``."""
        seen: dict[frozenset[str], bool] = {}  # lights share a few distinct name sets
        out = np.zeros(self.n, dtype=bool)
        for i, nm in enumerate(self.names):
            v = seen.get(nm)
            if v is None:
                v = seen[nm] = any(s.startswith(prefixes) for s in nm)
            out[i] = v
        return out


def read_lights(
    items: Sequence[LightItem], ctx: LightReadContext, time: Usd.TimeCode
) -> list[LightPrim]:
    """Read many lights; the i-th record is ``read_light`` of ``items[i]``. Never raises
    for bad data."""
    n = len(items)
    out: list[LightPrim | None] = [None] * n
    bulk: list[int] = []
    types: list[tuple[str, int]] = []
    names: list[frozenset[str]] = []
    legacy: dict[frozenset[str], bool] = {}
    for i, it in enumerate(items):
        t = _BULK_TYPES.get(it.prim.GetTypeName()) if it.prim else None
        if t is None:
            continue
        nm = it.names if it.names is not None else frozenset(it.prim.GetAuthoredPropertyNames())
        old = legacy.get(nm)
        if old is None:
            old = legacy[nm] = bool(nm & _LEGACY)
        if old or "inputs:texture:file" in nm:  # a textured rect: read_light reads it
            continue
        bulk.append(i)
        types.append(t)
        names.append(nm)
    if len(bulk) >= MIN_BULK_LIGHTS:
        try:
            got = _read_group([items[i] for i in bulk], types, names, ctx, time)
        except Exception:  # noqa: BLE001 - unexpected data: read_light reads (and warns)
            got = [None] * len(bulk)
        for i, lp in zip(bulk, got, strict=True):
            out[i] = lp
    result: list[LightPrim] = []
    for it, lp in zip(items, out, strict=True):
        if lp is None:
            lp = read_light(it.prim, ctx, time, it.world, it.visible, it.path, it.names)
        result.append(lp)
    return result


def _transforms(worlds: np.ndarray) -> dict[str, np.ndarray]:
    """``set_transform`` on a stack of (n, 4, 4) matrices."""
    pos = worlds[:, 3, :3].copy()
    norms = np.sqrt(np.einsum("nij,nij->ni", worlds[:, :3, :3], worlds[:, :3, :3]))
    n0, n1, n2 = norms[:, 0], norms[:, 1], norms[:, 2]
    ok2 = (n2 > 1e-12) & np.isfinite(n2)
    ok0 = (n0 > 1e-12) & np.isfinite(n0)
    with np.errstate(divide="ignore", invalid="ignore"):
        direction = np.where(ok2[:, None], -worlds[:, 2, :3] / n2[:, None], [0.0, -1.0, 0.0])
        tangent = np.where(ok0[:, None], worlds[:, 0, :3] / n0[:, None], [1.0, 0.0, 0.0])
    s = (n0 + n1 + n2) / 3.0
    scale = np.where(np.isfinite(s) & (s > 0), s, 1.0)
    return {
        "position": pos,
        "direction": direction,
        "tangent": tangent,
        "scale": scale,
        "n0": n0,
        "n1": n1,
    }


def _read_group(
    items: list[LightItem],
    types: list[tuple[str, int]],
    names: list[frozenset[str]],
    ctx: LightReadContext,
    time: Usd.TimeCode,
) -> list[LightPrim | None]:
    """Bulk-read lights of the four analytic local types; None for the ones to read
    singly."""
    n = len(items)
    col = _Columns(items, names, time)
    worlds = np.stack([np.asarray(it.world, dtype=np.float64) for it in items])
    col.bad |= ~(np.abs(worlds).sum(axis=(1, 2)) <= limits.MAX_COORDINATE_M)
    xf = _transforms(worlds)
    scale = xf["scale"]
    ltype = np.array([t for t, _ in types], dtype=object)
    emission = np.array([e for _, e in types], dtype=np.int64)

    # Radiance (nits, RGB): intensity * 2^exposure * colour [* blackbody].
    intensity = col.number("inputs:intensity", 1.0)
    exposure = col.number("inputs:exposure", 0.0)
    colour = col.colour("inputs:color", (1.0, 1.0, 1.0))
    normalize = col.flag("inputs:normalize", False)
    diffuse = col.number("inputs:diffuse", 1.0)
    specular = col.number("inputs:specular", 1.0)
    col.bad |= (intensity < 0) | (np.abs(exposure) > limits.MAX_ABS_EXPOSURE)
    col.bad |= (colour < 0).any(axis=1)  # clamped with a warning
    temp_on = col.flag("inputs:enableColorTemperature", False)
    kelvin = col.number("inputs:colorTemperature", 6500.0)
    rgb = colour.copy()
    if temp_on.any():
        ks = np.where(temp_on & np.isfinite(kelvin), kelvin, 6500.0)
        uk, inv = np.unique(ks, return_inverse=True)
        bb = np.array([blackbody_rgb(float(k)) for k in uk])[inv.reshape(-1)]
        rgb = np.where(temp_on[:, None], rgb * bb, rgb)
    with np.errstate(over="ignore", invalid="ignore"):
        radiance = (intensity * np.power(2.0, exposure))[:, None] * rgb

    # Size (m, world scale applied), projected and surface areas.
    is_sphere = ltype == prims.SPHERE_LIGHT
    is_rect = ltype == prims.RECT_LIGHT
    is_cyl = ltype == prims.CYLINDER_LIGHT
    is_disk = ltype == prims.DISK_LIGHT
    r_auth = col.number("inputs:radius", 0.5)
    width = col.number("inputs:width", 1.0)
    height = col.number("inputs:height", 1.0)
    length = col.number("inputs:length", 1.0)
    col.bad |= ~is_rect & (r_auth < 0)
    col.bad |= is_rect & ((width < 0) | (height < 0))
    col.bad |= is_cyl & (length < 0)
    radius = np.where(is_rect, 0.0, r_auth * scale)
    w_m = np.where(is_rect, width * xf["n0"], 0.0)
    h_m = np.where(is_rect, height * xf["n1"], 0.0)
    len_m = np.where(is_cyl, length * xf["n0"], 0.0)
    tap = np.zeros(n, dtype=bool)  # read at the default time, as read_light does
    for i in np.nonzero(is_sphere)[0].tolist():
        if "treatAsPoint" in names[i]:
            tap[i] = bool(items[i].prim.GetAttribute("treatAsPoint").Get() or False)
    r2 = radius * radius
    proj = np.select(
        [is_sphere | is_disk, is_rect, is_cyl], [np.pi * r2, w_m * h_m, 2.0 * radius * len_m]
    )
    area = np.select(
        [is_sphere, is_disk, is_rect, is_cyl],
        [4.0 * np.pi * r2, np.pi * r2, w_m * h_m, 2.0 * np.pi * radius * len_m],
    )
    col.bad |= normalize & ~(area > 0)  # warns: emits nothing
    col.bad |= ~normalize & ~(proj > 0)  # warns: zero-area light
    with np.errstate(divide="ignore", invalid="ignore"):
        radiance = np.where(
            normalize[:, None], radiance / np.where(area > 0, area, 1.0)[:, None], radiance
        )

    # ShapingAPI: cone, focus, tint, IES.
    shaping = col.has_prefix("inputs:shaping:", "shaping:")
    for i in np.nonzero(~shaping)[0]:
        shaping[i] = "ShapingAPI" in items[i].prim.GetAppliedSchemas()
    cone_deg = np.where(
        shaping, col.number("inputs:shaping:cone:angle", 90.0), prims.NO_CONE_ANGLE_DEG
    )
    soft = np.where(shaping, col.number("inputs:shaping:cone:softness", 0.0), 0.0)
    focus = np.where(shaping, col.number("inputs:shaping:focus", 0.0), 0.0)
    tint = np.where(shaping[:, None], col.colour("inputs:shaping:focusTint", (0.0, 0.0, 0.0)), 0.0)
    col.bad |= shaping & ((cone_deg < 0) | (cone_deg > prims.NO_CONE_ANGLE_DEG))
    angle_scale = np.where(shaping, col.number("inputs:shaping:ies:angleScale", 0.0), 0.0)
    ies_norm = shaping & col.flag("inputs:shaping:ies:normalize", False)
    has_cone = shaping & (cone_deg < prims.NO_CONE_ANGLE_DEG)
    soft = np.clip(soft, 0.0, 1.0)
    focus = np.maximum(focus, 0.0)
    ies_file: list[str | None] = [None] * n
    ies_asset: list[str | None] = [None] * n
    ies_scale = np.ones(n)
    ies_power = np.zeros(n)
    ies_rows, ies_vals = col.raw("inputs:shaping:ies:file")
    for i, asset in zip(ies_rows.tolist(), ies_vals, strict=True):
        if not shaping[i]:
            continue
        _ies_one(i, asset, ies_norm[i], ctx, col, ies_file, ies_asset, ies_scale, ies_power)
    has_ies = np.array([f is not None for f in ies_file], dtype=bool)
    has_cone &= ~has_ies

    # Intensity (cd along the axis), shadows, photometry.
    lum = radiance * proj[:, None]
    sh_any = col.has_prefix("inputs:shadow:", "shadow:")
    sh_enable = np.where(sh_any, col.flag("inputs:shadow:enable", True), True)
    sh_colour = np.where(sh_any[:, None], col.colour("inputs:shadow:color", (0.0, 0.0, 0.0)), 0.0)
    sd = np.where(sh_any, col.number("inputs:shadow:distance", -1.0), -1.0)
    sf = np.where(sh_any, col.number("inputs:shadow:falloff", -1.0), -1.0)
    sg = np.where(sh_any, col.number("inputs:shadow:falloffGamma", 1.0), 1.0)
    upd = col.token(
        "stb:shadow:update", prims.SHADOW_STATIC, (prims.SHADOW_STATIC, prims.SHADOW_DYNAMIC)
    )
    mob = col.token(
        "stb:mobility", prims.MOBILITY_DYNAMIC, (prims.MOBILITY_STATIC, prims.MOBILITY_DYNAMIC)
    )
    baked = col.flag("stb:baked", False) & (mob == prims.MOBILITY_STATIC)
    sh_dist = np.where(sd > 0, sd * scale, -1.0)
    sh_fall = np.where(sf > 0, sf * scale, -1.0)
    sh_fall = np.where((sh_dist > 0) & (sh_fall > sh_dist), sh_dist, sh_fall)
    sh_gamma = np.where(sg > 0, sg, 1.0)

    iy = lum @ _LUMA
    integ = np.zeros(n)
    peak = np.zeros(n)
    keys = list(
        zip(
            emission.tolist(),
            has_cone.tolist(),
            cone_deg.tolist(),
            soft.tolist(),
            focus.tolist(),
            ies_file,
            angle_scale.tolist(),
            strict=True,
        )
    )
    cache: dict[tuple[Any, ...], tuple[float, float]] = {}
    for i, k in enumerate(keys):
        v = cache.get(k)
        if v is None:
            v = cache[k] = shape_integral(*k)
        integ[i], peak[i] = v
    with np.errstate(over="ignore", invalid="ignore"):
        flux = iy * ies_scale * integ
        peak_cd = np.maximum(iy * ies_scale * peak, 0.0)
        imax = lum.max(axis=1)
        col.bad |= ~(np.isfinite(imax) & (imax >= 0))
        col.bad |= imax * ies_scale > limits.MAX_INTENSITY_CD
    # stb:range: a number that is not finite or not positive is ignored silently.
    rng_rows, rng_vals = col.raw("stb:range")
    rng_auth = np.full(n, -1.0)
    for i, v in zip(rng_rows.tolist(), rng_vals, strict=True):
        if not isinstance(v, (int, float)):
            col.bad[i] = True
        elif math.isfinite(v) and v > 0:
            rng_auth[i] = float(v)
    authored_rng = rng_auth > 0
    r_auto = influence_range(np.where(np.isfinite(peak_cd), peak_cd, 0.0))
    rng = np.where(authored_rng, rng_auth * scale, r_auto)

    out: list[LightPrim | None] = [None] * n
    bad = col.bad
    fields = {
        "position": xf["position"],
        "direction": xf["direction"],
        "tangent": xf["tangent"],
        "intensity": lum,
        "focus_tint": tint,
        "shadow_color": np.clip(sh_colour, 0.0, 1.0),
    }
    vecs = {k: list(v) for k, v in fields.items()}
    scal = {
        "emission": emission.tolist(),
        "flux": flux.tolist(),
        "radius": radius.tolist(),
        "width": w_m.tolist(),
        "height": h_m.tolist(),
        "length": len_m.tolist(),
        "treat_as_point": tap.tolist(),
        "has_cone": has_cone.tolist(),
        "cone_angle": cone_deg.tolist(),
        "cone_softness": soft.tolist(),
        "focus": focus.tolist(),
        "ies_angle_scale": angle_scale.tolist(),
        "ies_normalize": ies_norm.tolist(),
        "ies_scale": ies_scale.tolist(),
        "ies_power": ies_power.tolist(),
        "diffuse": diffuse.tolist(),
        "specular": specular.tolist(),
        "shadow_enable": sh_enable.tolist(),
        "shadow_distance": sh_dist.tolist(),
        "shadow_falloff": sh_fall.tolist(),
        "shadow_falloff_gamma": sh_gamma.tolist(),
        "baked": baked.tolist(),
        "range": rng.tolist(),
        "range_authored": authored_rng.tolist(),
        "peak_intensity": peak_cd.tolist(),
    }
    scale_l = scale.tolist()
    for i in np.nonzero(~bad)[0].tolist():
        it = items[i]
        lp = LightPrim(path=it.path, type=str(ltype[i]))
        for k, v in vecs.items():
            setattr(lp, k, v[i])
        for k, sv in scal.items():
            setattr(lp, k, sv[i])
        lp.transform = worlds[i]
        lp.world_scale = scale_l[i]
        lp.ies_file = ies_file[i]
        lp.ies_asset = ies_asset[i]
        lp.shadow_update = str(upd[i])
        lp.mobility = str(mob[i])
        lp.valid = True
        lp.enabled = bool(it.visible)
        out[i] = lp
    return out


def _ies_one(
    i: int,
    asset: Any,
    normalize: bool,
    ctx: LightReadContext,
    col: _Columns,
    ies_file: list[str | None],
    ies_asset: list[str | None],
    ies_scale: np.ndarray,
    ies_power: np.ndarray,
) -> None:
    """``_read_ies`` for light ``i``: anything that would warn marks it bad."""
    authored = asset.path if isinstance(asset, Sdf.AssetPath) else str(asset)
    if not authored:
        return
    ies_asset[i] = authored
    resolved = asset.resolvedPath if isinstance(asset, Sdf.AssetPath) else ""
    if not resolved:
        col.bad[i] = True
        return
    try:
        prof = ctx.ies_loader(resolved)
    except IesError:
        col.bad[i] = True
        return
    mx, power = ies_stats(resolved, prof)
    if not (math.isfinite(mx) and mx > 0):
        col.bad[i] = True
        return
    ies_file[i] = resolved
    ies_power[i] = power
    ies_scale[i] = mx / power if normalize else mx
