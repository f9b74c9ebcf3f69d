"""Constants shared by the Python renderer and the GLSL: one source of truth.

Every name in :data:`GLSL_CONSTANTS` is a ``#define`` of the virtual include
``common/constants.glsl``, which the shader loader (:mod:`stb_hydra.renderer.gl`)
generates from this module and puts at the top of every shader. Python code uses the
module-level names below, or the owners this module reads (:mod:`stb_hydra.limits`,
:mod:`stb_hydra.scene.prims`, :mod:`stb_hydra.color`); shaders use the ``#define`` of
the same name. Change a value in Python, never a literal in a shader or a module.

* ``LIM_*``: the limits of :mod:`stb_hydra.limits` the shaders need.
* ``TEX_UNIT_*``, ``UBO_*``, ``SSBO_*``, ``IMAGE_UNIT_*``: fixed GL binding points,
  declared with ``layout(binding = ...)`` in GLSL and bound to the same number here.
* ``LIGHT_COL_*``: float columns of one packed light record (``struct Light`` in
  ``shaders/common/lights.glsl``, laid out by :data:`LIGHT_LAYOUT`).
* The rest: codes and sentinels that both sides write or test (``EMIT_*`` and
  ``CONE_CUTOFF_TEST_RAD`` of :mod:`stb_hydra.scene.prims`, ``LUMINANCE_REC709`` of
  :mod:`stb_hydra.color`, ``PI``).
"""

from __future__ import annotations

import math
from collections.abc import Iterable

from .. import limits
from ..color import LUMINANCE_REC709
from ..scene import prims

# --- GL binding points ------------------------------------------------------------------

#: Uniform block of the per-frame constants (``FrameBlock``, common/frame.glsl).
UBO_FRAME = 0
#: Packed FoV lights (``LightBuffer``, common/lights.glsl).
SSBO_LIGHTS = 0
#: Shadow-map records of the atlas (``ShadowBuffer``, common/shadow.glsl).
SSBO_SHADOW_MAPS = 1
#: Per-cell buffers of the list-based methods (tiled, clustered, lighttree): cell
#: headers; light lists (tiled, clustered) or tree nodes (lighttree); cull statistics
#: (tiled, clustered) or the tree's light indices (lighttree).
SSBO_CELL_HEADERS = 2
SSBO_CELL_LISTS = 3
SSBO_CELL_EXTRA = 4
#: STB's light clusters (``-o bigtile=clusters``): super-cluster then cluster bounds
#: and flux (one array); the FoV light index of every clustered light (Morton order).
SSBO_STB_CLUSTERS = 5
SSBO_STB_CLUSTER_LIGHTS = 6
#: STB's FoV light records in the clusters' Morton order (contiguous per cluster).
SSBO_STB_CLUSTER_RECORDS = 7
#: STB's light clusters, ``-o cluster_pick=flux``: each clustered light's inclusive flux
#: CDF within its cluster (float, Morton order).
SSBO_STB_CLUSTER_CDF = 15
#: Light linking (``LightBuffer.link_ssbo``, common/links.glsl): the distant lights'
#: masks, ambient per link group, then one mask per in-view light (light-buffer order).
SSBO_LIGHT_LINKS = 8
#: ``stb bake``: the light-buffer indices of the lights whose range reaches the mesh
#: being baked (bake_light.frag; bake/gpu.py).
SSBO_BAKE_LIGHTS = 9
#: STB reuse (``-o reuse=on``): previous frame's FoV light index -> this frame's (int,
#: -1 = no longer in view), bound only when the FoV list changed.
SSBO_STB_REUSE_REMAP = 10
#: Shadow footprint (shadow_footprint.comp): the measured lights (FoV index, map
#: angular span) in; the needed map side per light (float bits, atomicMax) out.
SSBO_FOOTPRINT_LIGHTS = 11
SSBO_FOOTPRINT_OUT = 12
#: tiled / clustered shading (``CELL_POS_RANGE``): each list entry's light
#: ``pos_range`` (vec4, the light buffer's floats), parallel to ``SSBO_CELL_LISTS``.
SSBO_CELL_POS_RANGE = 13
#: STB reuse, fused pass: the pixels whose pick needs the area path (count, then
#: x | y << 16), appended by stb_reuse_shade.frag, read by stb_reuse_area.frag.
SSBO_STB_REUSE_AREA = 14
#: Image unit of the depth-pyramid level being written (hiz_minmax.comp).
IMAGE_UNIT_HIZ_DST = 0
#: Image unit of STB's full-resolution per-pixel terms of split quads (stb_shadow.frag).
IMAGE_UNIT_PIXEL_TERMS = 1
#: Image unit of STB's big-tile reservoirs written by stb_bigtile_clusters.comp.
IMAGE_UNIT_BIGTILE = 2
#: STB reuse: the reservoir history and its surface (depth, normal, roughness) written
#: by the shading pass for the next frame.
IMAGE_UNIT_REUSE_RESERVOIR = 3
IMAGE_UNIT_REUSE_SURFACE = 4
#: STB reuse, fused pass: the listed pixels' sun + ambient radiance (rgba32f), and the
#: lighting outputs stb_reuse_area.frag writes (lighting, taa_demod, taa_albedo).
IMAGE_UNIT_REUSE_PARTIAL = 5
IMAGE_UNIT_REUSE_OUT_COLOR = 6
IMAGE_UNIT_REUSE_OUT_DEMOD = 7
IMAGE_UNIT_REUSE_OUT_ALBEDO = 8
#: Texture unit of the min/max depth pyramid level read by the big-tile pass
#: (stb_bigtile.frag) and the tile culling (tiled_cull.comp): clear of the units
#: ``LightingMethod.bind_common`` hands out from 0 (at most 10: G-buffer and its link
#: groups, LTC, IES, atlas, sun).
TEX_UNIT_HIZ = 12

# --- Packed light record (struct Light, common/lights.glsl) ---------------------------

#: The std430 light record, vec4 by vec4: (GLSL member, names of its 4 float columns).
#: A name repeated over adjacent columns is a vector (xyz). The GLSL struct declares
#: the same members in the same order (checked by tests/test_shader_constants.py).
LIGHT_LAYOUT: tuple[tuple[str, tuple[str, str, str, str]], ...] = (
    ("pos_range", ("position", "position", "position", "range")),
    ("axis_emit", ("axis", "axis", "axis", "emission")),
    # w: the RectLight texture layer (u_rect_tex, common/rect_texture.glsl; -1 none).
    ("tangent_tex", ("tangent", "tangent", "tangent", "texture_layer")),
    ("intensity", ("intensity", "intensity", "intensity", "flux")),
    ("cone", ("cos_cutoff", "cutoff", "cone_start", "focus")),
    ("tint_ies", ("focus_tint", "focus_tint", "focus_tint", "ies_layer")),
    ("ies_shadow", ("ies_scale", "ies_angle_scale", "shadow_map", "shadow_flags")),
    ("shadow_color", ("shadow_color", "shadow_color", "shadow_color", "shadow_distance")),
    ("misc", ("shadow_falloff", "shadow_falloff_gamma", "diffuse", "specular")),
    # Area lights (issue 20, common/area.glsl): half sizes (m), shape code, radiance/cd.
    ("area", ("area_size_x", "area_size_y", "area_kind", "area_radiance")),
)


def _light_columns() -> dict[str, int]:
    cols: dict[str, int] = {}
    for i, (_, names) in enumerate(LIGHT_LAYOUT):
        for j, name in enumerate(names):
            cols.setdefault(name, 4 * i + j)
    return cols


#: First float column of each light-record field (a vector spans 3 columns).
LIGHT_COLUMNS: dict[str, int] = _light_columns()
LIGHT_RECORD_VEC4S = len(LIGHT_LAYOUT)  # 10
LIGHT_STRIDE_FLOATS = 4 * LIGHT_RECORD_VEC4S  # 40
LIGHT_STRIDE_BYTES = 4 * LIGHT_STRIDE_FLOATS  # 160

LIGHT_COL_POSITION = LIGHT_COLUMNS["position"]  # 0:3
LIGHT_COL_RANGE = LIGHT_COLUMNS["range"]  # 3
LIGHT_COL_AXIS = LIGHT_COLUMNS["axis"]  # 4:7
LIGHT_COL_EMISSION = LIGHT_COLUMNS["emission"]  # 7
LIGHT_COL_TANGENT = LIGHT_COLUMNS["tangent"]  # 8:11
LIGHT_COL_TEXTURE_LAYER = LIGHT_COLUMNS["texture_layer"]  # 11
LIGHT_COL_INTENSITY = LIGHT_COLUMNS["intensity"]  # 12:15
LIGHT_COL_FLUX = LIGHT_COLUMNS["flux"]  # 15
LIGHT_COL_COS_CUTOFF = LIGHT_COLUMNS["cos_cutoff"]  # 16
LIGHT_COL_CUTOFF = LIGHT_COLUMNS["cutoff"]  # 17
LIGHT_COL_CONE_START = LIGHT_COLUMNS["cone_start"]  # 18
LIGHT_COL_FOCUS = LIGHT_COLUMNS["focus"]  # 19
LIGHT_COL_FOCUS_TINT = LIGHT_COLUMNS["focus_tint"]  # 20:23
LIGHT_COL_IES_LAYER = LIGHT_COLUMNS["ies_layer"]  # 23
LIGHT_COL_IES_SCALE = LIGHT_COLUMNS["ies_scale"]  # 24
LIGHT_COL_IES_ANGLE_SCALE = LIGHT_COLUMNS["ies_angle_scale"]  # 25
LIGHT_COL_SHADOW_MAP = LIGHT_COLUMNS["shadow_map"]  # 26
LIGHT_COL_SHADOW_FLAGS = LIGHT_COLUMNS["shadow_flags"]  # 27
LIGHT_COL_SHADOW_COLOR = LIGHT_COLUMNS["shadow_color"]  # 28:31
LIGHT_COL_SHADOW_DISTANCE = LIGHT_COLUMNS["shadow_distance"]  # 31
LIGHT_COL_SHADOW_FALLOFF = LIGHT_COLUMNS["shadow_falloff"]  # 32
LIGHT_COL_SHADOW_FALLOFF_GAMMA = LIGHT_COLUMNS["shadow_falloff_gamma"]  # 33
LIGHT_COL_DIFFUSE = LIGHT_COLUMNS["diffuse"]  # 34
LIGHT_COL_SPECULAR = LIGHT_COLUMNS["specular"]  # 35
LIGHT_COL_AREA_SIZE_X = LIGHT_COLUMNS["area_size_x"]  # 36
LIGHT_COL_AREA_SIZE_Y = LIGHT_COLUMNS["area_size_y"]  # 37
LIGHT_COL_AREA_KIND = LIGHT_COLUMNS["area_kind"]  # 38
LIGHT_COL_AREA_RADIANCE = LIGHT_COLUMNS["area_radiance"]  # 39

#: Area shape codes (``area_kind``): 0 = lit with the point model (treatAsPoint, zero
#: size, mesh lights), else the emitter integrated over its area (common/area.glsl).
AREA_POINT = 0
AREA_RECT = 1
AREA_DISK = 2
AREA_SPHERE = 3
AREA_CYLINDER = 4

#: Index columns (IES layer, shadow map) holding "none".
LIGHT_INDEX_NONE = -1.0

# --- STB interleaved small tiles (common/tiles.glsl, data/quad_patterns.json) ---------------

#: Interleaved mode: 2 x 2 small tiles of SMALL_TILE_PX share one square footprint.
INTERLEAVE_FOOTPRINT_PX = 2 * limits.SMALL_TILE_PX  # 32
#: Quads along a small tile's side (8), i.e. 64 quads = slots per small tile.
INTERLEAVE_QUADS_PER_SIDE = limits.SMALL_TILE_PX // limits.QUAD_PX  # 8
#: Quad LUT texel (16 x 16 r32i, one per quad of a footprint): tile | slot << 4.
QUAD_LUT_SLOT_SHIFT = 4
#: Forward LUT texel (64 x 4 r32i, one per (slot, tile)): qx | qy << 8.
QUAD_FWD_Y_SHIFT = 8


# --- The GLSL side ------------------------------------------------------------------------


def _vec3(v: Iterable[float]) -> str:
    return "vec3(" + ", ".join(repr(float(x)) for x in v) + ")"


def _glsl_constants() -> dict[str, str]:
    return {
        # limits (formats kept as they were: the compiled shaders must not change)
        "LIM_HALF_MAX": f"{limits.HALF_MAX:.1f}",
        "LIM_MIN_LIGHT_DISTANCE": f"{limits.MIN_LIGHT_DISTANCE_M:.6f}",
        "LIM_RANGE_FADE_START": f"{limits.RANGE_FADE_START:.6f}",
        "LIM_IES_THETA": str(limits.IES_TABLE_THETA),
        "LIM_IES_PHI": str(limits.IES_TABLE_PHI),
        "LIM_SAMPLE_INDEX_BITS": str(limits.SAMPLE_INDEX_BITS),
        "LIM_EMPTY_LIGHT_INDEX": f"{limits.EMPTY_LIGHT_INDEX}u",
        "LIM_WEIGHT_LOG2_MIN": f"{limits.SAMPLE_WEIGHT_LOG2_MIN:.1f}",
        "LIM_WEIGHT_STEPS": f"{float(limits.SAMPLE_WEIGHT_STEPS_PER_OCTAVE):.1f}",
        "LIM_PDF_EPSILON": f"{limits.PDF_EPSILON:.3e}",
        "LIM_BIG_TILE_PX": str(limits.BIG_TILE_PX),
        "LIM_BIG_TILE_SLOTS_MAX": str(max(limits.BIG_TILE_SLOTS_ALLOWED)),
        "LIM_TERM_SHARE_REL_DISTANCE": f"{limits.STB_TERM_SHARE_REL_DISTANCE:.6f}",
        "LIM_RIS_PDF_FLOOR": f"{limits.STB_RIS_PDF_FLOOR:.6f}",
        "LIM_REUSE_K_MAX": str(limits.STB_REUSE_K_MAX),
        "LIM_REUSE_MAX_CHANGES": str(limits.STB_REUSE_MAX_CHANGES),
        "LIM_REUSE_DEBUG_M_MAX": f"{limits.STB_REUSE_DEBUG_M_MAX:.1f}",
        "LIM_REUSE_DEPTH_REL": f"{limits.STB_REUSE_DEPTH_REL:.6f}",
        "LIM_REUSE_NORMAL_COS": f"{limits.STB_REUSE_NORMAL_COS:.6f}",
        "LIM_REUSE_ROUGHNESS_DIFF": f"{limits.STB_REUSE_ROUGHNESS_DIFF:.6f}",
        "LIM_REUSE_QUAD_FLOOR": f"{limits.STB_REUSE_QUAD_FLOOR:.6f}",
        "LIM_REUSE_SHARE_MIS_RATIO": f"{limits.STB_REUSE_SHARE_MIS_RATIO:.6f}",
        "LIM_BIGTILE_SHAPE_FLOOR": f"{limits.STB_BIGTILE_SHAPE_FLOOR:.6f}",
        "LIM_REUSE_SLOT_GRID": str(limits.STB_REUSE_SLOT_GRID),
        "LIM_REUSE_SLOT_SHAPE_FLOOR": f"{limits.STB_REUSE_SLOT_SHAPE_FLOOR:.6f}",
        "LIM_REUSE_SLOT_CONE_MARGIN": f"{limits.STB_REUSE_SLOT_CONE_MARGIN:.6e}",
        "LIM_REUSE_SLOT_CONE_MIN_DCOS": f"{limits.STB_REUSE_SLOT_CONE_MIN_DCOS:.6e}",
        "LIM_REUSE_IES_COS_BINS": str(limits.STB_REUSE_IES_COS_BINS),
        "LIM_AREA_POINT_RATIO": f"{limits.AREA_POINT_RATIO:.6f}",
        "LIM_AREA_POLY_VERTS": str(limits.AREA_POLY_VERTS),
        "LIM_DOME_SAMPLES": str(limits.DOME_REFERENCE_SAMPLES),
        "LIM_DOME_SH_COEFFS": str(limits.DOME_SH_COEFFS),
        "LIM_AREA_SPEC_POINT": f"{limits.AREA_SPEC_POINT:.6f}",
        "LIM_AREA_SPEC_LTC": f"{limits.AREA_SPEC_LTC:.6f}",
        "LIM_GGX_ALPHA_MIN": f"{limits.GGX_ALPHA_MIN:.6f}",
        "LIM_PCSS_MAX_TEXELS": f"{limits.PCSS_MAX_TEXELS:.1f}",
        "LIM_AREA_SHADOW_POINTS": str(limits.AREA_SHADOW_POINTS),
        "LIM_AREA_SHADOW_POINTS_STB": str(limits.AREA_SHADOW_POINTS_STB),
        "LIM_AREA_SHADOW_SEARCH": str(limits.AREA_SHADOW_SEARCH),
        "LIM_AREA_SHADOW_SEARCH_COS": f"{limits.AREA_SHADOW_SEARCH_COS:.4f}",
        "LIM_AREA_SHADOW_SEARCH_CONE": f"{limits.AREA_SHADOW_SEARCH_CONE:.3f}",
        "LIM_AREA_SHADOW_EMPTY_DEPTH": f"{limits.AREA_SHADOW_EMPTY_DEPTH:.6f}",
        "LIM_AREA_SHADOW_STEPS": str(limits.AREA_SHADOW_STEPS),
        "LIM_AREA_SHADOW_REFINE": str(limits.AREA_SHADOW_REFINE),
        "LIM_AREA_SHADOW_THICK_TEXELS": f"{limits.AREA_SHADOW_THICK_TEXELS:.3f}",
        "LIM_AREA_SHADOW_THICK_STEPS": f"{limits.AREA_SHADOW_THICK_STEPS:.3f}",
        "LIM_AREA_SHADOW_RECEIVER_TEXELS": f"{limits.AREA_SHADOW_RECEIVER_TEXELS:.3f}",
        "LIM_BIG_TILE_CLUSTER_LIGHTS": str(limits.BIG_TILE_CLUSTER_LIGHTS),
        "LIM_BIG_TILE_CLUSTER_FANOUT": str(limits.BIG_TILE_CLUSTER_FANOUT),
        "LIM_BIG_TILE_SUPERS_MAX": str(limits.BIG_TILE_SUPERS_MAX),
        "LIM_MATERIAL_TEXTURE_SLOTS": str(limits.MATERIAL_TEXTURE_SLOTS),
        "LIM_UDIM_FIRST_TILE": str(limits.UDIM_FIRST_TILE),
        "LIM_LINK_GROUPS": str(limits.MAX_LIGHT_LINK_GROUPS),
        "LIM_FOOTPRINT_LIGHTS": str(limits.SHADOW_FOOTPRINT_LIGHTS_MAX),
        "LIM_FOOTPRINT_BINS": str(limits.SHADOW_FOOTPRINT_BINS),
        "LIM_MAX_LIGHT_CHANGES": str(limits.MAX_LIGHT_CHANGES),
        "LIM_TAA_EDGE_RUN_SCALE": str(limits.TAA_EDGE_RUN_SCALE),
        "LIM_TAA_YOUNG_GRID": str(limits.TAA_YOUNG_GRID),
        "LIM_MAX_EXTRA_DISTANT": str(limits.MAX_EXTRA_DISTANT),
        "LIM_CULL_LIGHTS_PER_INVOCATION": str(limits.CULL_LIGHTS_PER_INVOCATION),
        "LIM_CUBE_FACES": str(limits.CUBE_FACES),
        "LIM_RECT_TEXTURES": str(limits.MAX_RECT_TEXTURES),
        "LIM_RECT_TEXTURE_GRID": str(limits.RECT_TEXTURE_GRID),
        "LIM_RECT_TEXTURE_GRID_RT": str(limits.RECT_TEXTURE_GRID_REALTIME),
        "LIM_RECT_TEXTURE_FOOTPRINT": f"{limits.RECT_TEXTURE_FOOTPRINT:.4f}",
        # binding points
        "UBO_FRAME": str(UBO_FRAME),
        "SSBO_LIGHTS": str(SSBO_LIGHTS),
        "SSBO_SHADOW_MAPS": str(SSBO_SHADOW_MAPS),
        "SSBO_CELL_HEADERS": str(SSBO_CELL_HEADERS),
        "SSBO_CELL_LISTS": str(SSBO_CELL_LISTS),
        "SSBO_CELL_EXTRA": str(SSBO_CELL_EXTRA),
        "SSBO_STB_CLUSTERS": str(SSBO_STB_CLUSTERS),
        "SSBO_STB_CLUSTER_LIGHTS": str(SSBO_STB_CLUSTER_LIGHTS),
        "SSBO_STB_CLUSTER_RECORDS": str(SSBO_STB_CLUSTER_RECORDS),
        "SSBO_STB_CLUSTER_CDF": str(SSBO_STB_CLUSTER_CDF),
        "SSBO_LIGHT_LINKS": str(SSBO_LIGHT_LINKS),
        "SSBO_BAKE_LIGHTS": str(SSBO_BAKE_LIGHTS),
        "SSBO_STB_REUSE_REMAP": str(SSBO_STB_REUSE_REMAP),
        "SSBO_FOOTPRINT_LIGHTS": str(SSBO_FOOTPRINT_LIGHTS),
        "SSBO_FOOTPRINT_OUT": str(SSBO_FOOTPRINT_OUT),
        "SSBO_CELL_POS_RANGE": str(SSBO_CELL_POS_RANGE),
        "SSBO_STB_REUSE_AREA": str(SSBO_STB_REUSE_AREA),
        "IMAGE_UNIT_HIZ_DST": str(IMAGE_UNIT_HIZ_DST),
        "IMAGE_UNIT_PIXEL_TERMS": str(IMAGE_UNIT_PIXEL_TERMS),
        "IMAGE_UNIT_BIGTILE": str(IMAGE_UNIT_BIGTILE),
        "IMAGE_UNIT_REUSE_RESERVOIR": str(IMAGE_UNIT_REUSE_RESERVOIR),
        "IMAGE_UNIT_REUSE_SURFACE": str(IMAGE_UNIT_REUSE_SURFACE),
        "IMAGE_UNIT_REUSE_PARTIAL": str(IMAGE_UNIT_REUSE_PARTIAL),
        "IMAGE_UNIT_REUSE_OUT_COLOR": str(IMAGE_UNIT_REUSE_OUT_COLOR),
        "IMAGE_UNIT_REUSE_OUT_DEMOD": str(IMAGE_UNIT_REUSE_OUT_DEMOD),
        "IMAGE_UNIT_REUSE_OUT_ALBEDO": str(IMAGE_UNIT_REUSE_OUT_ALBEDO),
        "TEX_UNIT_HIZ": str(TEX_UNIT_HIZ),
        # codes and sentinels
        "PI": repr(math.pi),
        "LUMINANCE_REC709": _vec3(LUMINANCE_REC709),
        "EMIT_ISOTROPIC": repr(float(prims.EMIT_ISOTROPIC)),
        "EMIT_COSINE": repr(float(prims.EMIT_COSINE)),
        "EMIT_CYLINDER": repr(float(prims.EMIT_CYLINDER)),
        "AREA_POINT": repr(float(AREA_POINT)),
        "AREA_RECT": repr(float(AREA_RECT)),
        "AREA_DISK": repr(float(AREA_DISK)),
        "AREA_SPHERE": repr(float(AREA_SPHERE)),
        "AREA_CYLINDER": repr(float(AREA_CYLINDER)),
        "CONE_CUTOFF_TEST_RAD": repr(prims.CONE_CUTOFF_TEST_RAD),
        "INTERLEAVE_FOOTPRINT_PX": str(INTERLEAVE_FOOTPRINT_PX),
        "INTERLEAVE_QUADS_PER_SIDE": str(INTERLEAVE_QUADS_PER_SIDE),
        "QUAD_LUT_SLOT_SHIFT": str(QUAD_LUT_SLOT_SHIFT),
        "QUAD_FWD_Y_SHIFT": str(QUAD_FWD_Y_SHIFT),
    }


#: GLSL name -> GLSL source text of its value (the ``#define`` body).
GLSL_CONSTANTS: dict[str, str] = _glsl_constants()


def constants_glsl() -> str:
    """Source of the virtual include ``common/constants.glsl``."""
    lines = [
        "// Generated from stb_hydra/renderer/shader_constants.py (GLSL_CONSTANTS) and",
        "// stb_hydra/limits.py by the shader loader: change values there, not here.",
        "#ifndef STB_CONSTANTS_GLSL",
        "#define STB_CONSTANTS_GLSL",
    ]
    lines += [f"#define {k} {v}" for k, v in GLSL_CONSTANTS.items()]
    lines.append("#endif")
    return "\n".join(lines) + "\n"
