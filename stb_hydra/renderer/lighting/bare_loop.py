"""`bare`: the bare light loop, a yardstick for `stb bench` (issue 34).

Every FoV-culled light of the shared light buffer evaluated per pixel as an unshadowed
point light: Lambert x inverse square x the range window (``shaders/bare_loop.frag``).
No shapes, cones, IES, specular, shadows, sun or links: the least work a correct
per-pixel light loop does, so that the exact methods' cost per light-pixel can be read
as a ratio to the machine's own loop in the same run (``stb bench --methods
bare,reference``). Its image is right only for unshadowed, isotropic point lights on
Lambert surfaces; no test checks it yet.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .base import LightingMethod, program

if TYPE_CHECKING:
    from ..frame import FrameContext


class BareLoopLighting(LightingMethod):
    name = "bare"

    def execute(self, frame: FrameContext) -> None:
        prog = program(frame, "bare_loop.frag", self.lighting_defines(frame, {}))
        self.bind_common(frame, prog)
        self.fullscreen_pass(frame, prog, "lighting")
