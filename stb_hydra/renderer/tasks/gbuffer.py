"""G-buffer task: linear depth (r32f), octahedral normal, base colour + roughness,
F0 + metallic, motion vectors (px) and emission (nits) in one MRT pass; with light
linking (some light lights less than everything) also each pixel's link group
(``g_link``, r8ui: compiled and allocated only for such scenes)."""

from __future__ import annotations

import moderngl

from ..frame import FrameContext
from ..gl import set_uniform, shader_library
from ..graph import Imported, Rec, Resource, Tex
from ..records import FrameBlock
from .base import Pass

#: The MRT targets, in attachment order (``gbuffer.frag`` outputs).
GBUFFER_TARGETS = (
    Tex("g_depth", "r32f"),
    Tex("g_normal", "rg16f"),
    Tex("g_base_rough", "rgba16f"),
    Tex("g_f0_metal", "rgba16f"),
    Tex("g_motion", "rg16f"),
    Tex("g_emission", "rgba16f"),
)
#: The link-group target (``scene/links.py``), after the others.
LINK_TARGET = Tex("g_link", "r8ui")


def link_defines() -> dict[str, object]:
    """``gbuffer.frag``'s defines with light linking."""
    return {"HAS_LINKS": True, "LINK_TARGET_LOCATION": len(GBUFFER_TARGETS)}


class GBufferTask(Pass):
    name = "gbuffer"
    reads = (Imported("meshes"), Rec(FrameBlock))
    writes = (*GBUFFER_TARGETS, Tex("g_zbuffer", "depth24"))

    def io(self) -> tuple[tuple[Resource, ...], tuple[Resource, ...]]:
        links = self.delegate.light_table.has_light_links()
        return self.reads, (*self.writes, LINK_TARGET) if links else self.writes

    def execute(self, frame: FrameContext) -> None:
        ctx = frame.ctx
        bufs = frame.buffers
        links = self.delegate.light_table.has_light_links()
        names = [t.name for t in GBUFFER_TARGETS] + ([LINK_TARGET.name] if links else [])
        fbo = bufs.framebuffer("gbuffer_links" if links else "gbuffer", names, "g_zbuffer")
        fbo.use()
        ctx.viewport = (0, 0, *bufs.size)
        fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE | moderngl.BLEND)
        prog = shader_library(ctx).program(
            "gbuffer.vert", "gbuffer.frag", link_defines() if links else None
        )
        delegate = self.delegate
        for b in delegate.batches:
            m = b.material
            set_uniform(prog, "u_base_color", m.base)
            set_uniform(prog, "u_use_vertex_color", 1.0 if m.use_vertex_color else 0.0)
            set_uniform(prog, "u_roughness", m.roughness)
            set_uniform(prog, "u_metallic", m.metallic)
            set_uniform(prog, "u_specular_workflow", 1.0 if m.specular_workflow else 0.0)
            set_uniform(prog, "u_specular_color", m.specular_color)
            set_uniform(prog, "u_emissive", m.emissive)
            if links:
                set_uniform(prog, "u_link_group", b.links[0])
            delegate.vertex_array(b, prog).render(moderngl.TRIANGLES, instances=b.count)
        ctx.disable(moderngl.DEPTH_TEST)
