"""`sun`: the shadowed sun + dome ambient only (the talk's "sun-only" baseline)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from .base import LightingMethod, program

if TYPE_CHECKING:
    from ..frame import FrameContext


class SunOnlyLighting(LightingMethod):
    name = "sun"
    uses_local_lights = False

    def execute(self, frame: FrameContext) -> None:
        prog = program(frame, "lighting_direct.frag", self.lighting_defines(frame))
        self.bind_common(frame, prog)
        self.fullscreen_pass(frame, prog, "lighting")
