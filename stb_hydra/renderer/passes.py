"""The pass registry: which passes a frame has, built from the settings and the
lighting method. Order here is only the tie-break; the graph orders passes by
what they read and write (``graph.compile_graph``).

Adding a pass: write ``tasks/<name>.py`` (a ``Pass`` with ``reads``/``writes``),
then add one line to :func:`build_passes`.
"""

from __future__ import annotations

from dataclasses import dataclass

import moderngl

from ..color.ocio import ColorPipeline
from .frame import RenderSettings
from .gl_delegate import GLRenderDelegate
from .lighting.base import LightingMethod
from .tasks.aov_output import AovOutputTask, LightCountTask
from .tasks.base import Pass
from .tasks.color_correction import ColorCorrectionTask
from .tasks.distant_lights import DistantLightsTask
from .tasks.frame_uniforms import FrameUniformsTask
from .tasks.gbuffer import GBufferTask
from .tasks.hiz import HIZ_LEVELS, HiZTask
from .tasks.light_cull import LightCullTask
from .tasks.light_upload import LightUploadTask
from .tasks.lighting import LightingTask
from .tasks.lightmap import LightmapTask
from .tasks.shadow import SunShadowTask
from .tasks.shadow_atlas import ShadowAtlasTask
from .tasks.shadow_footprint import ShadowFootprintTask
from .tasks.taa import AccumulateTask
from .tasks.taa_filter import TaaFilterTask
from .tasks.temporal import TemporalTask

#: Resources owned outside the graph (the delegate's prims, the OCIO pipeline).
IMPORTS = ("light_table", "meshes", "color_pipeline")


@dataclass
class PassSet:
    """The passes of one engine configuration, with handles the engine drives."""

    passes: list[Pass]
    lighting: LightingTask
    accumulate: AccumulateTask
    #: The taa pass (``settings.temporal == "taa"``; it replaces ``accumulate``).
    temporal: TemporalTask | None
    aov_output: AovOutputTask
    frame_uniforms: FrameUniformsTask
    shadow_atlas: ShadowAtlasTask
    #: Baked static light (``stb bake``); in the graph only when the stage has lightmaps.
    lightmap: LightmapTask | None = None


def build_passes(
    ctx: moderngl.Context,
    delegate: GLRenderDelegate,
    settings: RenderSettings,
    method: LightingMethod,
    color: ColorPipeline,
    keep: PassSet | None = None,
) -> PassSet:
    """Every registered pass for ``settings`` and ``method`` (the graph culls the
    ones whose outputs nobody reads, e.g. debug views that were not requested).
    ``keep``: the passes being replaced; their long-lived, method-independent state
    (the shadow atlas with its captured maps, the frame uniforms with the previous
    view) is reused instead of built again."""
    local_shadows = settings.shadows and method.uses_local_lights
    if keep is None:
        atlas = ShadowAtlasTask(
            delegate,
            settings.shadow_atlas_size,
            settings.realtime_shadow_budget(),
            enabled=local_shadows,
            budget_ms=settings.shadow_budget_ms,
            cost_coeffs=settings.shadow_cost_coeffs,
            capture_mode=settings.shadow_capture_mode,
            resolution=settings.shadow_resolution,
        )
        uniforms = FrameUniformsTask(delegate, ctx)
    else:
        atlas, uniforms = keep.shadow_atlas, keep.frame_uniforms
        atlas.enabled = local_shadows
        atlas.resolution = settings.shadow_resolution
    lighting = LightingTask(delegate, method, taa_inputs=settings.temporal == "taa")
    accumulate = AccumulateTask(delegate)
    temporal = TemporalTask(delegate) if settings.temporal == "taa" else None
    aov = AovOutputTask(delegate, method)
    # The lightmap atlas is method-independent: kept across set_lighting like the atlas.
    lightmap = keep.lightmap if keep is not None and keep.lightmap is not None else None
    lightmap = lightmap or LightmapTask(delegate)
    passes: list[Pass] = [
        DistantLightsTask(delegate),
        LightCullTask(delegate, points_first=method.points_first),
        SunShadowTask(delegate),
        atlas,
        LightUploadTask(delegate),
        uniforms,
        GBufferTask(delegate),
        HiZTask(delegate, max(HIZ_LEVELS, method.hiz_level)),
        *([ShadowFootprintTask(delegate, atlas)] if settings.shadow_resolution != "flux" else []),
        lighting,
        temporal if temporal is not None else accumulate,
        *(
            [TaaFilterTask(delegate, temporal, settings.taa_filter)]
            if temporal and settings.taa_filter
            else []
        ),
        ColorCorrectionTask(delegate, color),
        *method.debug_passes(),
        LightCountTask(delegate),
        aov,
        lightmap,  # after gbuffer, before lighting (it modifies g_emission in place)
    ]
    return PassSet(passes, lighting, accumulate, temporal, aov, uniforms, atlas, lightmap)


__all__ = ["IMPORTS", "PassSet", "build_passes"]
