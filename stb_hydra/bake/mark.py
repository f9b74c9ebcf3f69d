"""Mark a stage's unanimated local lights static (a helper for trying ``stb bake``).

``mark_static_layer(scene, out)`` writes a layer that sublayers ``scene``, turns
instanceable ancestors of those lights into plain prims (a layer cannot edit a
light inside an instance) and authors ``stb:mobility = "static"`` on every local
light whose attributes and transform (ancestors included) are not time-varying.
"""

from __future__ import annotations

import os
from pathlib import Path

from pxr import Sdf, Usd, UsdGeom, UsdLux

from ..io.files import write_text_atomic


def _animated(prim: Usd.Prim) -> bool:
    if any(a.ValueMightBeTimeVarying() for a in prim.GetAttributes()):
        return True
    p = prim
    while p and not p.IsPseudoRoot():
        x = UsdGeom.Xformable(p)
        if x and x.TransformMightBeTimeVarying():
            return True
        p = p.GetParent()
    return False


def mark_static_layer(scene: str | os.PathLike[str], out: str | os.PathLike[str]) -> list[str]:
    """Write ``out``; returns the light paths marked static."""
    scene_p, out_p = Path(scene).resolve(), Path(out).resolve()
    stage = Usd.Stage.Open(str(scene_p))
    layer = Sdf.Layer.CreateAnonymous(".usda")
    layer.subLayerPaths.append(os.path.relpath(scene_p, out_p.parent))
    root = stage.GetRootLayer()
    for key in (
        "upAxis",
        "metersPerUnit",
        "startTimeCode",
        "endTimeCode",
        "framesPerSecond",
        "timeCodesPerSecond",
    ):
        if root.pseudoRoot.HasInfo(key):
            layer.pseudoRoot.SetInfo(key, root.pseudoRoot.GetInfo(key))
    if root.defaultPrim:
        layer.defaultPrim = root.defaultPrim
    marked: list[str] = []
    for prim in Usd.PrimRange(stage.GetPseudoRoot(), Usd.TraverseInstanceProxies()):
        if (
            not prim.HasAPI(UsdLux.LightAPI)
            or prim.IsA(UsdLux.DistantLight)
            or prim.IsA(UsdLux.DomeLight)
        ):
            continue
        if _animated(prim):
            continue
        p = prim
        while p and not p.IsPseudoRoot():
            if p.IsInstance():
                spec = Sdf.CreatePrimInLayer(layer, p.GetPath())
                spec.specifier = Sdf.SpecifierOver
                spec.SetInfo("instanceable", False)
            p = p.GetParent()
        spec = Sdf.CreatePrimInLayer(layer, prim.GetPath())
        spec.specifier = Sdf.SpecifierOver
        a = Sdf.AttributeSpec(
            spec, "stb:mobility", Sdf.ValueTypeNames.Token, Sdf.VariabilityUniform
        )
        a.default = "static"
        marked.append(str(prim.GetPath()))
    write_text_atomic(out_p, layer.ExportToString())
    return marked


__all__ = ["mark_static_layer"]
