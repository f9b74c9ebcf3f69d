"""``ShadowBudget`` (stage validator): shadowed lights, dynamic opt-ins and atlas area
per prefab.

Atlas estimate (the engine's resolution heuristic at a fixed reference view): a light
of influence radius r seen from d = VALIDATE_SHADOW_REFERENCE_DISTANCE_M (floored at
r: a camera inside the sphere sees it fill the screen) covers
``H * r / (d * tan(fov/2))`` pixels of a H = 1080 px, 60-degree view; its map side is
that diameter times SHADOW_TEXELS_PER_PIXEL times sqrt(flux x
VALIDATE_SHADOW_REFERENCE_EXPOSURE_SCALE / SHADOW_REFERENCE_FLUX_LM) (clamped to
SHADOW_FLUX_SCALE_RANGE), rounded to a power of two in [SHADOW_MAP_MIN_SIZE,
SHADOW_MAP_MAX_SIZE]. The prefab's area is the sum of side^2.
"""

from __future__ import annotations

import math

from pxr import Usd

from .. import limits
from ..scene import prims
from ..shadows import policy
from .analysis import LightRecord, analysis_for
from .common import finding
from .findings import Finding


def map_side(range_m: float, flux_lm: float) -> int:
    """Estimated shadow-map side (texels) at the reference view: the engine's own
    resolution policy for a light seen from the reference distance, no map yet."""
    side = policy.choose_resolutions(
        [limits.VALIDATE_SHADOW_REFERENCE_DISTANCE_M],
        [flux_lm * limits.VALIDATE_SHADOW_REFERENCE_EXPOSURE_SCALE],
        [range_m],
        limits.VALIDATE_SHADOW_REFERENCE_HEIGHT_PX,
        math.radians(limits.VALIDATE_SHADOW_REFERENCE_FOV_DEG),
        [0],
    )
    return int(side[0])


def _names(recs: list[LightRecord], n: int = 3) -> str:
    s = ", ".join(f"<{r.prim_path}>" for r in recs[:n])
    return s + (f" and {len(recs) - n} more" if len(recs) > n else "")


def check_shadows(stage: Usd.Stage) -> list[Finding]:
    ana = analysis_for(stage)
    out: list[Finding] = []
    atlas = limits.SHADOW_ATLAS_SIZE_DEFAULT**2
    for prefab, recs in ana.prefabs().items():
        shadowed = [r for r in recs if r.light.shadow_enable]
        n_max = limits.VALIDATE_SHADOWED_LIGHTS_PER_PREFAB_MAX
        if len(shadowed) > n_max:
            out.append(
                finding(
                    "shadow_count",
                    prefab,
                    f"{len(shadowed)} shadowed lights in one prefab (limit {n_max}): "
                    f"{_names(shadowed)}",
                )
            )
        dyn = [r for r in recs if r.light.shadow_update == prims.SHADOW_DYNAMIC]
        for r in dyn:
            note = "" if r.light.shadow_enable else " but inputs:shadow:enable is off (no effect)"
            out.append(
                finding(
                    "shadow_dynamic",
                    r.prim_path,
                    f"opts into dynamic shadows (stb:shadow:update = dynamic){note}",
                )
            )
        dyn_on = [r for r in dyn if r.light.shadow_enable]
        d_max = limits.VALIDATE_DYNAMIC_SHADOWS_PER_PREFAB_MAX
        if len(dyn_on) > d_max:
            out.append(
                finding(
                    "shadow_dynamic_count",
                    prefab,
                    f"{len(dyn_on)} dynamic-shadow lights in one prefab (limit {d_max}): "
                    f"{_names(dyn_on)}",
                )
            )
        area = sum(map_side(r.light.range, r.light.flux) ** 2 for r in shadowed)
        frac = area / atlas
        if frac > limits.VALIDATE_PREFAB_ATLAS_FRACTION_MAX:
            out.append(
                finding(
                    "shadow_atlas",
                    prefab,
                    f"shadow maps of {len(shadowed)} lights need ~{area / 2**20:.1f} Mtexel "
                    f"({frac:.0%} of the {limits.SHADOW_ATLAS_SIZE_DEFAULT}^2 atlas; limit "
                    f"{limits.VALIDATE_PREFAB_ATLAS_FRACTION_MAX:.0%}) seen from "
                    f"{limits.VALIDATE_SHADOW_REFERENCE_DISTANCE_M:g} m",
                )
            )
    return out
