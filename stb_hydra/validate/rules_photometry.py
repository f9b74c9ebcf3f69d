"""``Photometry`` (stage validator): luminous flux per light and per prefab.

Flux is the engine's own estimate (``LightPrim.flux``: luminance channel, lm) at the
stage's start time, after every UsdLux scalar, shaping and IES. Lights already
reported as invalid by ``LightValues`` are skipped (their flux is meaningless).
"""

from __future__ import annotations

import math

from pxr import Usd

from .. import limits
from .analysis import analysis_for
from .common import finding
from .findings import Finding


def check_photometry(stage: Usd.Stage) -> list[Finding]:
    ana = analysis_for(stage)
    lo, hi = limits.VALIDATE_LIGHT_FLUX_RANGE_LM
    out: list[Finding] = []
    for r in ana.local_lights():
        if not r.aggregate:
            continue
        f = float(r.light.flux)
        if math.isfinite(f) and lo <= f <= hi:
            continue
        side = "below" if math.isfinite(f) and f < lo else "above"
        where = f" (PointInstancer <{r.instancer}>)" if r.instancer else ""
        out.append(
            finding(
                "flux_light",
                r.prim_path,
                f"luminous flux {f:.4g} lm is {side} the plausible band [{lo:g}, {hi:g}] lm{where}",
            )
        )
    for prefab, recs in ana.prefabs().items():
        total = float(sum(r.light.flux for r in recs))
        if total > limits.VALIDATE_PREFAB_FLUX_MAX_LM:
            out.append(
                finding(
                    "flux_prefab",
                    prefab,
                    f"{len(recs)} lights emit {total:.4g} lm in total "
                    f"(limit {limits.VALIDATE_PREFAB_FLUX_MAX_LM:g} lm per prefab)",
                )
            )
    return out
