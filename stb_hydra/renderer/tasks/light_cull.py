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
from ..light_buffer import by_light_model, cull_lights, narrow_spheres
from ..material_binding import SLOT_OF
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
        self._boxes_key: object = None
        self._boxes = (np.zeros((0, 3)), np.zeros((0, 3)))
        self._alpha = limits.GGX_ALPHA_MIN

    def prepare(self, frame: FrameContext) -> None:
        t = self.delegate.light_table
        rows = cull_lights(t, frame.view.frustum_planes())
        rows = rows[~t.baked[rows]]  # baked lights come from the lightmaps (tasks/lightmap.py)
        point_count = sphere_count = wide_count = 0
        if self.points_first:
            narrow = None
            if np.any(t.area_kind[rows] == sc.AREA_SPHERE):
                lo, hi = self._mesh_boxes()
                narrow = narrow_spheres(t, rows, lo, hi, self._alpha_min())
            rows, point_count, sphere_count, wide_count = by_light_model(t, rows, narrow)
        frame.put(
            InViewLights(
                rows=rows,
                has_cones=bool(np.any(t.cone_cutoff[rows] < np.float32(CONE_CUTOFF_TEST_RAD))),
                has_ies=bool(np.any(t.ies_layer[rows] >= 0)),
                has_focus=bool(np.any(t.focus[rows] > 0)),
                has_rect_textures=bool(np.any(t.texture_layer[rows] >= 0)),
                point_count=point_count,
                sphere_count=sphere_count,
                wide_sphere_count=wide_count,
            )
        )
        frame.stats["fov_lights"] = len(rows)

    def _mesh_boxes(self) -> tuple[np.ndarray, np.ndarray]:
        """World AABBs (render frame, m) of the drawn meshes, (M, 3) each: finer than the
        draw batches' (a batch spans every mesh that shares its material)."""
        mb = self.delegate.mesh_bounds
        if self._boxes_key is not mb:
            v = list(mb.values())
            lo = np.array([b[0] for b in v], dtype=np.float64).reshape(-1, 3)
            hi = np.array([b[1] for b in v], dtype=np.float64).reshape(-1, 3)
            self._boxes_key, self._boxes = mb, (lo, hi)
        return self._boxes

    def _alpha_min(self) -> float:
        """Smallest GGX alpha any drawn surface can have (common/gbuffer.glsl: roughness
        squared, clamped; a roughness texture or primvar may reach the clamp; the 8-bit
        G-buffer target may round a constant down by half a step)."""
        d = self.delegate
        key = id(d.batches), len(d.batches)
        if self._alpha_key != key:
            slot = SLOT_OF["roughness"]
            a = 1.0
            for b in d.batches:
                m = b.material
                if m.textures[slot] is not None or m.pv1_slot == slot:
                    a = limits.GGX_ALPHA_MIN
                    break
                r = max(float(m.roughness) - 1.0 / 255.0, 0.0)
                a = min(a, r * r)
            self._alpha_key, self._alpha = key, max(a, limits.GGX_ALPHA_MIN)
        return self._alpha
