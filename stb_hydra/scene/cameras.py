"""UsdGeom.Camera -> :class:`CameraPrim` (render frame, metres)."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from pxr import Usd, UsdGeom

from .prims import CameraPrim


def read_camera(
    prim: Usd.Prim, time: Usd.TimeCode, world: np.ndarray, meters_per_unit: float
) -> CameraPrim:
    """``world`` is the camera's local-to-render matrix. Clipping distances are
    converted from stage units to metres (the transform's scale is ignored for
    them, as in UsdGeom)."""
    cam = UsdGeom.Camera(prim)
    gc = cam.GetCamera(time)
    cp = CameraPrim(path=str(prim.GetPath()))
    m = np.asarray(world, dtype=np.float64).copy()
    # Remove scale from the camera frame: keep orthonormal axes.
    for i in range(3):
        n = np.linalg.norm(m[i, :3])
        if n > 1e-12 and math.isfinite(n):
            m[i, :3] /= n
    cp.transform = m
    cp.projection = "orthographic" if gc.projection == gc.Orthographic else "perspective"
    cp.focal_length = float(gc.focalLength) or 50.0
    cp.horizontal_aperture = float(gc.horizontalAperture) or 20.955
    cp.vertical_aperture = float(gc.verticalAperture) or 15.2908
    cp.horizontal_aperture_offset = float(gc.horizontalApertureOffset)
    cp.vertical_aperture_offset = float(gc.verticalApertureOffset)
    rng = gc.clippingRange
    near, far = float(rng.min) * meters_per_unit, float(rng.max) * meters_per_unit
    if not (math.isfinite(near) and math.isfinite(far)) or near <= 0 or far <= near:
        near, far = 0.1, 1000.0
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
