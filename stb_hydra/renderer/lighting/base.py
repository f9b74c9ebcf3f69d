"""The lighting-method contract. A method turns the G-buffer (+ lights, shadows)
into scene-linear radiance in the ``lighting`` buffer. Methods share the BRDF,
light, IES and shadow includes, so images compare pixel for pixel.

A method declares, as class-level data:

* ``name`` - its CLI name (``--lighting``), registered in ``lighting/__init__.py``;
* ``options`` - a :class:`~.options.Schema` (validated in one place; cross-option
  rules in ``check_options``);
* ``debug_aovs`` - the debug views it can draw (``stb render --aov``), each drawn by
  a pass from ``debug_passes()`` that joins the graph only when asked for;
* ``uses_local_lights`` and ``hiz_level`` - what the engine must schedule for it;
* ``internal`` - its own render buffers (``Tex`` writes of the lighting pass).

Its passes read the standard inputs in ``READS``; everything is bound through
``bind_common`` from the frame's records, never through the engine.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any, ClassVar, cast

import moderngl
import numpy as np

from ...scene import prims
from ..dome_shadows import SkyOcclusion
from ..fullscreen import draw_fullscreen
from ..gl import set_uniform, shader_library
from ..graph import Rec, Resource, Tex
from ..records import (
    DistantLights,
    FrameBlock,
    InViewLights,
    LightBuffer,
    ShadowSlots,
    SunShadowMap,
)
from ..shader_constants import SSBO_LIGHT_LINKS, SSBO_LIGHTS, SSBO_SHADOW_MAPS
from .options import Schema

if TYPE_CHECKING:
    from ...renderer.tasks.base import Pass
    from ..frame import FrameContext
    from ..gl_delegate import GLRenderDelegate

#: G-buffer textures the shared lighting code samples, with their formats.
GBUFFER_INPUTS: tuple[Tex, ...] = (
    Tex("g_depth", "r32f"),
    Tex("g_normal", "rg16f"),
    Tex("g_base_rough", "rgba16f"),
    Tex("g_f0_metal", "rgba16f"),
    Tex("g_emission", "rgba16f"),
)
GBUFFER_SAMPLERS = tuple(t.name for t in GBUFFER_INPUTS)
#: The pixel's light-link group (``tasks/gbuffer.LINK_TARGET``): read only by scenes
#: with light linking.
LINK_INPUT = Tex("g_link", "r8ui")
#: Clearcoat weight and roughness (``tasks/gbuffer.COAT_TARGET``): read only by scenes
#: with a coated material.
COAT_INPUT = Tex("g_coat", "rg16f")

#: What every lighting method reads.
READS: tuple[Resource, ...] = (
    *GBUFFER_INPUTS,
    Rec(FrameBlock),
    Rec(DistantLights),
    Rec(InViewLights),
    Rec(LightBuffer),
    Rec(ShadowSlots),
    Rec(SunShadowMap),
)

Warn = Callable[[str], None]

#: The exact methods' light loops by light model (issue 34), in light-buffer order
#: (``light_buffer.by_light_model``): model -> the define that compiles its loop into
#: lighting_direct.frag, tiled_lighting.frag and lighttree_lighting.frag.
LIGHT_LOOP_DEFINES: dict[str, str] = {
    "point": "LOOP_POINT",
    "sphere_narrow": "LOOP_SPHERE_NARROW",
    "sphere_wide": "LOOP_SPHERE_WIDE",
    "general": "LOOP_GENERAL",
}


def light_models(lights: InViewLights) -> frozenset[str]:
    """The light models (keys of :data:`LIGHT_LOOP_DEFINES`) with lights in
    ``lights``, from its partition's counts (``InViewLights.point_count`` ...); lights
    of a buffer that is not split by model are all ``general``."""
    n_rest = lights.count - lights.point_count - lights.sphere_count - lights.wide_sphere_count
    counts = {
        "point": lights.point_count,
        "sphere_narrow": lights.sphere_count,
        "sphere_wide": lights.wide_sphere_count,
        "general": n_rest,
    }
    return frozenset(m for m, c in counts.items() if c > 0)


def light_loops(models: frozenset[str], clearcoat: bool = False) -> frozenset[str]:
    """The loops an exact method's shader holds for lights of ``models``: each loop is
    inlined light code, and on llvmpipe four of them took a program's cold compile from
    ~8 s to 20-25 s (issue 34), so a loop is compiled only for a model the scene has,
    and the cheap loops only where they replace code: a point light takes the point
    loop, a narrow sphere the narrow loop (point model + closed-form diffuse), the
    rest the general ``light_radiance``; wide spheres (LTC over the silhouette) have
    their own loop only where there is no general loop, else they run in it (it
    handles every model with the same value, and the light order puts them just
    before the rest). With a clearcoat (``HAS_CLEARCOAT``) the sphere loops would
    inline the whole coated ``light_radiance`` again, so every sphere runs in the
    general loop. Every model in ``models`` is covered by one loop."""
    loops = set()
    if "point" in models:
        loops.add("point")
    spheres = models & {"sphere_narrow", "sphere_wide"}
    if clearcoat and spheres:
        loops.add("general")
    elif "sphere_narrow" in models:
        loops.add("sphere_narrow")
    if "general" in models:
        loops.add("general")
    elif "sphere_wide" in models and "general" not in loops:
        loops.add("sphere_wide")
    return frozenset(loops)


#: What the lighting pass also writes for the temporal pass (``--temporal taa``;
#: ``shaders/common/lighting_out.glsl``): lighting / albedo + linear depth (m), and
#: albedo + the lighting's alpha.
TAA_INPUTS: tuple[Tex, ...] = (Tex("taa_demod", "rgba32f"), Tex("taa_albedo", "rgba32f"))


class LightingMethod:
    name: ClassVar[str] = "base"
    #: Class-level option schema (``-o KEY=VALUE``).
    options: ClassVar[Schema] = Schema()
    #: Debug AOVs this method draws (names in ``tasks/aov_output.AOVS``); an instance
    #: may offer fewer (views that need an option it was made without).
    debug_aovs: tuple[str, ...] = ()
    #: Debug AOVs drawn only under some options: AOV -> the options it needs (said in
    #: the error when an instance without them is asked for one).
    debug_aov_requires: ClassVar[dict[str, str]] = {}
    #: True when the method evaluates local lights (culling, light buffer, atlas).
    #: False: the engine's scene index does not even hold the local lights its images
    #: cannot show (``light_filter``).
    uses_local_lights: ClassVar[bool] = True
    #: Min/max depth pyramid level the method samples (0: none); may depend on options.
    hiz_level: int = 0
    #: The lighting pass also writes ``TAA_INPUTS`` (set by the lighting task).
    taa_inputs: bool = False
    #: The method's light loop has point-only and sphere-only parts: in-view lights are
    #: ordered point lights, narrow sphere lights, other sphere lights, the rest;
    #: ``u_point_lights``, ``u_sphere_end`` and ``u_wide_sphere_end`` say where the parts
    #: end (``InViewLights``, ``light_buffer.by_light_model``); each part's loop is
    #: compiled only for the models seen (``LOOP_*`` defines, :func:`light_loops`).
    points_first: ClassVar[bool] = False
    #: Area-light penumbrae rotate their point set per integrated frame
    #: (``AREA_SHADOW_PER_FRAME`` + ``AREA_SHADOW_SEQUENCE``, common/shadow.glsl; by
    #: ``FrameContext.sample_index``), so ``--accumulate`` and taa converge to the
    #: light's visibility while a lone real-time frame keeps the fixed set (no shimmer):
    #: the exact methods.
    area_shadows_per_frame: ClassVar[bool] = False
    #: A textured dome's prefiltered sky light is shadowed by the sky occlusion maps
    #: (``DOME_OCCLUSION``, ``renderer/dome_shadows.SkyOcclusion``): every method but
    #: the reference, which samples the dome with shadow maps of its own.
    dome_occlusion: ClassVar[bool] = True
    #: Textured RectLights are integrated cell by cell (``RECT_TEXTURE_EXACT``,
    #: common/rect_texture_shading.glsl): the exact methods, which must equal the
    #: reference; the others use the textured-LTC lookup.
    exact_rect_textures: ClassVar[bool] = False

    def __init__(
        self, delegate: GLRenderDelegate | None, warn: Warn | None = None, **options: Any
    ) -> None:
        self.delegate = delegate
        self.warn: Warn = warn or (lambda _msg: None)
        #: Validated options (defaults filled in).
        self.o: dict[str, Any] = self.validate_options(options)
        #: The textured dome's sky occlusion maps (made on first use).
        self._sky: SkyOcclusion | None = None
        #: Light models seen in view since the method was made (``points_first``
        #: methods): their loops stay compiled in, so a model that comes and goes (a
        #: light moving in and out of view, a sphere turning narrow or wide) costs one
        #: program build, not one a frame (:meth:`scene_defines`).
        self.light_models: frozenset[str] = frozenset()

    # -- the contract --
    @classmethod
    def validate_options(cls, given: Mapping[str, Any]) -> dict[str, Any]:
        """All options of this method, validated (raises ``OptionError``)."""
        o = cls.options.validate(cls.name, given)
        cls.check_options(o)
        return o

    @classmethod
    def check_options(cls, o: dict[str, Any]) -> None:
        """Rules between options (after each one is typed and in range); may
        normalise values in place. Raise ``OptionError`` naming the method."""

    def internal(self) -> tuple[Tex, ...]:
        """The method's own render buffers (written by the lighting pass)."""
        return ()

    def reads(self) -> tuple[Resource, ...]:
        extra = (Tex(f"hiz{self.hiz_level}", "rg32f"),) if self.hiz_level else ()
        links = (LINK_INPUT,) if self.light_links else ()
        coat = (COAT_INPUT,) if self.clearcoat else ()
        return (*READS, *extra, *links, *coat)

    @property
    def light_links(self) -> bool:
        """The scene has light linking (``g_link`` and the link SSBO exist)."""
        d = self.delegate
        return d is not None and d.light_table.has_light_links()

    @property
    def clearcoat(self) -> bool:
        """Some material has a clearcoat lobe (``g_coat`` exists)."""
        d = self.delegate
        return d is not None and d.has_clearcoat

    def debug_passes(self) -> list[Pass]:
        """Passes drawing ``debug_aovs`` (each writes ``debug_<aov>``)."""
        return []

    # -- shared helpers --
    def scene_defines(self, frame: FrameContext) -> dict[str, object]:
        """Feature defines from what the scene has (compile only what is needed)."""
        defines: dict[str, object] = {}
        if frame.sun.enabled or frame.extra_distant:
            defines["HAS_SUN"] = True
        if frame.sun.enabled and frame.sun.shadow:
            defines["HAS_SUN_SHADOW"] = True
        dome = frame.get(DistantLights).dome
        if float(frame.ambient.max()) > 0 or dome is not None:
            defines["HAS_AMBIENT"] = True
        if dome is not None:
            defines["HAS_DOME_MAP"] = True  # the textured dome (common/dome.glsl)
            if self._sky_occluded(frame):
                defines["DOME_OCCLUSION"] = True  # common/dome_occlusion.glsl
        d = self.delegate
        if d is not None and len(d.seen_rect_emitters()):
            defines["RECT_EMITTERS_SEEN"] = True  # common/rect_emitter.glsl
        if frame.get(LightBuffer).links:
            defines["HAS_LINKS"] = True  # common/links.glsl
        if self.clearcoat:
            defines["HAS_CLEARCOAT"] = True  # common/brdf.glsl's coat lobe, g_coat
        lights = frame.get(InViewLights)
        if self.uses_local_lights and lights.count:
            if self.delegate is not None and self.delegate.has_ies and lights.has_ies:
                defines["HAS_IES"] = True
            if lights.has_cones:
                defines["HAS_CONES"] = True
            if not lights.has_focus:
                defines["NO_FOCUS"] = True  # no focusTint pow (common/lights.glsl)
            if not lights.has_cylinders:
                defines["NO_CYLINDER_LIGHTS"] = True  # common/area.glsl's streamed polygon
            if self.points_first:
                self.light_models |= light_models(lights)
                for m in light_loops(self.light_models, self.clearcoat):
                    defines[LIGHT_LOOP_DEFINES[m]] = True
            if lights.has_rect_textures and d is not None and d.rect_texture_array is not None:
                defines["RECT_TEXTURES"] = True  # common/rect_texture_shading.glsl
                if self.exact_rect_textures:
                    defines["RECT_TEXTURE_EXACT"] = True
            if frame.get(LightBuffer).has_shadows:
                defines["HAS_SHADOWS"] = True
                if self.points_first and not self.clearcoat:
                    # the lights without shadows of each loop's part in a loop without
                    # the shadow code (light_buffer.unshadowed_first, u_*_unshadowed_end)
                    defines["SPLIT_UNSHADOWED"] = True
                if frame.settings.shadow_filter == "stochastic":
                    defines["STOCHASTIC_PCF"] = True
                if self.area_shadows_per_frame:
                    defines["AREA_SHADOW_PER_FRAME"] = True
                    defines["AREA_SHADOW_SEQUENCE"] = True
        return defines

    def bind_common(self, frame: FrameContext, prog: moderngl.Program, first_unit: int = 0) -> int:
        """Bind G-buffer samplers, light buffer, LTC table, IES array, shadow atlas and
        records, sun shadow. Returns the next free texture unit."""
        unit = first_unit
        tex = frame.buffers.textures
        for name in GBUFFER_SAMPLERS:
            if name in prog:
                tex[name].use(unit)
                cast(moderngl.Uniform, prog[name]).value = unit
                unit += 1
        if "u_area_shadow_index" in prog:  # AREA_SHADOW_SEQUENCE (common/shadow.glsl)
            set_uniform(prog, "u_area_shadow_index", float(frame.sample_index))
        if self.points_first:  # where each loop by light model ends (its LOOP_* define)
            iv = frame.get(InViewLights)
            end = iv.point_count + iv.sphere_count
            set_uniform(prog, "u_point_lights", iv.point_count)
            set_uniform(prog, "u_sphere_end", end)
            set_uniform(prog, "u_wide_sphere_end", end + iv.wide_sphere_count)
            set_uniform(prog, "u_sphere_unshadowed_end", iv.point_count + iv.sphere_unshadowed)
            set_uniform(prog, "u_tail_unshadowed_end", end + iv.tail_unshadowed)
        lb = frame.get(LightBuffer)
        if lb.ssbo is not None:
            lb.ssbo.bind_to_storage_buffer(SSBO_LIGHTS)
        if lb.link_ssbo is not None:
            lb.link_ssbo.bind_to_storage_buffer(SSBO_LIGHT_LINKS)
        for opt in (LINK_INPUT, COAT_INPUT):
            if opt.name in prog:
                tex[opt.name].use(unit)
                cast(moderngl.Uniform, prog[opt.name]).value = unit
                unit += 1
        if "u_ltc" in prog:  # area lights' GGX specular (common/area.glsl)
            shader_library(frame.ctx).ltc_texture().use(unit)
            cast(moderngl.Uniform, prog["u_ltc"]).value = unit
            unit += 1
        d = self.delegate
        if d is not None and "u_ies" in prog and d.ies_texture is not None:
            d.ies_texture.use(unit)
            cast(moderngl.Uniform, prog["u_ies"]).value = unit
            unit += 1
        if d is not None and "u_ies_cos" in prog and d.ies_cos_texture is not None:
            d.ies_cos_texture.use(unit)
            cast(moderngl.Uniform, prog["u_ies_cos"]).value = unit
            unit += 1
        slots = frame.get(ShadowSlots)
        if slots.records is not None:
            slots.records.bind_to_storage_buffer(SSBO_SHADOW_MAPS)
        if slots.atlas is not None and "u_shadow_atlas" in prog:
            slots.atlas.use(unit)
            cast(moderngl.Uniform, prog["u_shadow_atlas"]).value = unit
            unit += 1
        sun = frame.get(SunShadowMap)
        if "u_sun_shadow" in prog and sun.texture is not None:
            sun.texture.use(unit)
            cast(moderngl.Uniform, prog["u_sun_shadow"]).value = unit
            unit += 1
        if d is not None and "u_dome_mult" in prog:  # common/dome.glsl
            unit = d.dome_env.bind(prog, unit)
        if d is not None and "u_dome_shadow" in prog and self._sky_occluded(frame):
            dist = frame.get(DistantLights)
            assert dist.dome is not None
            if self._sky is None:
                self._sky = SkyOcclusion(frame.ctx)
            mask = int(dist.dome.shadow_link_mask)
            sky = self._sky.prepare(d, dist.dome, mask, dist.dome_sun, frame.sample_index)
            if sky is not None:
                unit = self._sky.bind(prog, unit)
        if d is not None and "u_rect_tex" in prog and d.rect_texture_array is not None:
            d.rect_texture_array.use(unit)  # common/rect_texture.glsl
            cast(moderngl.Uniform, prog["u_rect_tex"]).value = unit
            unit += 1
        if d is not None and "u_rect_seen_count" in prog:  # common/rect_emitter.glsl
            seen = d.seen_rect_emitters()
            set_uniform(prog, "u_rect_seen_count", len(seen))
            if len(seen) and "u_rect_seen" in prog:
                u = cast(moderngl.Uniform, prog["u_rect_seen"])
                full = np.zeros((u.array_length, 4), np.float32)
                full[: 4 * len(seen)] = seen.reshape(-1, 4)[: u.array_length]
                u.write(full.tobytes())
        return unit

    def _sky_occluded(self, frame: FrameContext) -> bool:
        """Does this frame shadow the textured dome's prefiltered light (a method with
        ``dome_occlusion``, a dome that casts shadows)?"""
        dome = frame.get(DistantLights).dome
        return self.dome_occlusion and dome is not None and bool(dome.shadow_enable)

    def prepare(self, frame: FrameContext) -> None:
        """CPU work before the frame's uniforms are written."""

    def execute(self, frame: FrameContext) -> None:
        raise NotImplementedError

    def lighting_defines(
        self, frame: FrameContext, defines: dict[str, object] | None = None
    ) -> dict[str, object]:
        """Defines of a lighting shader (one that includes ``common/lighting_out.glsl``):
        ``defines`` (default: :meth:`scene_defines`), with its taa outputs switched on
        when the temporal pass needs them."""
        d = self.scene_defines(frame) if defines is None else defines
        return {**d, "TAA_DEMOD_OUT": True} if self.taa_inputs else d

    def fullscreen_pass(self, frame: FrameContext, prog: moderngl.Program, target: str) -> None:
        """Draw ``prog`` into ``target``; the ``lighting`` target also into
        ``TAA_INPUTS`` when the temporal pass needs them."""
        names = [target]
        if target == "lighting" and self.taa_inputs:
            names += [t.name for t in TAA_INPUTS]
        fbo = frame.buffers.framebuffer("fb_" + "_".join(names), names)
        draw_fullscreen(frame.ctx, prog, fbo, frame.buffers.size)

    def release(self) -> None:
        """Free GL objects the method owns."""

    def release_base(self) -> None:
        """Free GL objects of the base class (the sky occlusion maps); the lighting
        task calls it after :meth:`release`."""
        if self._sky is not None:
            self._sky.release()
            self._sky = None


def program(frame: FrameContext, frag: str, defines: dict[str, object]) -> moderngl.Program:
    return shader_library(frame.ctx).program("fullscreen.vert", frag, defines)


__all__ = ["TAA_INPUTS", "LightingMethod", "program", "set_uniform"]


def drawn_without_local_lighting(light_type: str, names: frozenset[str]) -> bool:
    """Whether a method that does not evaluate local lights (``uses_local_lights``
    False: ``sun``) still draws something of a light of ``light_type`` with these
    authored properties: every non-local light (distant, dome, portal), a baked light
    (``stb:baked``: the lightmap pass evaluates it where a mesh has no lightmap) and a
    textured RectLight (the camera may see its texture,
    ``GLRenderDelegate.seen_rect_emitters``). A ``stage_index_base.LightFilter``."""
    if light_type not in prims.LOCAL_LIGHT_TYPES or "stb:baked" in names:
        return True
    return light_type == prims.RECT_LIGHT and any(n.endswith("texture:file") for n in names)


def light_filter(method: type[LightingMethod]) -> Callable[[str, frozenset[str]], bool] | None:
    """The scene index's light filter for ``method`` (None: every light): Hydra's
    supported sprim types (``HdRenderDelegate::GetSupportedSprimTypes``) for a method
    without local lights, so that they are neither populated, synced nor uploaded."""
    return None if method.uses_local_lights else drawn_without_local_lighting
