"""G-buffer task: linear depth (r32f), octahedral normal, base colour + roughness,
F0 + metallic, motion vectors (px) and emission (nits) + occlusion in one MRT pass;
with light linking (some light lights less than everything) also each pixel's link
group (``g_link``, r8ui), with a clearcoated material the coat's weight and roughness
(``g_coat``, rg16f): each compiled and allocated only for such scenes.

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
#: Clearcoat weight and roughness, after the link target (scenes with a coated material).
COAT_TARGET = Tex("g_coat", "rg16f")


def link_defines() -> dict[str, object]:
    """``gbuffer.frag``'s defines with light linking."""
    return {"HAS_LINKS": True, "LINK_TARGET_LOCATION": len(GBUFFER_TARGETS)}


def optional_targets(links: bool, coat: bool) -> tuple[tuple[Tex, ...], dict[str, object]]:
    """The optional targets a scene needs, in attachment order, and their defines."""
    targets: list[Tex] = []
    defines: dict[str, object] = {}
    if links:
        defines.update(link_defines())
        targets.append(LINK_TARGET)
    if coat:
        defines["HAS_CLEARCOAT"] = True
        defines["COAT_TARGET_LOCATION"] = len(GBUFFER_TARGETS) + len(targets)
        targets.append(COAT_TARGET)
    return tuple(targets), defines


class GBufferTask(Pass):
    name = "gbuffer"
    reads = (Imported("meshes"), Rec(FrameBlock))
    writes = (*GBUFFER_TARGETS, Tex("g_zbuffer", "depth24"))

    def _optional(self) -> tuple[bool, tuple[Tex, ...], dict[str, object]]:
        links = self.delegate.light_table.has_light_links()
        extra, defines = optional_targets(links, self.delegate.has_clearcoat)
        return links, extra, defines

    def io(self) -> tuple[tuple[Resource, ...], tuple[Resource, ...]]:
        _links, extra, _d = self._optional()
        return self.reads, (*self.writes, *extra)

    def execute(self, frame: FrameContext) -> None:
        ctx = frame.ctx
        bufs = frame.buffers
        links, extra, base_defines = self._optional()
        names = [t.name for t in GBUFFER_TARGETS] + [t.name for t in extra]
        fbo_key = "gbuffer" + "".join("_" + t.name for t in extra)
        fbo = bufs.framebuffer(fbo_key, names, "g_zbuffer")
        fbo.use()
        ctx.viewport = (0, 0, *bufs.size)
        fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        ctx.enable(moderngl.DEPTH_TEST)
        ctx.disable(moderngl.CULL_FACE | moderngl.BLEND)
        lib = shader_library(ctx)
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
