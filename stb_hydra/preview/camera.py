"""The previewer's free camera: an orbit about a pivot (usdview's model).

Render frame: Y up, metres, row-vector matrices (``p' = p @ M``), the camera
looking down its local -Z. Angles in degrees; drags in window pixels.

* tumble (Alt+LMB): yaw about +Y and pitch about the camera's right axis;
* track (Alt+MMB): the pivot moves in the view plane so that the point under the
  cursor follows it;
* dolly (Alt+RMB, wheel): the distance to the pivot scales exponentially;
* frame (F, A): the pivot at a box's centre, the box's bounding sphere filling
  the smaller field of view;
* fly (WASD, Q/E): the pivot and the eye move together.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ..scene.prims import CameraPrim
from ..shadows.capture import look_at

#: Tumble rate (degrees per pixel of drag), usdview's 0.25.
TUMBLE_DEG_PER_PX = 0.25
#: Dolly: the distance scales by exp(-DOLLY_PER_PX * px) for a drag of px pixels
#: (right/down = closer), and by exp(-DOLLY_PER_WHEEL * steps) per wheel step.
DOLLY_PER_PX = 0.005
DOLLY_PER_WHEEL = 0.15
#: Pitch stays this far (degrees) from the poles (look_at is singular there).
PITCH_LIMIT_DEG = 89.0
#: Framing: the bounding sphere is padded by this factor.
FRAME_PADDING = 1.05


@dataclass
class OrbitCamera:
    """Eye = pivot + distance * (cos p sin y, sin p, cos p cos y)."""

    pivot: np.ndarray
    distance: float
    yaw: float = 35.0
    pitch: float = -20.0
    #: Lens: focal length and horizontal aperture (mm); vertical from the aspect.
    focal_length: float = 35.0
    horizontal_aperture: float = 36.0
    #: Radius (m) of the scene's bounding sphere: sets the clipping range.
    scene_radius: float = 1.0

    # -- derived --
    def direction(self) -> np.ndarray:
        """Unit vector from the pivot to the eye."""
        y, p = math.radians(self.yaw), math.radians(self.pitch)
        return np.array([math.cos(p) * math.sin(y), -math.sin(p), math.cos(p) * math.cos(y)])

    def eye(self) -> np.ndarray:
        return np.asarray(self.pivot, dtype=np.float64) + self.distance * self.direction()

    def transform(self) -> np.ndarray:
        """Camera-to-world (row-vector 4x4)."""
        return look_at(self.eye(), self.pivot)

    def half_fov(self, aspect: float) -> tuple[float, float]:
        """Half field of view (radians), horizontal and vertical."""
        tx = 0.5 * self.horizontal_aperture / self.focal_length
        return math.atan(tx), math.atan(tx / max(aspect, 1e-6))

    def to_prim(self, aspect: float) -> CameraPrim:
        """The camera as a :class:`CameraPrim` for the engine."""
        cam = CameraPrim(path="/__stb_preview_camera")
        cam.focal_length = self.focal_length
        cam.horizontal_aperture = self.horizontal_aperture
        cam.vertical_aperture = self.horizontal_aperture / max(aspect, 1e-6)
        cam.transform = self.transform()
        r = max(self.scene_radius, 1e-3)
        far = self.distance + 4.0 * r
        cam.far = far
        cam.near = max(
            far * 1e-5, min(self.distance * 0.05, max(self.distance - 2.0 * r, 0.0)), 1e-3
        )
        return cam

    # -- usdview's gestures --
    def tumble(self, dx: float, dy: float) -> None:
        """Drag of (dx, dy) pixels (right, down): the eye orbits the pivot."""
        self.yaw = (self.yaw - TUMBLE_DEG_PER_PX * dx) % 360.0
        self.pitch = float(
            np.clip(self.pitch + TUMBLE_DEG_PER_PX * dy, -PITCH_LIMIT_DEG, PITCH_LIMIT_DEG)
        )

    def track(self, dx: float, dy: float, viewport_height: int, aspect: float) -> None:
        """Drag of (dx, dy) pixels: the pivot moves so the scene follows the cursor
        at the pivot's depth."""
        _, hy = self.half_fov(aspect)
        m_per_px = 2.0 * self.distance * math.tan(hy) / max(viewport_height, 1)
        t = self.transform()
        right, up = t[0, :3], t[1, :3]
        self.pivot = np.asarray(self.pivot, dtype=np.float64) + m_per_px * (-dx * right + dy * up)

    def dolly(self, px: float = 0.0, wheel: float = 0.0) -> None:
        """Alt+RMB drag of ``px`` pixels (right/down = closer) or ``wheel`` steps
        (up = closer): the eye moves along the view axis, never through the pivot."""
        k = math.exp(-DOLLY_PER_PX * px - DOLLY_PER_WHEEL * wheel)
        self.distance = float(np.clip(self.distance * k, 1e-4, 1e7))

    def fly(self, forward: float, right: float, up: float) -> None:
        """Move eye and pivot together (metres, camera axes; +Y world up)."""
        t = self.transform()
        d = -forward * t[2, :3] + right * t[0, :3] + up * np.array([0.0, 1.0, 0.0])
        self.pivot = np.asarray(self.pivot, dtype=np.float64) + d

    def frame(self, lo: npt.ArrayLike, hi: npt.ArrayLike, aspect: float) -> None:
        """Pivot at the box's centre; distance so its bounding sphere fits the
        smaller half field of view (padded by FRAME_PADDING). Keeps yaw and pitch."""
        lo_, hi_ = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
        if not (np.all(np.isfinite(lo_)) and np.all(np.isfinite(hi_))) or np.any(hi_ < lo_):
            return
        r = max(0.5 * float(np.linalg.norm(hi_ - lo_)), 1e-3)
        self.pivot = 0.5 * (lo_ + hi_)
        self.distance = r / math.sin(min(self.half_fov(aspect))) * FRAME_PADDING
        self.scene_radius = max(self.scene_radius, r)

    @classmethod
    def framing(cls, lo: npt.ArrayLike, hi: npt.ArrayLike, aspect: float) -> OrbitCamera:
        """A camera framing the box from a raised three-quarter view."""
        cam = cls(pivot=np.zeros(3), distance=1.0)
        cam.frame(lo, hi, aspect)
        return cam

    @classmethod
    def from_prim(cls, prim: CameraPrim, pivot_distance: float, scene_radius: float) -> OrbitCamera:
        """The free camera taking over a stage camera's view (its lens, position and
        direction; the pivot ``pivot_distance`` metres ahead)."""
        t = np.asarray(prim.transform, dtype=np.float64)
        fwd = -t[2, :3] / max(float(np.linalg.norm(t[2, :3])), 1e-30)
        eye = t[3, :3]
        d = -fwd  # pivot -> eye
        pitch = -math.degrees(math.asin(float(np.clip(d[1], -1.0, 1.0))))
        yaw = math.degrees(math.atan2(d[0], d[2]))
        ap = prim.horizontal_aperture if prim.projection == "perspective" else 36.0
        fl = prim.focal_length if prim.projection == "perspective" else 35.0
        return cls(
            pivot=eye + fwd * pivot_distance,
            distance=float(pivot_distance),
            yaw=yaw % 360.0,
            pitch=float(np.clip(pitch, -PITCH_LIMIT_DEG, PITCH_LIMIT_DEG)),
            focal_length=fl,
            horizontal_aperture=ap,
            scene_radius=scene_radius,
        )
