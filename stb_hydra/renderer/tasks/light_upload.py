"""Light-buffer commit: packs the in-view lights with their shadow-map slots into
the delegate's light SSBO (binding 0), uploading only what changed."""

from __future__ import annotations

from ..frame import FrameContext
from ..graph import Imported, Rec
from ..records import InViewLights, LightBuffer, ShadowSlots
from .base import Pass


class LightUploadTask(Pass):
    name = "light_upload"
    reads = (Imported("light_table"), Rec(InViewLights), Rec(ShadowSlots))
    writes = (Rec(LightBuffer),)

    def prepare(self, frame: FrameContext) -> None:
        lights = frame.get(InViewLights)
        slots = frame.get(ShadowSlots)
        uploaded = self.delegate.upload_lights(lights.rows, slots.maps)
        frame.stats["light_upload"] = uploaded
        frame.put(
            LightBuffer(
                ssbo=self.delegate.light_ssbo,
                count=lights.count,
                has_shadows=slots.any,
                uploaded=uploaded,
            )
        )
