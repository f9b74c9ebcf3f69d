"""FoV light culling (CPU, vectorised) and the packed std430 light buffer.

The packed layout mirrors ``struct Light`` in ``shaders/common/lights.glsl``:
nine vec4 (144 bytes) per light; index in the buffer = position in the FoV list.
"""

from __future__ import annotations

import numpy as np

from .. import limits
from .light_table import LightTable

LIGHT_STRIDE_FLOATS = 36  # 9 x vec4
LIGHT_STRIDE_BYTES = LIGHT_STRIDE_FLOATS * 4
#: Float column of the shadow-map record slot (``Light.shadow.x`` in lights.glsl;
#: -1 = unshadowed): the one column patched when only slots change.
LIGHT_SHADOW_SLOT_COLUMN = 26


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


def pack_lights(
    table: LightTable, rows: np.ndarray, shadow_maps: np.ndarray | None = None
) -> np.ndarray:
    """(n, 36) float32 std430 records for the FoV rows."""
    n = len(rows)
    out = np.zeros((n, LIGHT_STRIDE_FLOATS), dtype=np.float32)
    if n == 0:
        return out
    t = table
    out[:, 0:3] = t.position[rows]
    out[:, 3] = t.range[rows]
    out[:, 4:7] = t.direction[rows]
    out[:, 7] = t.emission[rows]
    out[:, 8:11] = t.tangent[rows]
    out[:, 11] = t.type[rows]
    out[:, 12:15] = t.intensity[rows]
    out[:, 15] = t.flux[rows]
    cut = t.cone_cutoff[rows]
    out[:, 16] = np.cos(cut)
    out[:, 17] = cut
    out[:, 18] = t.cone_start[rows]
    out[:, 19] = t.focus[rows]
    out[:, 20:23] = t.focus_tint[rows]
    out[:, 23] = t.ies_layer[rows]
    out[:, 24] = t.ies_scale[rows]
    out[:, 25] = t.ies_angle_scale[rows]
    out[:, LIGHT_SHADOW_SLOT_COLUMN] = -1.0 if shadow_maps is None else shadow_maps
    out[:, 27] = t.shadow_enable[rows].astype(np.float32) + 2.0 * t.shadow_dynamic[rows]
    out[:, 28:31] = t.shadow_color[rows]
    out[:, 31] = t.shadow_distance[rows]
    out[:, 32] = t.shadow_falloff[rows]
    out[:, 33] = t.shadow_falloff_gamma[rows]
    out[:, 34] = t.diffuse[rows]
    out[:, 35] = t.specular[rows]
    return out
