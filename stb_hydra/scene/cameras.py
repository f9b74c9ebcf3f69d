"""UsdGeom.Camera -> :class:`CameraPrim` (render frame, metres)."""

from __future__ import annotations

import math

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


def exposure_scale(prim: Usd.Prim, time: Usd.TimeCode) -> float:
    """UsdGeomCamera's linear exposure scale (exposure, fStop, time, ISO, responsivity)."""
    try:
        s = float(UsdGeom.Camera(prim).ComputeLinearExposureScale(time))
    except Exception:  # noqa: BLE001 - bad input must never crash
        return 1.0
    return s if math.isfinite(s) and s > 0 else 1.0
