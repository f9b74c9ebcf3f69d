"""CPU light culling: influence spheres against the view frustum (vectorised) ->
the frame's ``InViewLights`` (rows in light-buffer order + feature flags)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ... import limits
from ...scene.prims import CONE_CUTOFF_TEST_RAD
from .. import shader_constants as sc
from ..frame import FrameContext
from ..graph import Imported, Rec
from ..light_buffer import by_light_model, cull_lights, narrow_spheres, unshadowed_first
from ..material_binding import alpha_floor
from ..records import InViewLights
from .base import Pass

if TYPE_CHECKING:
    from ..gl_delegate import GLRenderDelegate


class LightCullTask(Pass):
    name = "light_cull"
    reads = (Imported("light_table"),)
    writes = (Rec(InViewLights),)

    def __init__(self, delegate: GLRenderDelegate, points_first: bool = False) -> None:
        super().__init__(delegate)
        #: Order the in-view lights point lights first, then sphere lights
        #: (``InViewLights.point_count``, ``sphere_count``): the exact methods ask for it
        #: (``LightingMethod.points_first``).
        self.points_first = points_first
        self._alpha_key: tuple[int, int] | None = None
        self._alpha = limits.GGX_ALPHA_MIN
        #: The last narrow-sphere mask and what it was computed from (:meth:`_narrow`).
        self._narrow_key: tuple | None = None
        self._narrow_mask = np.zeros(0, dtype=bool)

    def prepare(self, frame: FrameContext) -> None:
        t = self.delegate.light_table
        rows = cull_lights(t, frame.view.frustum_planes())
        rows = rows[~t.baked[rows]]  # baked lights come from the lightmaps (tasks/lightmap.py)
        point_count = sphere_count = wide_count = sphere_unshadowed = tail_unshadowed = 0
        if self.points_first:
            narrow = None
            if np.any(t.area_kind[rows] == sc.AREA_SPHERE):
                narrow = self._narrow(rows)
            rows, point_count, sphere_count, wide_count = by_light_model(t, rows, narrow)
            rows, sphere_unshadowed, tail_unshadowed = unshadowed_first(
                t, rows, point_count, sphere_count
            )
        frame.put(
            InViewLights(
                rows=rows,
                has_cones=bool(np.any(t.cone_cutoff[rows] < np.float32(CONE_CUTOFF_TEST_RAD))),
                has_ies=bool(np.any(t.ies_layer[rows] >= 0)),
                has_focus=bool(np.any(t.focus[rows] > 0)),
                has_cylinders=bool(np.any(t.area_kind[rows] == sc.AREA_CYLINDER)),
                has_rect_textures=bool(np.any(t.texture_layer[rows] >= 0)),
                point_count=point_count,
                sphere_count=sphere_count,
                wide_sphere_count=wide_count,
                sphere_unshadowed=sphere_unshadowed,
                tail_unshadowed=tail_unshadowed,
            )
        )
        frame.stats["fov_lights"] = len(rows)

    def _narrow(self, rows: np.ndarray) -> np.ndarray:
        """``narrow_spheres`` over ``rows``, recomputed only when its inputs changed: the
        (lights x receiver boxes) distances cost ~70 ms of CPU per 256 boxes at 5,000
        lights on this machine, every frame otherwise."""
        t = self.delegate.light_table
        boxes = self._mesh_boxes()
        alpha = self._alpha_min()
        cols = (t.position, t.area_kind, t.area_size, t.specular)
        key = (boxes, alpha, rows.tobytes(), *(hash(c[rows].tobytes()) for c in cols))
        old = self._narrow_key
        if old is None or old[0] is not boxes or old[1:] != key[1:]:
            lo, hi, box_alpha = boxes
            self._narrow_mask = narrow_spheres(t, rows, lo, hi, alpha, box_alpha)
            self._narrow_key = key
        return self._narrow_mask

    def _mesh_boxes(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """World AABBs (render frame, m) that hold every drawn triangle, (B, 3) each:
        each mesh's leaf boxes per instance (``delegate.receiver_boxes``,
        ``renderer/receiver_bounds.py``), finer than a mesh's AABB (a mesh of scattered
        boxes spans them all) and than the draw batches' (issue 34 item 2); and (B,) the
        smallest GGX alpha of each box's material (``material_binding.alpha_floor``)."""
        return self.delegate.receiver_boxes

    def _alpha_min(self) -> float:
        """Smallest GGX alpha any drawn surface can have (common/gbuffer.glsl: roughness
        squared, clamped; a roughness texture or primvar may reach the clamp; the 8-bit
        G-buffer target may round a constant down by half a step)."""
        d = self.delegate
        key = id(d.batches), len(d.batches)
        if self._alpha_key != key:
            a = min((alpha_floor(b.material) for b in d.batches), default=1.0)
            self._alpha_key, self._alpha = key, max(a, limits.GGX_ALPHA_MIN)
        return self._alpha
