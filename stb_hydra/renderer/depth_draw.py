"""Depth-only draws of the delegate's batches with alpha-tested cut-outs.

Shadow maps (spot, omni per face and in one pass, the sun) draw every batch into
depth. A batch whose material cuts out (``opacityThreshold`` > 0) must leave its
cut cells out of the map too, so it draws with the ``ALPHA_TEST`` variant of the
same programs (``common/material.glsl``: its opacity slot, discard below the
threshold), compiled only when a scene has such a batch. :class:`DepthDraw` holds
the pair, sets a pass's uniforms on whichever is used and draws a batch with the
right one.
"""

from __future__ import annotations

import moderngl

from .gl import set_uniform, shader_library
from .gl_delegate import DrawBatch, GLRenderDelegate
from .material_binding import bind_material, unbind_samplers


class DepthDraw:
    """The plain and alpha-tested variants of one depth program."""

    def __init__(
        self, ctx: moderngl.Context, vertex: str, fragment: str, geometry: str | None = None
    ) -> None:
        self.ctx = ctx
        self._stages = (vertex, fragment, geometry)
        lib = shader_library(ctx)
        self.plain = lib.program(vertex, fragment, geometry=geometry)
        self._alpha: moderngl.Program | None = None
        self._uniforms: dict[str, object] = {}

    @property
    def alpha(self) -> moderngl.Program:
        if self._alpha is None:
            v, f, g = self._stages
            self._alpha = shader_library(self.ctx).program(v, f, {"ALPHA_TEST": True}, geometry=g)
        return self._alpha

    def set(self, name: str, value: object) -> None:
        """Set a uniform of the pass (on the plain program now, the alpha one when used)."""
        self._uniforms[name] = value
        set_uniform(self.plain, name, value)

    def program_for(self, delegate: GLRenderDelegate, b: DrawBatch) -> moderngl.Program:
        if not b.material.cutout:
            return self.plain
        prog = self.alpha
        for k, v in self._uniforms.items():
            set_uniform(prog, k, v)
        bind_material(prog, b.material, delegate.textures)
        return prog

    def draw(self, delegate: GLRenderDelegate, b: DrawBatch) -> None:
        prog = self.program_for(delegate, b)
        delegate.vertex_array(b, prog, depth_only=True).render(
            moderngl.TRIANGLES, instances=b.count
        )
        if prog is not self.plain:
            unbind_samplers(self.ctx)
