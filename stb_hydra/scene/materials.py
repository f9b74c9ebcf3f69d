"""UsdShade materials -> :class:`MaterialPrim` (UsdPreviewSurface constant inputs).

Only constant inputs are read. An input driven by a texture reader uses the
reader's ``inputs:fallback`` (or the UsdPreviewSurface default) and the
material records a warning; MaterialX-only materials fall back to defaults
(``MaterialPrim.uses_defaults``, with a warning).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from pxr import Sdf, Usd, UsdShade

from .prims import MaterialPrim

_DEFAULTS = {
    "diffuseColor": (0.18, 0.18, 0.18),
    "roughness": 0.5,
    "metallic": 0.0,
    "emissiveColor": (0.0, 0.0, 0.0),
    "opacity": 1.0,
    "useSpecularWorkflow": 0,
    "specularColor": (0.0, 0.0, 0.0),
    "ior": 1.5,
}


def _input_value(
    shader: UsdShade.Shader, name: str, time: Usd.TimeCode, warnings: list[str]
) -> Any:
    """Constant value of input ``name``: authored, a connected reader's fallback, or the
    UsdPreviewSurface default (a connection adds a warning)."""
    inp = shader.GetInput(name)
    if not inp:
        return _DEFAULTS[name]
    if inp.HasConnectedSource():
        src = inp.GetConnectedSources()[0]
        src_shader = UsdShade.Shader(src[0].source.GetPrim()) if src else None
        warnings.append(f"input '{name}' is connected (textures are not sampled); using a constant")
        if src_shader:
            fb = src_shader.GetInput("fallback")
            v = fb.Get(time) if fb else None
            if v is not None:
                try:
                    arr = np.asarray(v, dtype=np.float64).reshape(-1)
                    return tuple(arr[:3]) if isinstance(_DEFAULTS[name], tuple) else float(arr[0])
                except (TypeError, ValueError):
                    pass
        return _DEFAULTS[name]
    v = inp.Get(time)
    return _DEFAULTS[name] if v is None else v


def _color(v: Any) -> np.ndarray:
    arr = np.asarray(v, dtype=np.float64).reshape(-1)
    if arr.size < 3:
        arr = np.full(3, float(arr[0]) if arr.size else 0.0)
    arr = np.where(np.isfinite(arr[:3]), arr[:3], 0.0)
    return np.maximum(arr, 0.0)


def _scalar(v: Any, lo: float, hi: float, default: float) -> float:
    try:
        f = float(v)
    except (TypeError, ValueError):
        return default
    if not np.isfinite(f):
        return default
    return min(max(f, lo), hi)


def _surface_shader(mat: UsdShade.Material) -> UsdShade.Shader | None:
    """The material's surface shader, or None when there is none (or it is unreadable)."""
    try:
        src = mat.ComputeSurfaceSource()
        shader = src[0] if src and src[0] else None
    except Exception:  # noqa: BLE001 - bad input must never crash
        return None
    if shader is None or not shader.GetPrim().IsValid():
        return None
    return shader


def _use_defaults(mp: MaterialPrim, why: str) -> MaterialPrim:
    """Mark ``mp`` as defaults-only (``uses_defaults``) with a warning saying why."""
    mp.uses_defaults = True
    mp.warnings.append(f"material <{mp.path}>: {why}; using defaults")
    return mp


def read_material(prim: Usd.Prim, time: Usd.TimeCode) -> MaterialPrim:
    """Constant UsdPreviewSurface inputs of a material; ``uses_defaults`` without one."""
    mp = MaterialPrim(path=str(prim.GetPath()))
    shader = _surface_shader(UsdShade.Material(prim))
    if shader is None or shader.GetShaderId() != "UsdPreviewSurface":
        # MaterialX networks authored in USD (ND_* shaders, the mtlx render context).
        from .materialx import read_usd_materialx

        mx_mp = read_usd_materialx(prim, time)
        if mx_mp is not None:
            return mx_mp
    if shader is None:
        return _use_defaults(mp, "no UsdPreviewSurface surface")
    sid = shader.GetShaderId()
    if sid != "UsdPreviewSurface":
        return _use_defaults(mp, f"surface shader '{sid}' is not UsdPreviewSurface")
    w: list[str] = []
    mp.diffuse_color = _color(_input_value(shader, "diffuseColor", time, w))
    mp.roughness = _scalar(_input_value(shader, "roughness", time, w), 0.0, 1.0, 0.5)
    mp.metallic = _scalar(_input_value(shader, "metallic", time, w), 0.0, 1.0, 0.0)
    mp.emissive_color = _color(_input_value(shader, "emissiveColor", time, w))
    mp.opacity = _scalar(_input_value(shader, "opacity", time, w), 0.0, 1.0, 1.0)
    mp.use_specular_workflow = bool(_input_value(shader, "useSpecularWorkflow", time, w))
    mp.specular_color = _color(_input_value(shader, "specularColor", time, w))
    mp.ior = _scalar(_input_value(shader, "ior", time, w), 1.0, 4.0, 1.5)
    mp.warnings.extend(f"material <{mp.path}>: {m}" for m in dict.fromkeys(w))
    return mp


def bound_material_path(prim: Usd.Prim) -> str | None:
    """Path of the material bound for full rendering, or None.

    When the winning binding (``ComputeBoundMaterial``: binding strength and purpose
    resolved by USD) targets a path with no Material prim -- the materials of a
    ``.mtlx`` reference, which usd-core cannot compose and the scene index synthesises
    (:mod:`stb_hydra.scene.materialx`) -- that relationship's material target is
    returned: renderers look it up among the scene's materials."""
    try:
        mat, rel = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()
    except Exception:  # noqa: BLE001 - bad input must never crash
        return None
    if not mat:
        if not rel:
            return None
        try:
            # A collection binding targets (collection, material); a direct one (material).
            targets = [t for t in rel.GetTargets() if t.IsPrimPath()]
        except Exception:  # noqa: BLE001
            return None
        return str(targets[-1]) if targets else None
    p = mat.GetPath()
    return str(p) if p != Sdf.Path.emptyPath else None
