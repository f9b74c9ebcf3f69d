"""G-buffer task: linear depth (r32f), octahedral normal, base colour + roughness,
F0 + metallic, motion vectors (px) and emission (nits) in one MRT pass."""

from __future__ import annotations

import moderngl

from ..gl import set_uniform, shader_library
from .base import Task

#: (name, components, dtype)
GBUFFER_TARGETS = (
    ("g_depth", 1, "f4"),
    ("g_normal", 2, "f2"),
    ("g_base_rough", 4, "f2"),
    ("g_f0_metal", 4, "f2"),
    ("g_motion", 2, "f2"),
    ("g_emission", 4, "f2"),
)


class GBufferTask(Task):
    name = "gbuffer"

    def execute(self, frame) -> None:
        ctx = frame.ctx
        bufs = frame.buffers
        for name, comps, dtype in GBUFFER_TARGETS:
            bufs.texture(name, comps, dtype)
        zbuf = bufs.textures.get("g_zbuffer")
        if zbuf is None or zbuf.size != bufs.size:
            bufs.set_texture("g_zbuffer", ctx.depth_texture(bufs.size))
        fbo = bufs.framebuffer("gbuffer", [n for n, _, _ in GBUFFER_TARGETS], "g_zbuffer")
        fbo.use()
        ctx.viewport = (0, 0, *bufs.size)
        fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE | moderngl.BLEND)
        prog = shader_library(ctx).program("gbuffer.vert", "gbuffer.frag")
        delegate = self.engine.delegate
        for b in delegate.batches:
            m = b.material
            set_uniform(prog, "u_base_color", m.base)
            set_uniform(prog, "u_use_vertex_color", 1.0 if m.use_vertex_color else 0.0)
            set_uniform(prog, "u_roughness", m.roughness)
            set_uniform(prog, "u_metallic", m.metallic)
            set_uniform(prog, "u_specular_workflow", 1.0 if m.specular_workflow else 0.0)
            set_uniform(prog, "u_specular_color", m.specular_color)
            set_uniform(prog, "u_emissive", m.emissive)
            delegate.vertex_array(b, prog).render(moderngl.TRIANGLES, instances=b.count)
        ctx.disable(moderngl.DEPTH_TEST)
