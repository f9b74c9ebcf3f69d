"""CPU light culling: influence spheres against the view frustum (vectorised).
The FoV light buffer is uploaded in the commit phase (``GLRenderDelegate.
upload_fov_lights``), after the shadow task assigned shadow maps."""

from __future__ import annotations

from .base import Task


class LightCullTask(Task):
    name = "light_cull"

    def prepare(self, frame) -> None:
        d = self.engine.delegate
        d.cull_fov(frame.view.frustum_planes())
        frame.light_count = len(d.fov_rows)
        frame.stats["fov_lights"] = frame.light_count
