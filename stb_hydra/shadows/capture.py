"""Shadow-map capture parameters and records (GL-free; the GL capture itself is
:mod:`stb_hydra.renderer.shadow_capture`).

* Spot lights (cone <= ``SPOT_MAX_HALF_ANGLE_DEG``): a perspective depth map
  rendered from the light into a temporary depth target of the map's interior size.
* Omni lights (no cone or a wide one; disk/rect hemispheres too): a cube of 6
  faces rendered into a temporary 3F x 2F depth grid, F = interior / 2.
* Copy (``shadow_copy.frag``) into the atlas rect: linearise, distance along
  the texel's ray, bias, normalise by the range, 3 px border (clamp for spot,
  octahedral mirroring for omni).

Every capture records a :class:`Capture` (the light transform it used); lookups
use that, not the light's current transform. :func:`map_record` is the std430
``ShadowMap`` record (``common/shadow.glsl``) the lighting shaders read.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from .. import limits
from .atlas import AtlasRect

#: Widest cone captured with one perspective map; wider cones use an octahedral map.
SPOT_MAX_HALF_ANGLE_DEG = 75.0
#: Bias as a multiple of the texel's angular size (x distance), applied at copy.
BIAS_TEXELS = 1.0
#: Floats per std430 ``ShadowMap`` record (``common/shadow.glsl``): mat4 + 3 vec4.
RECORD_FLOATS = 28
#: Receiver normal offset, in texels at the receiver's distance (lookup side).
NORMAL_BIAS_TEXELS = 0.6

_FACES = (  # forward, up
    ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0)),
    ((-1.0, 0.0, 0.0), (0.0, 1.0, 0.0)),
    ((0.0, 1.0, 0.0), (0.0, 0.0, 1.0)),
    ((0.0, -1.0, 0.0), (0.0, 0.0, 1.0)),
    ((0.0, 0.0, 1.0), (0.0, 1.0, 0.0)),
    ((0.0, 0.0, -1.0), (0.0, 1.0, 0.0)),
)


#: ``Capture.shadow_mask`` of a light without shadow linking (every group casts).
ALL_SHADOW_GROUPS = 0xFFFFFFFF


@dataclass(frozen=True)
class Capture:
    """The light transform a map is captured with (exact-compare 'moved' key), and the
    shadow-link groups that cast into it (``scene/links.py``: a mask change re-captures)."""

    position: tuple[float, float, float]
    direction: tuple[float, float, float]
    range: float
    near: float
    spot_half_angle: float  # radians; <= 0: omni
    shadow_mask: int = ALL_SHADOW_GROUPS

    @property
    def omni(self) -> bool:
        return self.spot_half_angle <= 0.0


def _vec3(v: Iterable[float]) -> tuple[float, float, float]:
    x, y, z = (float(c) for c in v)
    return (x, y, z)


def capture_for(
    position: Iterable[float],
    direction: Iterable[float],
    range_m: float,
    radius: float,
    cone_cutoff_rad: float,
    emission: int,
    shadow_mask: int = ALL_SHADOW_GROUPS,
) -> Capture:
    """Capture parameters of a light (positions in metres, cone cut-off in radians)."""
    half = float(cone_cutoff_rad)
    spot = half < math.radians(SPOT_MAX_HALF_ANGLE_DEG) and emission != 2
    near = max(float(radius) * 1.05, 0.01)
    rng = max(float(range_m), near * 4.0)
    return Capture(
        _vec3(position),
        _vec3(direction),
        rng,
        near,
        min(half * 1.02 + math.radians(1.0), math.radians(85.0)) if spot else 0.0,
        int(shadow_mask),
    )


def capture_for_row(table: Any, row: int) -> Capture:
    """:func:`capture_for` of light-table row ``row`` (a ``LightTable`` or anything with
    its ``position``, ``direction``, ``range``, ``radius``, ``cone_cutoff`` and
    ``emission`` columns; ``shadow_link_mask`` if it has one)."""
    t, r = table, row
    masks = getattr(t, "shadow_link_mask", None)
    mask = ALL_SHADOW_GROUPS if masks is None else int(masks[r])
    return capture_for(
        t.position[r],
        t.direction[r],
        t.range[r],
        t.radius[r],
        t.cone_cutoff[r],
        t.emission[r],
        mask,
    )


def spot_view_proj(c: Capture) -> np.ndarray:
    pos = np.array(c.position)
    d = np.array(c.direction)
    to_world = look_at(pos, pos + d, up=_up_for(d))
    t = math.tan(c.spot_half_angle)
    return np.linalg.inv(to_world) @ perspective(t, t, 0.0, 0.0, c.near, c.range)


def _up_for(d: np.ndarray) -> tuple[float, float, float]:
    return (0.0, 0.0, 1.0) if abs(float(d[1])) > 0.9 else (0.0, 1.0, 0.0)


def face_rotations() -> np.ndarray:
    """(6, 3, 3) world -> face-view rotations (row-vector), face order +X -X +Y -Y +Z -Z."""
    return _face_rotations().copy()


@functools.cache
def _face_rotations() -> np.ndarray:
    out = np.zeros((6, 3, 3))
    for i, (f, up) in enumerate(_FACES):
        m = look_at(np.zeros(3), np.array(f), up=up)
        out[i] = np.linalg.inv(m)[:3, :3]
    return out


def omni_face_view_projs(c: Capture) -> np.ndarray:
    """(6, 4, 4) row-vector world -> clip matrices of the cube faces of an omni capture
    (90 degree frusta, near ``c.near``, far ``c.range``), face order as ``face_rotations``."""
    proj = perspective(1.0, 1.0, 0.0, 0.0, c.near, c.range)
    trans = np.eye(4)
    trans[3, :3] = -np.asarray(c.position, dtype=np.float64)
    rot = np.zeros((6, 4, 4))
    rot[:, :3, :3] = face_rotations()
    rot[:, 3, 3] = 1.0
    return trans @ rot @ proj


def omni_face_view_projs_many(
    position: np.ndarray, near: np.ndarray, far: np.ndarray
) -> np.ndarray:
    """(L, 6, 4, 4) ``omni_face_view_projs`` of L lights at once (positions (L, 3) in
    metres, near / far planes (L,))."""
    pos = np.asarray(position, dtype=np.float64).reshape(-1, 3)
    n = np.asarray(near, dtype=np.float64).reshape(-1)
    f = np.asarray(far, dtype=np.float64).reshape(-1)
    rot = _face_rotations()  # (6, 3, 3)
    # view = [p - pos, 1] @ [[R, 0], [0, 1]]: translation row -pos @ R
    view = np.zeros((len(pos), 6, 4, 4))
    view[:, :, :3, :3] = rot
    view[:, :, 3, :3] = -np.einsum("li,fij->lfj", pos, rot)
    view[:, :, 3, 3] = 1.0
    proj = np.zeros((len(pos), 4, 4))
    proj[:, 0, 0] = proj[:, 1, 1] = 1.0
    proj[:, 2, 2] = -(f + n) / (f - n)
    proj[:, 2, 3] = -1.0
    proj[:, 3, 2] = -2.0 * f * n / (f - n)
    return view @ proj[:, None]


def capture_view_projs(c: Capture) -> np.ndarray:
    """(F, 4, 4) view-projections one capture renders: 6 cube faces (omni) or 1 (spot)."""
    return omni_face_view_projs(c) if c.omni else spot_view_proj(c)[None]


def texel_angle(c: Capture, interior: int) -> float:
    """Angular size of one map texel (radians), for biases."""
    if c.omni:
        return math.sqrt(4.0 * math.pi) / max(interior, 1)
    return 2.0 * math.tan(c.spot_half_angle) / max(interior, 1)


def map_record(c: Capture, rect: AtlasRect, atlas_size: int) -> np.ndarray:
    """The std430 ``ShadowMap`` record (``RECORD_FLOATS`` floats) of a map captured
    with ``c`` into ``rect`` of an ``atlas_size`` atlas: view-projection (spot), position
    and range, interior rect and omni flag, near / texel angle / 1 / atlas size /
    normal bias."""
    border = limits.SHADOW_MAP_BORDER_PX
    interior = rect.size - 2 * border
    rec = np.zeros(RECORD_FLOATS, dtype=np.float32)
    if not c.omni:
        rec[0:16] = spot_view_proj(c).astype(np.float32).reshape(16)
    rec[16:19] = c.position
    rec[19] = c.range
    rec[20:24] = (rect.x + border, rect.y + border, interior, 1.0 if c.omni else 0.0)
    rec[24:28] = (c.near, texel_angle(c, interior), 1.0 / atlas_size, NORMAL_BIAS_TEXELS)
    return rec


# Row-vector camera matrices (GL-free, so they live here; ``renderer.camera`` re-exports
# them for the main camera and the sun).


def look_at(
    eye: npt.ArrayLike, target: npt.ArrayLike, up: npt.ArrayLike = (0.0, 1.0, 0.0)
) -> np.ndarray:
    """Camera-to-world (row-vector) looking from ``eye`` at ``target``."""
    eye = np.asarray(eye, dtype=np.float64)
    f = np.asarray(target, dtype=np.float64) - eye
    f /= max(np.linalg.norm(f), 1e-30)
    up = np.asarray(up, dtype=np.float64)
    if abs(float(f @ up)) > 0.999:
        up = np.array([0.0, 0.0, 1.0])
    x = np.cross(f, up)
    x /= np.linalg.norm(x)
    y = np.cross(x, f)
    m = np.eye(4)
    m[0, :3], m[1, :3], m[2, :3], m[3, :3] = x, y, -f, eye
    return m


def perspective(
    tan_x: float, tan_y: float, off_x: float, off_y: float, near: float, far: float
) -> np.ndarray:
    """Row-vector projection for an off-axis frustum (view looks down -Z)."""
    l, r = (off_x - tan_x), (off_x + tan_x)
    b, t = (off_y - tan_y), (off_y + tan_y)
    m = np.zeros((4, 4))
    m[0, 0] = 2.0 / (r - l)
    m[1, 1] = 2.0 / (t - b)
    m[2, 0] = (r + l) / (r - l)
    m[2, 1] = (t + b) / (t - b)
    m[2, 2] = -(far + near) / (far - near)
    m[2, 3] = -1.0
    m[3, 2] = -2.0 * far * near / (far - near)
    return m
