"""What the previewer's Materials panel shows: each material the renderer draws, its
inputs (a constant, a texture or a primvar), what each texture became on the GPU
(size, decode, downscale) and what fell back (warnings, notes). No imgui here: the
records are plain data (tested without a window)."""

from __future__ import annotations

import os
from typing import Any

from ..renderer.gl_delegate import GLRenderDelegate
from ..renderer.material_binding import SLOT_INPUTS
from ..renderer.textures import TextureKey
from ..scene.prims import MaterialPrim

#: Constant inputs shown, in order (UsdPreviewSurface names -> MaterialPrim fields).
_CONSTANTS = (
    ("diffuseColor", "diffuse_color"),
    ("emissiveColor", "emissive_color"),
    ("specularColor", "specular_color"),
    ("metallic", "metallic"),
    ("roughness", "roughness"),
    ("opacity", "opacity"),
    ("opacityThreshold", "opacity_threshold"),
    ("ior", "ior"),
    ("occlusion", "occlusion"),
    ("normal", "normal"),
    ("clearcoat", "clearcoat"),
)


def _fmt(v: Any) -> str:
    try:
        import numpy as np

        a = np.asarray(v, dtype=float).reshape(-1)
        return ", ".join(f"{x:.4g}" for x in a)
    except (TypeError, ValueError):
        return str(v)


def material_records(delegate: GLRenderDelegate) -> list[dict[str, Any]]:
    """One record per material sprim: ``path``, ``source``, ``meshes`` (how many
    draw with it), ``inputs`` (list of (input, kind, text)), ``warnings``, ``notes``."""
    users: dict[str, int] = {}
    for rp in delegate.meshes.values():
        if rp.mesh is not None and rp.mesh.material:
            users[rp.mesh.material] = users.get(rp.mesh.material, 0) + 1
    out = []
    for path in sorted(delegate.materials):
        mat: MaterialPrim | None = delegate.materials[path].material
        if mat is None:
            continue
        rows: list[tuple[str, str, str]] = []
        for name, field in _CONSTANTS:
            ref = mat.textures.get(name)
            if ref is not None:
                rows.append((name, "texture", _texture_text(delegate, ref)))
                continue
            pv = mat.primvars.get(name)
            if pv is not None:
                rows.append((name, "primvar", f"{pv.name} (fallback {_fmt(pv.fallback)})"))
                continue
            rows.append((name, "constant", _fmt(getattr(mat, field))))
        for name, ref in mat.textures.items():
            if name not in SLOT_INPUTS and name not in dict(_CONSTANTS):
                rows.append((name, "texture (not rendered)", _texture_text(delegate, ref)))
        out.append(
            {
                "path": path,
                "source": mat.source or ("defaults" if mat.uses_defaults else ""),
                "meshes": users.get(path, 0),
                "inputs": rows,
                "warnings": list(mat.warnings),
                "notes": list(mat.notes),
            }
        )
    return out


def _texture_text(delegate: GLRenderDelegate, ref: Any) -> str:
    name = os.path.basename(ref.file) if ref.file else (ref.asset or "?")
    t = delegate.textures.textures.get(TextureKey(ref.file, ref.source_color_space))
    parts = [name, f"[{ref.channels}]", ref.source_color_space]
    if ref.st != "st":
        parts.append(f"st={ref.st}")
    if t is None:
        parts.append("not loaded: fallback " + _fmt(ref.fallback))
    else:
        w, h = t.texture.width, t.texture.height
        parts.append(f"{w}x{h}" + (f" x{t.layers} tiles" if t.layers > 1 else ""))
        parts.append(t.decode.kind + (f" from {t.decode.space}" if t.decode.space else ""))
        if t.shrink > 1:
            parts.append(f"downscaled 1/{t.shrink}")
    return " ".join(parts)
