"""Camera matrices for rendering (render frame: Y up, metres).

Matrices are row-vector (``p' = p @ M``), as everywhere in stb_hydra; upload
them as row-major bytes and use ``M * v`` in GLSL (see ``render.gl``).
OpenGL clip conventions (NDC z in [-1, 1]).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ..scene.prims import CameraPrim
from ..shadows.capture import look_at, perspective


@dataclass
class ViewSetup:
    """Everything a frame needs about its camera."""

    view: np.ndarray  # world -> view (row-vector 4x4)
    proj: np.ndarray  # view -> clip
    view_proj: np.ndarray
    inv_view: np.ndarray  # camera -> world
    position: np.ndarray  # camera position (m)
    forward: np.ndarray  # unit, world
    near: float
    far: float
    width: int
    height: int
    #: Half extents of the image plane at unit view depth: (tan(fx/2), tan(fy/2)).
    tan_half: tuple[float, float]
    #: Centre offsets of the image plane at unit view depth (aperture offsets).
    offset: tuple[float, float]
    orthographic: bool = False
    exposure_scale: float = 1.0
    #: Subpixel offset of the image content (px, +x right, +y up; temporal reuse).
    jitter: tuple[float, float] = (0.0, 0.0)
    #: ``view_proj`` without the jitter (the previous frame's matrix for motion vectors).
    unjittered_view_proj: np.ndarray | None = None

    def frustum_planes(self) -> np.ndarray:
        """(6, 4) world-space planes (n, d) with n.p + d >= 0 inside: left,
        right, bottom, top, near, far (Gribb-Hartmann from view_proj)."""
        m = self.view_proj  # row-vector: clip = p @ m, so columns are the rows of GL's matrix
        c = [m[:, i] for i in range(4)]
        planes = np.array(
            [c[3] + c[0], c[3] - c[0], c[3] + c[1], c[3] - c[1], c[3] + c[2], c[3] - c[2]]
        )
        n = np.linalg.norm(planes[:, :3], axis=1, keepdims=True)
        return planes / np.maximum(n, 1e-30)


def orthographic(
    half_w: float, half_h: float, off_x: float, off_y: float, near: float, far: float
) -> np.ndarray:
    m = np.zeros((4, 4))
    m[0, 0] = 1.0 / half_w
    m[1, 1] = 1.0 / half_h
    m[2, 2] = -2.0 / (far - near)
    m[3, 0] = -off_x / half_w
    m[3, 1] = -off_y / half_h
    m[3, 2] = -(far + near) / (far - near)
    m[3, 3] = 1.0
    return m


def conform_aperture(cam: CameraPrim, aspect: float) -> tuple[float, float]:
    """Horizontal/vertical aperture conformed to the image aspect by expanding
    one of them (UsdImaging's 'fit': the authored aperture stays fully visible)."""
    h, v = cam.horizontal_aperture, cam.vertical_aperture
    cam_aspect = h / max(v, 1e-12)
    if aspect > cam_aspect:
        h = v * aspect
    else:
        v = h / aspect
    return h, v


def view_setup(
    cam: CameraPrim,
    width: int,
    height: int,
    exposure_scale: float = 1.0,
    jitter: tuple[float, float] = (0.0, 0.0),
) -> ViewSetup:
    """The frame's matrices. ``jitter`` shifts the image content by a subpixel
    offset (px) through the aperture offset, so the projection and the shaders'
    pixel -> view reconstruction (``u_tan_off``) agree; ``unjittered_view_proj``
    keeps the matrix without it."""
    inv_view = np.asarray(cam.transform, dtype=np.float64)
    view = np.linalg.inv(inv_view)
    h_ap, v_ap = conform_aperture(cam, width / height)
    if cam.projection == "orthographic":
        # USD: apertures are in tenths of a scene unit for ortho cameras.
        hw, hh = 0.05 * h_ap, 0.05 * v_ap
        ox, oy = 0.1 * cam.horizontal_aperture_offset, 0.1 * cam.vertical_aperture_offset
        proj0 = orthographic(hw, hh, ox, oy, cam.near, cam.far)
        tan_half = (hw, hh)
    else:
        f = max(cam.focal_length, 1e-9)
        tx, ty = 0.5 * h_ap / f, 0.5 * v_ap / f
        ox, oy = cam.horizontal_aperture_offset / f, cam.vertical_aperture_offset / f
        proj0 = perspective(tx, ty, ox, oy, cam.near, cam.far)
        tan_half = (tx, ty)
    # NDC = (x / depth - offset) / tan_half: the content moves by +j px when the
    # offset moves by -2 j tan_half / size.
    jx, jy = float(jitter[0]), float(jitter[1])
    if jx or jy:
        ox -= 2.0 * jx * tan_half[0] / width
        oy -= 2.0 * jy * tan_half[1] / height
        if cam.projection == "orthographic":
            proj = orthographic(tan_half[0], tan_half[1], ox, oy, cam.near, cam.far)
        else:
            proj = perspective(tan_half[0], tan_half[1], ox, oy, cam.near, cam.far)
    else:
        proj = proj0
    offset = (ox, oy)
    fwd = -inv_view[2, :3]
    fwd = fwd / max(float(np.linalg.norm(fwd)), 1e-30)
    return ViewSetup(
        view=view,
        proj=proj,
        view_proj=view @ proj,
        inv_view=inv_view,
        position=inv_view[3, :3].copy(),
        forward=fwd,
        near=cam.near,
        far=cam.far,
        width=width,
        height=height,
        tan_half=tan_half,
        offset=offset,
        orthographic=cam.projection == "orthographic",
        exposure_scale=exposure_scale,
        jitter=(jx, jy),
        unjittered_view_proj=view @ proj0,
    )


def framing_camera(
    bounds_min: npt.ArrayLike, bounds_max: npt.ArrayLike, aspect: float = 16 / 9
) -> CameraPrim:
    """A free camera framing an axis-aligned box from a raised three-quarter view."""
    lo = np.asarray(bounds_min, dtype=np.float64)
    hi = np.asarray(bounds_max, dtype=np.float64)
    if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))) or np.any(hi < lo):
        lo, hi = np.array([-1.0, -1.0, -1.0]), np.array([1.0, 1.0, 1.0])
    center = 0.5 * (lo + hi)
    radius = max(0.5 * float(np.linalg.norm(hi - lo)), 1e-3)
    cam = CameraPrim(path="/__stb_free_camera")
    cam.focal_length = 35.0
    cam.horizontal_aperture = 36.0
    cam.vertical_aperture = 36.0 / aspect
    half_fov = math.atan(0.5 * min(cam.horizontal_aperture, cam.vertical_aperture) / 35.0)
    dist = radius / math.sin(half_fov) * 1.05
    d = np.array([1.0, 0.6, 1.3])
    d /= np.linalg.norm(d)
    eye = center + d * dist
    cam.transform = look_at(eye, center)
    cam.near = max(dist - radius * 1.5, dist * 1e-3, 1e-3)
    cam.far = dist + radius * 1.5
    return cam
