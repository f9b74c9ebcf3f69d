"""`reference`: every FoV-culled light evaluated per pixel (exact, O(lights)).
Shadows of local lights come from the shared shadow functions (unshadowed until
the shadow atlas exists). This is the ground truth other methods are measured
against."""

from __future__ import annotations

from typing import TYPE_CHECKING

from .base import LightingMethod, program

if TYPE_CHECKING:
    from ..frame import FrameContext


class ReferenceLighting(LightingMethod):
    name = "reference"
    points_first = True
    area_shadows_per_frame = True

    def execute(self, frame: FrameContext) -> None:
        defines = self.scene_defines(frame)
        if frame.light_count:
            defines["LOCAL_LIGHTS"] = True
        prog = program(frame, "lighting_direct.frag", self.lighting_defines(frame, defines))
        self.bind_common(frame, prog)
        self.fullscreen_pass(frame, prog, "lighting")
