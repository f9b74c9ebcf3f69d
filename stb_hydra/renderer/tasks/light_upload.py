"""Light-buffer commit: packs the in-view lights with their shadow-map slots into
the delegate's light SSBO (binding 0), uploading only what changed; with light linking
also the link SSBO (``renderer/link_masks.py``: the lights' masks in the same order,
the distant lights' masks, ambient per link group)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..frame import FrameContext
from ..graph import Imported, Rec
from ..link_masks import LinkBufferUploader, pack_link_buffer
from ..records import DistantLights, InViewLights, LightBuffer, ShadowSlots
from .base import Pass

if TYPE_CHECKING:
    from ..gl_delegate import GLRenderDelegate


class LightUploadTask(Pass):
    name = "light_upload"
    reads = (Imported("light_table"), Rec(InViewLights), Rec(ShadowSlots), Rec(DistantLights))
    writes = (Rec(LightBuffer),)

    def __init__(self, delegate: GLRenderDelegate) -> None:
        super().__init__(delegate)
        self.links = LinkBufferUploader()

    def prepare(self, frame: FrameContext) -> None:
        lights = frame.get(InViewLights)
        slots = frame.get(ShadowSlots)
        uploaded = self.delegate.upload_lights(lights.rows, slots.maps)
        frame.stats["light_upload"] = uploaded
        t = self.delegate.light_table
        links = t.has_light_links()
        link_ssbo = None
        if links:
            words = pack_link_buffer(
                t, lights.rows, frame.get(DistantLights), frame.settings.ambient
            )
            link_ssbo = self.links.upload(frame.ctx, words)
        frame.put(
            LightBuffer(
                ssbo=self.delegate.light_ssbo,
                count=lights.count,
                has_shadows=slots.any,
                uploaded=uploaded,
                links=links,
                link_ssbo=link_ssbo,
            )
        )

    def release(self) -> None:
        self.links.release()
