"""A camera orbit authored on a stage: the moving-camera sequences of the temporal
tests and ``tools/taa_orbit.py``."""

from __future__ import annotations

from pxr import Gf, Usd, UsdGeom


def orbit_camera(
    stage: Usd.Stage,
    frames: int,
    degrees: float,
    pivot_distance: float = 12.0,
    camera: str | None = None,
) -> str:
    """Turn the stage's camera (``camera``, default its first) about a vertical axis
    through the ground point ``pivot_distance`` ahead of it: ``degrees`` per frame,
    one time sample per frame at times 1..``frames`` (the camera's default-time
    transform is frame 1). Authored on the current edit target; returns the camera's
    path."""
    if camera is not None:
        prim = stage.GetPrimAtPath(camera)
    else:
        prim = next((p for p in stage.Traverse() if p.IsA(UsdGeom.Camera)), None)
    if prim is None or not prim.IsValid():
        raise ValueError("orbit_camera: the stage has no camera")
    xf = UsdGeom.Xformable(prim)
    m0 = xf.ComputeLocalToWorldTransform(Usd.TimeCode.Default())
    parent = xf.ComputeParentToWorldTransform(Usd.TimeCode.Default())
    eye = m0.ExtractTranslation()
    fwd = -Gf.Vec3d(m0[2][0], m0[2][1], m0[2][2]).GetNormalized()
    pivot = eye + fwd * pivot_distance
    pivot[1] = 0.0
    xf.ClearXformOpOrder()
    op = xf.AddTransformOp()
    to_local = parent.GetInverse()
    for i in range(frames):
        rot = Gf.Matrix4d().SetRotate(Gf.Rotation(Gf.Vec3d(0, 1, 0), degrees * i))
        world = m0 * Gf.Matrix4d().SetTranslate(-pivot) * rot * Gf.Matrix4d().SetTranslate(pivot)
        op.Set(world * to_local, Usd.TimeCode(1 + i))
    stage.SetStartTimeCode(1)
    stage.SetEndTimeCode(max(frames, 1))
    return str(prim.GetPath())


__all__ = ["orbit_camera"]
