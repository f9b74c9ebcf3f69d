"""Lighting-method interface. A method turns the G-buffer (+ lights, shadows) into
scene-linear radiance in the 'lighting' buffer. Methods share the BRDF, light,
IES and shadow includes, so images compare pixel for pixel."""

from __future__ import annotations

from typing import TYPE_CHECKING

import moderngl

from ..gl import set_uniform, shader_library

if TYPE_CHECKING:
    from ..engine import Engine
    from ..frame import FrameContext

GBUFFER_SAMPLERS = ("g_depth", "g_normal", "g_base_rough", "g_f0_metal", "g_emission")


class LightingMethod:
    name = "base"
    #: True when the method evaluates local lights (needs culling/light buffer).
    uses_local_lights = True

    def __init__(self, engine: Engine, **options) -> None:
        self.engine = engine
        self.options = options

    def scene_defines(self, frame: FrameContext) -> dict[str, object]:
        """Feature defines from what the scene has (compile only what is needed)."""
        d = self.engine.delegate
        defines: dict[str, object] = {}
        if frame.sun.enabled or frame.extra_distant:
            defines["HAS_SUN"] = True
        if frame.sun.enabled and frame.sun.shadow:
            defines["HAS_SUN_SHADOW"] = True
        if float(frame.ambient.max()) > 0:
            defines["HAS_AMBIENT"] = True
        if self.uses_local_lights and frame.light_count:
            if d.has_ies and d.fov_flags["ies"]:
                defines["HAS_IES"] = True
            if d.fov_flags["cones"]:
                defines["HAS_CONES"] = True
            if d.fov_flags["shadows"]:
                defines["HAS_SHADOWS"] = True
                if frame.settings.shadow_filter == "stochastic":
                    defines["STOCHASTIC_PCF"] = True
        return defines

    def bind_common(self, frame: FrameContext, prog: moderngl.Program, first_unit: int = 0) -> int:
        """Bind G-buffer samplers, light buffer, IES array, sun shadow. Returns next unit."""
        unit = first_unit
        bufs = frame.buffers
        for name in GBUFFER_SAMPLERS:
            if name in prog:
                bufs.textures[name].use(unit)
                prog[name].value = unit
                unit += 1
        d = self.engine.delegate
        if d.light_ssbo is not None:
            d.light_ssbo.bind_to_storage_buffer(0)
        if "u_ies" in prog and d.ies_texture is not None:
            d.ies_texture.use(unit)
            prog["u_ies"].value = unit
            unit += 1
        atlas = self.engine.task("shadow_atlas")
        if atlas is not None:
            unit = atlas.bind(prog, unit)
        sun = self.engine.task("shadow")
        if "u_sun_shadow" in prog and sun is not None and sun.texture is not None:
            sun.texture.use(unit)
            prog["u_sun_shadow"].value = unit
            unit += 1
        return unit

    def prepare(self, frame: FrameContext) -> None:
        pass

    def execute(self, frame: FrameContext) -> None:
        raise NotImplementedError

    def fullscreen_pass(self, frame: FrameContext, prog: moderngl.Program, target: str) -> None:
        ctx = frame.ctx
        fbo = frame.buffers.framebuffer("fb_" + target, [target])
        fbo.use()
        ctx.viewport = (0, 0, *frame.buffers.size)
        ctx.disable(moderngl.BLEND | moderngl.DEPTH_TEST)
        self.engine.fullscreen(prog).render(moderngl.TRIANGLES, vertices=3)

    def release(self) -> None:
        pass


def program(frame: FrameContext, frag: str, defines: dict[str, object]) -> moderngl.Program:
    return shader_library(frame.ctx).program("fullscreen.vert", frag, defines)


__all__ = ["LightingMethod", "program", "set_uniform"]
