"""``StageUnits`` (stage validator): ``metersPerUnit`` / ``upAxis``.

* ``units_missing``: the root layer (or session layer) authors neither value -> USD
  falls back to centimetres (0.01) and Y up, and every light size, range and flux of
  a metre-scale asset is off by 100x. Supersedes usdGeomValidators:StageMetadataChecker.
* ``units_mismatch``: USD applies no unit conversion across composition arcs, so a
  sublayer, reference or payload whose layer authors different units or up axis than
  the stage is drawn at the wrong scale/orientation -- unless the referencing prim's
  world transform compensates (scale within VALIDATE_UNITS_RTOL of the unit ratio;
  the layer's up axis mapped onto the stage's up axis).
"""

from __future__ import annotations

import math

import numpy as np
from pxr import Pcp, Sdf, Usd, UsdGeom

from .. import limits
from .common import finding
from .findings import Finding

_AXES = {
    "X": np.array([1.0, 0.0, 0.0]),
    "Y": np.array([0.0, 1.0, 0.0]),
    "Z": np.array([0.0, 0.0, 1.0]),
}


def _layer_units(layer: Sdf.Layer) -> tuple[float | None, str | None]:
    root = layer.pseudoRoot
    mpu = root.GetInfo("metersPerUnit") if root.HasInfo("metersPerUnit") else None
    up = root.GetInfo("upAxis") if root.HasInfo("upAxis") else None
    return (float(mpu) if mpu is not None else None, str(up) if up is not None else None)


def _same(a: float, b: float) -> bool:
    return abs(a - b) <= limits.VALIDATE_UNITS_RTOL * max(abs(a), abs(b))


def check_units(stage: Usd.Stage) -> list[Finding]:
    out: list[Finding] = []
    missing = [k for k in ("metersPerUnit", "upAxis") if not stage.HasAuthoredMetadata(k)]
    if missing:
        out.append(
            finding(
                "units_missing",
                "/",
                f"root layer does not author {' and '.join(missing)} (USD falls back to "
                "metersPerUnit 0.01 = centimetres, upAxis Y)",
            )
        )
    mpu = float(UsdGeom.GetStageMetersPerUnit(stage))
    up = str(UsdGeom.GetStageUpAxis(stage))
    stack = stage.GetLayerStack(includeSessionLayers=False)
    stack_ids = {lyr.identifier for lyr in stage.GetLayerStack(includeSessionLayers=True)}
    for lyr in stack[1:]:
        lm, lu = _layer_units(lyr)
        diffs = _diffs(lm, lu, mpu, up)
        if diffs:
            out.append(
                finding(
                    "units_mismatch",
                    "/",
                    f"sublayer @{lyr.identifier}@ declares {diffs}; a sublayer's units are "
                    "ignored, its content is read in the stage's units",
                )
            )
    it = iter(stage.Traverse(Usd.TraverseInstanceProxies()))
    for prim in it:
        if not (prim.HasAuthoredReferences() or prim.HasAuthoredPayloads()):
            continue
        for node in prim.GetPrimIndex().rootNode.children:
            if node.arcType not in (Pcp.ArcTypeReference, Pcp.ArcTypePayload):
                continue
            if node.IsDueToAncestor():
                continue
            layer = node.layerStack.identifier.rootLayer
            if layer is None or layer.identifier in stack_ids:
                continue
            lm, lu = _layer_units(layer)
            diffs = _diffs(lm, lu, mpu, up, _compensation(prim))
            if diffs:
                kind = "payload" if node.arcType == Pcp.ArcTypePayload else "reference"
                out.append(
                    finding(
                        "units_mismatch",
                        str(prim.GetPath()),
                        f"{kind} @{layer.identifier}@ declares {diffs}",
                    )
                )
    return out


def _compensation(prim: Usd.Prim) -> np.ndarray:
    """3x3 world linear part (row-vector) of the referencing prim."""
    m = np.array(UsdGeom.XformCache().GetLocalToWorldTransform(prim), dtype=np.float64)
    return m.reshape(4, 4)[:3, :3]


def _diffs(lm, lu, mpu, up, world: np.ndarray | None = None) -> str:
    parts = []
    if lm is not None and math.isfinite(lm) and lm > 0 and not _same(lm, mpu):
        scale = float(np.cbrt(abs(np.linalg.det(world)))) if world is not None else 1.0
        if not _same(scale, lm / mpu):
            parts.append(
                f"metersPerUnit {lm:g} (stage: {mpu:g}, ratio {lm / mpu:g}, no compensating scale)"
            )
    if lu is not None and lu != up and lu in _AXES and up in _AXES:
        mapped = _AXES[lu] @ world if world is not None else _AXES[lu]
        n = float(np.linalg.norm(mapped))
        if n <= 0 or float(mapped @ _AXES[up]) / n < 0.99:
            parts.append(f"upAxis {lu} (stage: {up}, not rotated onto it)")
    return "; ".join(parts)
