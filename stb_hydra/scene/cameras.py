"""UsdGeom.Camera -> :class:`CameraPrim` (render frame, metres)."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from pxr import Usd, UsdGeom

from .. import limits
from .prims import CameraPrim

#: UsdGeom.Camera attribute -> CameraPrim field.
_FIELDS = {
    "focalLength": "focal_length",
    "horizontalAperture": "horizontal_aperture",
    "verticalAperture": "vertical_aperture",
    "horizontalApertureOffset": "horizontal_aperture_offset",
    "verticalApertureOffset": "vertical_aperture_offset",
}


def _positive(value: float, fallback: float) -> float:
    """``value`` if > 0 and at most ``limits.MAX_COORDINATE_M`` (float32-safe), else
    ``fallback``."""
    return value if 0 < value <= limits.MAX_COORDINATE_M else fallback


def read_camera(
    prim: Usd.Prim,
    time: Usd.TimeCode,
    world: np.ndarray,
    meters_per_unit: float,
    warn: Callable[[str], None] | None = None,
) -> CameraPrim:
    """``world`` is the camera's local-to-render matrix. Clipping distances are
    converted from stage units to metres (the transform's scale is ignored for
    them, as in UsdGeom). Unusable values (a non-finite or singular transform, a
    focal length or aperture that is not a finite positive number, a bad clipping
    range) are replaced by defaults, each with a one-line ``warn``."""
    cam = UsdGeom.Camera(prim)
    gc = cam.GetCamera(time)
    cp = CameraPrim(path=str(prim.GetPath()))
    problems: list[str] = []
    m = np.asarray(world, dtype=np.float64).copy()
    # Remove scale from the camera frame: keep orthonormal axes.
    for i in range(3):
        n = np.linalg.norm(m[i, :3])
        if n > 1e-12 and math.isfinite(n):
            m[i, :3] /= n
    if not np.all(np.abs(m) <= limits.MAX_COORDINATE_M) or abs(np.linalg.det(m[:3, :3])) < 1e-6:
        problems.append("transform is not finite, huge or singular; using the identity")
        m = np.eye(4)
    cp.transform = m
    cp.projection = "orthographic" if gc.projection == gc.Orthographic else "perspective"
    for name, value, default in (
        ("focalLength", float(gc.focalLength), 50.0),
        ("horizontalAperture", float(gc.horizontalAperture), 20.955),
        ("verticalAperture", float(gc.verticalAperture), 15.2908),
    ):
        ok = _positive(value, default)
        if value != 0.0 and ok != value:  # 0 is USD's "unset" here: default silently
            problems.append(f"{name} {value:g} is not a positive number; using {default:g}")
        setattr(cp, _FIELDS[name], ok)
    for name, value, aperture in (
        ("horizontalApertureOffset", float(gc.horizontalApertureOffset), cp.horizontal_aperture),
        ("verticalApertureOffset", float(gc.verticalApertureOffset), cp.vertical_aperture),
    ):
        # past 1000 apertures off axis the frustum's edges cancel in float (1e30 divided
        # by zero in the shadow fit: found by tools/fuzz.py)
        if not abs(value) <= limits.CAMERA_MAX_APERTURE_OFFSET * aperture:
            problems.append(f"{name} {value:g} is not finite or huge; using 0")
            value = 0.0
        setattr(cp, _FIELDS[name], value)
    rng = gc.clippingRange
    near, far = float(rng.min) * meters_per_unit, float(rng.max) * meters_per_unit
    if not (math.isfinite(near) and math.isfinite(far)) or near <= 0 or far <= near:
        problems.append(
            f"clippingRange ({rng.min:g}, {rng.max:g}) is unusable; using (0.1, 1000) m"
        )
        near, far = 0.1, 1000.0
    if warn is not None:
        for p in problems:
            warn(f"camera <{cp.path}>: {p}")
    cp.near, cp.far = near, far
    planes = [np.asarray(p, dtype=np.float64) for p in gc.clippingPlanes]
    if planes:
        pl = np.array(planes)
        pl[:, 3] *= meters_per_unit
        cp.clipping_planes = pl
    return cp


def exposure_scale(
    prim: Usd.Prim, time: Usd.TimeCode, warn: Callable[[str], None] | None = None
) -> float:
    """UsdGeomCamera's linear exposure scale (exposure, fStop, time, ISO, responsivity).
    A scale that is not a finite positive float (e.g. ``exposure = 200``: 2^200
    overflows) is replaced by 1 with a one-line ``warn``."""
    cam = UsdGeom.Camera(prim)
    try:
        s = float(cam.ComputeLinearExposureScale(time))
    except Exception as exc:  # noqa: BLE001 - bad input must never crash
        why = f"could not be computed ({type(exc).__name__})"
    else:
        if math.isfinite(s) and s > 0:
            return s
        why = f"is {s:g}"
    if warn is not None:
        vals = []
        for name, label in (
            ("exposure", "exposure"),
            ("fStop", "fStop"),
            ("exposure:time", "time"),
            ("exposure:iso", "ISO"),
            ("exposure:responsivity", "responsivity"),
        ):
            attr = prim.GetAttribute(name)
            if attr and attr.HasAuthoredValue():
                vals.append(f"{label} {attr.Get(time)}")
        detail = f" ({', '.join(vals)})" if vals else ""
        warn(f"camera <{prim.GetPath()}>: exposure scale {why}{detail}; using 1 (no exposure)")
    return 1.0


#: Relative change of a camera's world matrix (max abs element difference over its
#: largest element) below which two time samples count as the same view.
CAMERA_STILL_TOLERANCE = 1e-9


def camera_moves(stage: Usd.Stage, path: str | None, times: list[float | None]) -> bool:
    """Whether the camera at ``path`` changes its view over ``times`` (world transform,
    ancestors included, or a lens attribute: focal length, apertures and offsets,
    clipping range). ``path`` None (a free framing camera) never moves."""
    if path is None or len(times) < 2:
        return False
    prim = stage.GetPrimAtPath(path)
    if not prim or not prim.IsA(UsdGeom.Camera):
        return False
    cam = UsdGeom.Camera(prim)
    cache_times = [Usd.TimeCode(t) if t is not None else Usd.TimeCode.Default() for t in times]
    xf = UsdGeom.Xformable(prim)
    first = np.array(xf.ComputeLocalToWorldTransform(cache_times[0]), dtype=np.float64)
    scale = max(float(np.abs(first).max()), 1.0)
    lens = (
        cam.GetFocalLengthAttr(),
        cam.GetHorizontalApertureAttr(),
        cam.GetVerticalApertureAttr(),
        cam.GetHorizontalApertureOffsetAttr(),
        cam.GetVerticalApertureOffsetAttr(),
        cam.GetClippingRangeAttr(),
    )
    lens0 = [a.Get(cache_times[0]) for a in lens]
    for t in cache_times[1:]:
        m = np.array(xf.ComputeLocalToWorldTransform(t), dtype=np.float64)
        if float(np.abs(m - first).max()) > CAMERA_STILL_TOLERANCE * scale:
            return True
        if [a.Get(t) for a in lens] != lens0:
            return True
    return False
