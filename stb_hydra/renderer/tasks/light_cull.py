"""CPU light culling: influence spheres against the view frustum (vectorised) ->
the frame's ``InViewLights`` (rows in light-buffer order + feature flags)."""

from __future__ import annotations

import numpy as np

from ...scene.prims import CONE_CUTOFF_TEST_RAD
from ..frame import FrameContext
from ..graph import Imported, Rec
from ..light_buffer import cull_lights
from ..records import InViewLights
from .base import Pass


class LightCullTask(Pass):
    name = "light_cull"
    reads = (Imported("light_table"),)
    writes = (Rec(InViewLights),)

    def prepare(self, frame: FrameContext) -> None:
        t = self.delegate.light_table
        rows = cull_lights(t, frame.view.frustum_planes())
        rows = rows[~t.baked[rows]]  # baked lights come from the lightmaps (tasks/lightmap.py)
        frame.put(
            InViewLights(
                rows=rows,
                has_cones=bool(np.any(t.cone_cutoff[rows] < np.float32(CONE_CUTOFF_TEST_RAD))),
                has_ies=bool(np.any(t.ies_layer[rows] >= 0)),
            )
        )
        frame.stats["fov_lights"] = len(rows)
