"""CPU light culling: influence spheres against the view frustum (vectorised),
then the FoV light buffer upload (only when something changed)."""

from __future__ import annotations

from .base import Task


class LightCullTask(Task):
    name = "light_cull"

    def prepare(self, frame) -> None:
        d = self.engine.delegate
        uploaded = d.update_fov_lights(frame.view.frustum_planes())
        frame.light_count = len(d.fov_rows)
        frame.stats["fov_lights"] = frame.light_count
        frame.stats["light_upload"] = uploaded
