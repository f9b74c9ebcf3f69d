"""`reference`: every FoV-culled light evaluated per pixel (exact, O(lights)).
Shadows of local lights come from the shared shadow functions (unshadowed until
the shadow atlas exists). A textured dome is importance-sampled, each sample with
its own shadow map (``renderer/dome_shadows.py``). This is the ground truth other
methods are measured against."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from ..dome_shadows import DomeSamples, DomeShadowMaps
from ..records import DistantLights
from .base import LightingMethod, program

if TYPE_CHECKING:
    from ..frame import FrameContext


class ReferenceLighting(LightingMethod):
    name = "reference"
    points_first = True
    area_shadows_per_frame = True
    dome_occlusion = False  # the dome is importance-sampled with its own shadow maps
    exact_rect_textures = True

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._dome: DomeShadowMaps | None = None

    def execute(self, frame: FrameContext) -> None:
        defines = self.scene_defines(frame)
        if frame.light_count:
            defines["LOCAL_LIGHTS"] = True
        samples = self._dome_samples(frame)
        if samples is not None:
            defines["DOME_SAMPLED"] = True
            if frame.get(DistantLights).dome_sun:
                defines["DOME_SUN_SAMPLED"] = True  # the sun is in the samples
        prog = program(frame, "lighting_direct.frag", self.lighting_defines(frame, defines))
        unit = self.bind_common(frame, prog)
        if samples is not None and self._dome is not None:
            self._dome.bind(prog, samples, unit)
        self.fullscreen_pass(frame, prog, "lighting")

    def _dome_samples(self, frame: FrameContext) -> DomeSamples | None:
        """Draw this frame's dome directions and render their shadow maps (a textured
        dome; None otherwise)."""
        dome = frame.get(DistantLights).dome
        d = self.delegate
        if dome is None or d is None:
            return None
        if self._dome is None:
            self._dome = DomeShadowMaps(frame.ctx)
        samples = self._dome.draw_samples(dome, frame.seed, frame.sample_index)
        if samples is None:
            return None
        mask = int(dome.shadow_link_mask) if dome.shadow_enable else 0
        self._dome.render(d, samples, mask)
        return samples

    def release(self) -> None:
        if self._dome is not None:
            self._dome.release()
            self._dome = None
