"""FoV light culling (CPU, vectorised) and the packed std430 light buffer.

The packed layout mirrors ``struct Light`` in ``shaders/common/lights.glsl``:
ten vec4 (160 bytes) per light; index in the buffer = position in the FoV list.
"""

from __future__ import annotations

import numpy as np

from .. import limits
from . import shader_constants as sc
from .light_table import LightTable

LIGHT_STRIDE_FLOATS = sc.LIGHT_STRIDE_FLOATS  # 10 x vec4
LIGHT_STRIDE_BYTES = sc.LIGHT_STRIDE_BYTES
#: Float column of the shadow-map record slot (-1 = unshadowed): the one column
#: patched when only slots change.
LIGHT_SHADOW_SLOT_COLUMN = sc.LIGHT_COL_SHADOW_MAP


def cull_lights(table: LightTable, planes: np.ndarray) -> np.ndarray:
    """Rows of enabled local lights whose influence sphere touches the frustum.

    ``planes``: (6, 4) world planes, inside where n.p + d >= 0. Conservative
    sphere test; returns row indices in increasing order (stable FoV order).
    """
    mask = table.local_mask()
    rows = np.nonzero(mask)[0]
    if len(rows) == 0:
        return rows
    p = table.position[rows]
    r = table.range[rows].astype(np.float64)
    dist = p @ planes[:, :3].T + planes[:, 3]  # (n, 6)
    inside = np.all(dist >= -r[:, None], axis=1)
    out = rows[inside]
    if len(out) > limits.MAX_FOV_LIGHTS:
        # Keep the brightest: the packed sample index cannot address more.
        order = np.argsort(-table.flux[out], kind="stable")[: limits.MAX_FOV_LIGHTS]
        out = np.sort(out[order])
    return out


def half_extent(table: LightTable, rows: np.ndarray) -> np.ndarray:
    """The lights' half extents (m) as ``light_half_extent`` in common/area.glsl computes
    them: 0 for point lights, the half diagonal of a rect, the larger of a cylinder's
    radius and half length, the radius of a disk or sphere."""
    kind = table.area_kind[rows]
    size = table.area_size[rows].astype(np.float32)
    ext = size[:, 0].copy()
    rect = kind == sc.AREA_RECT
    ext[rect] = np.hypot(size[rect, 0], size[rect, 1])
    cyl = kind == sc.AREA_CYLINDER
    ext[cyl] = np.maximum(size[cyl, 0], size[cyl, 1])
    ext[kind == sc.AREA_POINT] = 0.0
    return ext


def points_first(table: LightTable, rows: np.ndarray) -> tuple[np.ndarray, int]:
    """``rows`` stably partitioned: lights without extent (never lit as an area: no
    polygon, no LTC) first, then the rest, each part in its given order; and the
    number of the first part. The exact methods run the first part through a loop
    that holds only the point model (``light_radiance_point_at``): on SIMD hardware that
    executes both sides of a branch, a loop body carrying the area code costs it for
    every light (issue 34)."""
    out, n_point, _thin, _wide = by_light_model(table, rows)
    return out, n_point


def by_light_model(
    table: LightTable, rows: np.ndarray, narrow: np.ndarray | None = None
) -> tuple[np.ndarray, int, int, int]:
    """``rows`` stably partitioned by the light model the exact methods' loops need:
    lights without extent (``light_radiance_point_at``), sphere lights ``narrow`` marks
    (``light_radiance_sphere_narrow``: closed-form diffuse, point specular; see
    :func:`narrow_spheres`), the other sphere lights (``light_radiance_sphere_wide``:
    LTC specular where the lobe needs it), then the rest (``light_radiance``), each part
    in its given order; and the sizes of the first three parts. ``narrow``: a mask over
    ``rows`` (None: no light is known narrow)."""
    if len(rows) == 0:
        return rows, 0, 0, 0
    point = half_extent(table, rows) <= 0.0
    sphere = ~point & (table.area_kind[rows] == sc.AREA_SPHERE)
    thin = sphere & narrow if narrow is not None else np.zeros_like(sphere)
    wide = sphere & ~thin
    rest = ~(point | sphere)
    parts = (point, thin, wide)
    counts = [int(np.count_nonzero(m)) for m in parts]
    out = np.concatenate([rows[m] for m in (*parts, rest)])
    return out, counts[0], counts[1], counts[2]


def unshadowed_first(
    table: LightTable, rows: np.ndarray, point_count: int, sphere_count: int
) -> tuple[np.ndarray, int, int]:
    """``rows`` in :func:`by_light_model`'s order with its narrow-sphere part
    (``rows[point_count:point_count + sphere_count]``) and the part after it (wide
    spheres and the rest) each stably partitioned: lights without shadows
    (``shadow_enable`` false: never given a shadow map) first. Returns the rows and how
    many lights without shadows open each of the two parts. The exact methods loop over
    those with the shadow code left out (``SPLIT_UNSHADOWED``, issue 34: on llvmpipe the
    shadow code of a light loop runs for every light, shadowed or not). Each pixel still
    sums its lights in buffer order."""
    a, b = point_count, point_count + sphere_count
    counts = []
    parts = [rows[:a]]
    for part in (rows[a:b], rows[b:]):
        off = ~table.shadow_enable[part]
        counts.append(int(np.count_nonzero(off)))
        parts += [part[off], part[~off]]
    return np.concatenate(parts), counts[0], counts[1]


def narrow_spheres(
    table: LightTable,
    rows: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    alpha_min: float,
    box_alpha: np.ndarray | None = None,
) -> np.ndarray:
    """Mask over ``rows``: sphere lights narrow against every specular lobe they can
    reach, so common/area.glsl's ``area_spec_weight`` is 0 at every receiver and they
    need no LTC integral: radius below ``limits.AREA_SPEC_POINT`` x min over the boxes of
    (distance from the light's centre to the box x the box's alpha) (with a 1e-3 margin
    for float32). ``lo``, ``hi``: world AABBs ((B, 3), render frame, m) such that every
    receiver lies in one; ``box_alpha`` (B,): the smallest GGX alpha of a receiver in
    each box (None: ``alpha_min``, the smallest in the scene, for every box; a box's
    alpha is never taken below ``alpha_min``'s clamp ``limits.GGX_ALPHA_MIN``). A
    receiver in box b is at least d_b away and has alpha >= alpha_b, so its
    radius / (distance x alpha) is below the bound. A light without specular
    (multiplier 0) is narrow too."""
    out = np.zeros(len(rows), dtype=bool)
    sph = np.nonzero(table.area_kind[rows] == sc.AREA_SPHERE)[0]
    if len(sph) == 0:
        return out
    r = rows[sph]
    radius = table.area_size[r, 0].astype(np.float64)
    no_spec = table.specular[r] == 0.0
    if len(lo) == 0:
        out[sph] = True  # nothing to light
        return out
    floor = max(alpha_min, limits.GGX_ALPHA_MIN)
    a = (
        np.full(len(lo), floor)
        if box_alpha is None
        else np.maximum(np.asarray(box_alpha, np.float64), limits.GGX_ALPHA_MIN)
    )
    reach = np.full(len(r), np.inf)  # min over boxes of distance x alpha (m)
    p = table.position[r]
    for i in range(0, len(lo), 256):  # (lights x 256 boxes) at a time
        gap = np.maximum(np.maximum(lo[None, i : i + 256] - p[:, None], 0.0), 0.0)
        gap = np.maximum(gap, p[:, None] - hi[None, i : i + 256])
        d = np.sqrt((gap * gap).sum(axis=2)) * a[None, i : i + 256]
        reach = np.minimum(reach, d.min(axis=1))
    bound = limits.AREA_SPEC_POINT * (1.0 - 1e-3)
    with np.errstate(divide="ignore", invalid="ignore"):
        ok = radius < bound * reach
    out[sph] = ok | no_spec
    return out


def pack_lights(
    table: LightTable, rows: np.ndarray, shadow_maps: np.ndarray | None = None
) -> np.ndarray:
    """(n, 36) float32 std430 records for the FoV rows."""
    n = len(rows)
    out = np.zeros((n, LIGHT_STRIDE_FLOATS), dtype=np.float32)
    if n == 0:
        return out
    t = table
    C = sc  # columns of struct Light (shader_constants.LIGHT_LAYOUT)
    out[:, C.LIGHT_COL_POSITION : C.LIGHT_COL_POSITION + 3] = t.position[rows]
    out[:, C.LIGHT_COL_RANGE] = t.range[rows]
    out[:, C.LIGHT_COL_AXIS : C.LIGHT_COL_AXIS + 3] = t.direction[rows]
    out[:, C.LIGHT_COL_EMISSION] = t.emission[rows]
    out[:, C.LIGHT_COL_TANGENT : C.LIGHT_COL_TANGENT + 3] = t.tangent[rows]
    out[:, C.LIGHT_COL_TEXTURE_LAYER] = t.texture_layer[rows]
    out[:, C.LIGHT_COL_INTENSITY : C.LIGHT_COL_INTENSITY + 3] = t.intensity[rows]
    out[:, C.LIGHT_COL_FLUX] = t.flux[rows]
    cut = t.cone_cutoff[rows]
    out[:, C.LIGHT_COL_COS_CUTOFF] = np.cos(cut)
    out[:, C.LIGHT_COL_CUTOFF] = cut
    out[:, C.LIGHT_COL_CONE_START] = t.cone_start[rows]
    out[:, C.LIGHT_COL_FOCUS] = t.focus[rows]
    out[:, C.LIGHT_COL_FOCUS_TINT : C.LIGHT_COL_FOCUS_TINT + 3] = t.focus_tint[rows]
    out[:, C.LIGHT_COL_IES_LAYER] = t.ies_layer[rows]
    out[:, C.LIGHT_COL_IES_SCALE] = t.ies_scale[rows]
    out[:, C.LIGHT_COL_IES_ANGLE_SCALE] = t.ies_angle_scale[rows]
    out[:, C.LIGHT_COL_SHADOW_MAP] = C.LIGHT_INDEX_NONE if shadow_maps is None else shadow_maps
    flags = t.shadow_enable[rows].astype(np.float32) + 2.0 * t.shadow_dynamic[rows]
    out[:, C.LIGHT_COL_SHADOW_FLAGS] = flags
    out[:, C.LIGHT_COL_SHADOW_COLOR : C.LIGHT_COL_SHADOW_COLOR + 3] = t.shadow_color[rows]
    out[:, C.LIGHT_COL_SHADOW_DISTANCE] = t.shadow_distance[rows]
    out[:, C.LIGHT_COL_SHADOW_FALLOFF] = t.shadow_falloff[rows]
    out[:, C.LIGHT_COL_SHADOW_FALLOFF_GAMMA] = t.shadow_falloff_gamma[rows]
    out[:, C.LIGHT_COL_DIFFUSE] = t.diffuse[rows]
    out[:, C.LIGHT_COL_SPECULAR] = t.specular[rows]
    out[:, C.LIGHT_COL_AREA_SIZE_X] = t.area_size[rows, 0]
    out[:, C.LIGHT_COL_AREA_SIZE_Y] = t.area_size[rows, 1]
    out[:, C.LIGHT_COL_AREA_KIND] = t.area_kind[rows]
    out[:, C.LIGHT_COL_AREA_RADIANCE] = t.area_radiance[rows]
    return out
