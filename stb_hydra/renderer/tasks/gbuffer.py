"""G-buffer task: linear depth (r32f), octahedral normal, base colour + roughness,
F0 + metallic, motion vectors (px) and emission (nits) + occlusion in one MRT pass;
with light linking (some light lights less than everything) also each pixel's link
group (``g_link``, r8ui: compiled and allocated only for such scenes).

Batches whose material reads textures, primvars, a normal map or cuts out draw with
the ``HAS_MATERIAL_TEXTURES`` variant of the program (compiled only when a scene has
such a batch); the others with the constant-only program."""

from __future__ import annotations

import moderngl

from ..frame import FrameContext
from ..gl import set_uniform, shader_library
from ..graph import Imported, Rec, Resource, Tex
from ..material_binding import bind_material, unbind_samplers
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
        lib = shader_library(ctx)
        base_defines: dict[str, object] = link_defines() if links else {}
        plain = lib.program("gbuffer.vert", "gbuffer.frag", base_defines or None)
        textured: moderngl.Program | None = None
        delegate = self.delegate
        cache = delegate.textures
        for b in delegate.batches:
            m = b.material
            prog = plain
            if m.textured:
                if textured is None:
                    defines = {**base_defines, "HAS_MATERIAL_TEXTURES": True}
                    textured = lib.program("gbuffer.vert", "gbuffer.frag", defines)
                prog = textured
            bind_material(prog, m, cache)
            if links:
                set_uniform(prog, "u_link_group", b.links[0])
            delegate.vertex_array(b, prog).render(moderngl.TRIANGLES, instances=b.count)
        if textured is not None:
            unbind_samplers(ctx)
        ctx.disable(moderngl.DEPTH_TEST)
