"""G-buffer task: linear depth (r32f), octahedral normal, base colour + roughness,
F0 + metallic, motion vectors (px) and emission (nits) + occlusion in one MRT pass.

Batches whose material reads textures, primvars, a normal map or cuts out draw with
the ``HAS_MATERIAL_TEXTURES`` variant of the program (compiled only when a scene has
such a batch); the others with the constant-only program."""

from __future__ import annotations

import moderngl

from ..frame import FrameContext
from ..gl import shader_library
from ..graph import Imported, Rec, Tex
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


class GBufferTask(Pass):
    name = "gbuffer"
    reads = (Imported("meshes"), Rec(FrameBlock))
    writes = (*GBUFFER_TARGETS, Tex("g_zbuffer", "depth24"))

    def execute(self, frame: FrameContext) -> None:
        ctx = frame.ctx
        bufs = frame.buffers
        fbo = bufs.framebuffer("gbuffer", [t.name for t in GBUFFER_TARGETS], "g_zbuffer")
        fbo.use()
        ctx.viewport = (0, 0, *bufs.size)
        fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE | moderngl.BLEND)
        lib = shader_library(ctx)
        plain = lib.program("gbuffer.vert", "gbuffer.frag")
        textured: moderngl.Program | None = None
        delegate = self.delegate
        cache = delegate.textures
        for b in delegate.batches:
            m = b.material
            prog = plain
            if m.textured:
                if textured is None:
                    defines: dict[str, object] = {"HAS_MATERIAL_TEXTURES": True}
                    textured = lib.program("gbuffer.vert", "gbuffer.frag", defines)
                prog = textured
            bind_material(prog, m, cache)
            delegate.vertex_array(b, prog).render(moderngl.TRIANGLES, instances=b.count)
        if textured is not None:
            unbind_samplers(ctx)
        ctx.disable(moderngl.DEPTH_TEST)
