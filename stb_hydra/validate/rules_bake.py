"""``StaticBake`` (stage validator): static lights and baked lightmaps (``stb bake``).

* ``static_light_dynamic_geometry`` -- a light marked ``stb:mobility = "static"``
  whose influence sphere meets the bounds of dynamic geometry: once baked, that
  geometry gets the light unshadowed (docs/BAKE.md). The range is the one the
  renderer and ``stb bake`` use: authored ``stb:range``, else the automatic range at
  the exposure of the stage's first camera (exposure 1 without a camera).
* ``lightmap_density`` -- a baked mesh whose ``stb:lightmap:texelDensity`` is under
  ``limits.VALIDATE_LIGHTMAP_TEXEL_DENSITY_MIN``.
* ``bake_stale`` -- the stage has a bake record (``customLayerData["stb:bake"]`` in
  its layer stack, written by ``stb bake``) and a baked light moved, changed, went
  away or was marked baked without being in the record.
"""

from __future__ import annotations

import numpy as np
from pxr import Usd, UsdGeom

from .. import limits
from ..scene import prims
from ..scene.cameras import exposure_scale
from ..scene.lights import influence_range
from .analysis import analysis_for
from .common import finding
from .findings import Finding

#: Names written by ``stb bake`` (stb_hydra/bake/baker.py).
LAYER_KEY = "stb:bake"
DENSITY_ATTR = "stb:lightmap:texelDensity"
BAKED_ATTR = "stb:baked"


def check_bake(stage: Usd.Stage) -> list[Finding]:
    out = _dynamic_overlap(stage)
    out += _density(stage)
    out += _stale(stage)
    return out


def _dynamic_overlap(stage: Usd.Stage) -> list[Finding]:
    ana = analysis_for(stage)
    static = [r for r in ana.local_lights() if r.light.mobility == prims.MOBILITY_STATIC]
    dyn = [m for m in ana.meshes if m.dynamic]
    if not static or not dyn:
        return []
    boxes = []
    for m in dyn:
        pts = np.c_[np.asarray(m.points, dtype=np.float64), np.ones(len(m.points))]
        w = np.einsum("ni,kij->knj", pts, m.world_transforms())[..., :3].reshape(-1, 3)
        w = w[np.all(np.isfinite(w), axis=1)]
        if len(w):
            boxes.append((m.path, w.min(axis=0), w.max(axis=0)))
    exposure, cam = _camera_exposure(stage)
    at = f" at the exposure of <{cam}>" if cam else ""
    out: list[Finding] = []
    for r in static:
        c = np.asarray(r.light.position, dtype=np.float64)
        rad = float(r.light.range)
        if not r.light.range_authored and np.isfinite(rad):
            rad = float(influence_range(np.asarray([r.light.peak_intensity]), exposure)[0])
        hit = [path for path, lo, hi in boxes if np.linalg.norm(np.clip(c, lo, hi) - c) < rad]
        if hit:
            more = f" and {len(hit) - 1} more" if len(hit) > 1 else ""
            out.append(
                finding(
                    "static_light_dynamic_geometry",
                    r.prim_path,
                    f"static light's influence ({rad:.3g} m{at}) reaches dynamic geometry "
                    f"<{hit[0]}>{more}",
                )
            )
    return out


def _camera_exposure(stage: Usd.Stage) -> tuple[float, str | None]:
    """Linear exposure scale of the stage's first camera (the one ``stb render`` and
    ``stb bake`` use by default) and its path; (1, None) without a camera."""
    for prim in stage.Traverse():
        if prim.IsA(UsdGeom.Camera):
            return exposure_scale(prim, Usd.TimeCode.EarliestTime()), str(prim.GetPath())
    return 1.0, None


def _density(stage: Usd.Stage) -> list[Finding]:
    lo = limits.VALIDATE_LIGHTMAP_TEXEL_DENSITY_MIN
    out: list[Finding] = []
    for prim in stage.Traverse():
        a = prim.GetAttribute(DENSITY_ATTR)
        if not a or not a.HasAuthoredValue():
            continue
        d = a.Get()
        if d is None or not (float(d) >= lo):
            out.append(
                finding(
                    "lightmap_density",
                    str(prim.GetPath()),
                    f"lightmap texel density {float(d) if d is not None else float('nan'):.3g} "
                    f"texels/m is under {lo:g} texels/m",
                )
            )
    return out


def _bake_record(stage: Usd.Stage) -> dict | None:
    for layer in stage.GetLayerStack(includeSessionLayers=False):
        rec = layer.customLayerData.get(LAYER_KEY)
        if isinstance(rec, dict):
            return rec
    return None


def _stale(stage: Usd.Stage) -> list[Finding]:
    rec = _bake_record(stage)
    baked = [
        p
        for p in stage.Traverse()
        if (a := p.GetAttribute(BAKED_ATTR)) and a.HasAuthoredValue() and a.Get()
    ]
    if rec is None:
        return [
            finding(
                "bake_stale",
                str(p.GetPath()),
                "marked stb:baked but the stage has no bake record (customLayerData 'stb:bake')",
            )
            for p in baked
        ]
    from ..bake.baker import light_fingerprint

    fps = dict(rec.get("lights", {}) or {})
    when = rec.get("time", "?")
    out: list[Finding] = []
    for path, fp in sorted(fps.items()):
        prim = stage.GetPrimAtPath(path)
        if not prim:
            out.append(finding("bake_stale", path, f"baked light is gone (bake of {when})"))
        elif light_fingerprint(prim) != fp:
            out.append(
                finding(
                    "bake_stale",
                    path,
                    f"baked light moved or changed since the bake of {when}",
                )
            )
    for p in baked:
        if str(p.GetPath()) not in fps:
            out.append(
                finding(
                    "bake_stale",
                    str(p.GetPath()),
                    f"marked stb:baked but not in the bake of {when}",
                )
            )
    return out


__all__ = ["check_bake"]
