"""CPU light culling: influence spheres against the view frustum (vectorised) ->
the frame's ``InViewLights`` (rows in light-buffer order + feature flags)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ...scene.prims import CONE_CUTOFF_TEST_RAD
from ..frame import FrameContext
from ..graph import Imported, Rec
from ..light_buffer import cull_lights, points_first
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
        #: Order the in-view lights point lights first (``InViewLights.point_count``):
        #: the exact methods ask for it (``LightingMethod.points_first``).
        self.points_first = points_first

    def prepare(self, frame: FrameContext) -> None:
        t = self.delegate.light_table
        rows = cull_lights(t, frame.view.frustum_planes())
        rows = rows[~t.baked[rows]]  # baked lights come from the lightmaps (tasks/lightmap.py)
        point_count = 0
        if self.points_first:
            rows, point_count = points_first(t, rows)
        frame.put(
            InViewLights(
                rows=rows,
                has_cones=bool(np.any(t.cone_cutoff[rows] < np.float32(CONE_CUTOFF_TEST_RAD))),
                has_ies=bool(np.any(t.ies_layer[rows] >= 0)),
                has_rect_textures=bool(np.any(t.texture_layer[rows] >= 0)),
                point_count=point_count,
            )
        )
        frame.stats["fov_lights"] = len(rows)
