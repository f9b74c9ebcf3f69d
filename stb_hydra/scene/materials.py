"""UsdShade materials -> :class:`MaterialPrim` (UsdPreviewSurface networks).

A material's surface shader is read input by input. Each input is either a
constant (authored, or the UsdPreviewSurface default) or, when its value comes
from a reader node (followed through node-graph interfaces with
``UsdShade.Input.GetValueProducingAttributes``):

* ``UsdUVTexture`` -> a :class:`TextureRef` (file resolved against the layer that
  authored it, ``<UDIM>`` kept; wrapS/wrapT, fallback, scale, bias,
  sourceColorSpace; the output used: rgb/r/g/b/a), whose ``st`` is followed to a
  ``UsdPrimvarReader_float2`` (any primvar name) through any chain of
  ``UsdTransform2d`` nodes (folded into one affine ``st_transform``); an
  unconnected ``st`` is a constant coordinate;
* ``UsdPrimvarReader_float/float2/float3/float4`` (and the normal/point/vector/int
  variants) -> a primvar input (``MaterialPrim.primvars``): the mesh's primvar of
  that name per vertex, the reader's fallback where the mesh has none;
* anything else -> the reader's ``fallback`` (or the input's default) with one
  warning naming the node.

``displacement`` is not rendered (one warning when it is driven or non-zero).
Materials whose surface is not UsdPreviewSurface go to :mod:`.materialx` when it
can read them (MaterialX networks), else fall back to defaults
(``MaterialPrim.uses_defaults``, with a warning).
"""

from __future__ import annotations

import math
import os
from typing import Any

import numpy as np
from pxr import Sdf, Usd, UsdShade

from .prims import ST_IDENTITY, WRAP_MODES, MaterialPrim, PrimvarRef, TextureRef

#: UsdPreviewSurface inputs and their spec defaults.
_DEFAULTS: dict[str, Any] = {
    "diffuseColor": (0.18, 0.18, 0.18),
    "roughness": 0.5,
    "metallic": 0.0,
    "emissiveColor": (0.0, 0.0, 0.0),
    "opacity": 1.0,
    "opacityThreshold": 0.0,
    "useSpecularWorkflow": 0,
    "specularColor": (0.0, 0.0, 0.0),
    "ior": 1.5,
    "clearcoat": 0.0,
    "clearcoatRoughness": 0.01,
    "occlusion": 1.0,
    "normal": (0.0, 0.0, 1.0),
    "displacement": 0.0,
}
#: Inputs with three components (colours, the normal).
_VECTOR_INPUTS = frozenset({"diffuseColor", "emissiveColor", "specularColor", "normal"})
#: Inputs a texture or primvar may drive (the rest are read as constants only).
_DRIVABLE = frozenset(
    {
        "diffuseColor",
        "emissiveColor",
        "specularColor",
        "metallic",
        "roughness",
        "clearcoat",
        "clearcoatRoughness",
        "opacity",
        "normal",
        "occlusion",
    }
)
_PRIMVAR_READERS = frozenset(
    {
        "UsdPrimvarReader_float",
        "UsdPrimvarReader_float2",
        "UsdPrimvarReader_float3",
        "UsdPrimvarReader_float4",
        "UsdPrimvarReader_int",
        "UsdPrimvarReader_normal",
        "UsdPrimvarReader_point",
        "UsdPrimvarReader_vector",
        "UsdPrimvarReader_string",
    }
)
_OUTPUT_CHANNELS = {"rgb": "rgb", "rgba": "rgba", "r": "r", "g": "g", "b": "b", "a": "a"}
_COLOR_SPACES = ("auto", "sRGB", "raw")
#: Longest UsdTransform2d chain followed (a cycle is an authoring error).
_MAX_CHAIN = 16


def _vec(v: Any, n: int, default: tuple[float, ...]) -> tuple[float, ...]:
    """``v`` as n finite floats (a scalar is broadcast; a short vector is padded from
    ``default``); non-finite or unreadable values give ``default``."""
    try:
        arr = np.asarray(v, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        return default
    if arr.size == 0 or not np.all(np.isfinite(arr)):
        return default
    if arr.size == 1:
        arr = np.full(n, arr[0])
    out = list(default)
    for i in range(min(n, arr.size)):
        out[i] = float(arr[i])
    return tuple(out[:n])


def _color(v: Any) -> np.ndarray:
    arr = np.asarray(_vec(v, 3, (0.0, 0.0, 0.0)), dtype=np.float64)
    return np.maximum(arr, 0.0)


def _scalar(v: Any, lo: float, hi: float, default: float) -> float:
    try:
        f = float(np.asarray(v, dtype=np.float64).reshape(-1)[0])
    except (TypeError, ValueError, IndexError):
        return default
    if not np.isfinite(f):
        return default
    return min(max(f, lo), hi)


def _shader_id(shader: UsdShade.Shader) -> str:
    try:
        return str(shader.GetShaderId() or "")
    except Exception:  # noqa: BLE001 - bad input must never crash
        return ""


def _source_of(inp: UsdShade.Input) -> tuple[UsdShade.Shader | None, str, Any]:
    """What produces ``inp``'s value: (shader, output name, None) when a shader
    output does (through node graphs), else (None, "", the constant value or None)."""
    try:
        attrs = inp.GetValueProducingAttributes(False)
    except Exception:  # noqa: BLE001
        attrs = []
    if not attrs:
        return None, "", None
    a = attrs[0]
    name, kind = UsdShade.Utils.GetBaseNameAndType(a.GetName())
    if kind == UsdShade.AttributeType.Output:
        shader = UsdShade.Shader(a.GetPrim())
        return (shader if shader else None), str(name), None
    return None, "", a.Get()


def _value(shader: UsdShade.Shader, name: str, default: Any, time: Usd.TimeCode) -> Any:
    """Constant value of input ``name`` (through interface connections), else default."""
    inp = shader.GetInput(name)
    if not inp:
        return default
    src, _out, _v = _source_of(inp)
    if src is not None:
        return default  # a value-only input wired to a node: the default stands
    try:
        attrs = inp.GetValueProducingAttributes(False)
        v = attrs[0].Get(time) if attrs else None
    except Exception:  # noqa: BLE001
        v = None
    return default if v is None else v


def _transform2d(shader: UsdShade.Shader, time: Usd.TimeCode) -> np.ndarray:
    """UsdTransform2d as a 3x3 affine (column vectors): ``in * scale``, rotated
    counter-clockwise by ``rotation`` degrees, plus ``translation`` (the spec's order)."""
    s = _vec(_value(shader, "scale", (1.0, 1.0), time), 2, (1.0, 1.0))
    r = math.radians(_scalar(_value(shader, "rotation", 0.0, time), -1e9, 1e9, 0.0))
    t = _vec(_value(shader, "translation", (0.0, 0.0), time), 2, (0.0, 0.0))
    c, sn = math.cos(r), math.sin(r)
    return np.array(
        [[c * s[0], -sn * s[1], t[0]], [sn * s[0], c * s[1], t[1]], [0.0, 0.0, 1.0]],
        dtype=np.float64,
    )


def _primvar_name(shader: UsdShade.Shader, time: Usd.TimeCode) -> str:
    v = _value(shader, "varname", "st", time)
    name = str(v) if v is not None else "st"
    return name.removeprefix("primvars:") or "st"


def _st_of(
    tex: UsdShade.Shader, time: Usd.TimeCode, warn: list[str]
) -> tuple[str, tuple[float, ...]]:
    """(primvar name, 2x3 st transform) of a texture's ``st`` input."""
    m = np.eye(3)
    inp = tex.GetInput("st")
    node = tex
    for _ in range(_MAX_CHAIN):
        if not inp:
            break
        src, _out, const = _source_of(inp)
        if src is None:
            # A constant coordinate: every point reads the same texel.
            st = _vec(const if const is not None else (0.0, 0.0), 2, (0.0, 0.0))
            c = m @ np.array([st[0], st[1], 1.0])
            return "st", (0.0, 0.0, float(c[0]), 0.0, 0.0, float(c[1]))
        sid = _shader_id(src)
        if sid == "UsdTransform2d":
            m = m @ _transform2d(src, time)
            node, inp = src, src.GetInput("in")
            continue
        if sid in _PRIMVAR_READERS:
            flat = (m[0, 0], m[0, 1], m[0, 2], m[1, 0], m[1, 1], m[1, 2])
            return _primvar_name(src, time), tuple(float(x) for x in flat)
        warn.append(
            f"st of <{tex.GetPath()}> comes from unsupported node <{src.GetPath()}> "
            f"('{sid}'); using primvar 'st'"
        )
        break
    else:
        warn.append(f"st of <{node.GetPath()}>: UsdTransform2d chain too long; using 'st'")
    flat = (m[0, 0], m[0, 1], m[0, 2], m[1, 0], m[1, 1], m[1, 2])
    return "st", tuple(float(x) for x in flat) if not np.allclose(m, np.eye(3)) else ST_IDENTITY


def _resolved_file(tex: UsdShade.Shader, time: Usd.TimeCode) -> tuple[str, str]:
    """(resolved path or "", authored path) of a texture's ``file``; ``<UDIM>`` paths
    resolve against the layer that authored them."""
    inp = tex.GetInput("file")
    if not inp:
        return "", ""
    try:
        attrs = inp.GetValueProducingAttributes(False)
        attr = attrs[0] if attrs else inp.GetAttr()
        v = attr.Get(time)
    except Exception:  # noqa: BLE001
        return "", ""
    if not isinstance(v, Sdf.AssetPath):
        return "", str(v or "")
    authored = v.path
    if v.resolvedPath:
        return v.resolvedPath, authored
    if UsdShade.UdimUtils.IsUdimIdentifier(authored):
        layer = _authoring_layer(attr, time)
        if layer is not None:
            try:
                r = UsdShade.UdimUtils.ResolveUdimPath(authored, layer)
            except Exception:  # noqa: BLE001
                r = ""
            if r:
                return r, authored
            # No tile resolved: keep the pattern next to the layer (the cache warns).
            if not os.path.isabs(authored) and not layer.anonymous:
                base = os.path.dirname(layer.realPath)
                return os.path.normpath(os.path.join(base, authored)), authored
    return "", authored


def _authoring_layer(attr: Usd.Attribute, time: Usd.TimeCode) -> Sdf.Layer | None:
    try:
        stack = attr.GetPropertyStack(time)
    except Exception:  # noqa: BLE001
        return None
    for spec in stack:
        if spec.HasDefaultValue() or spec.layer.GetNumTimeSamplesForPath(spec.path):
            return spec.layer
    return stack[0].layer if stack else None


def _wrap(tex: UsdShade.Shader, name: str, time: Usd.TimeCode, warn: list[str]) -> str:
    v = str(_value(tex, name, "useMetadata", time) or "useMetadata")
    if v not in WRAP_MODES:
        warn.append(f"<{tex.GetPath()}>: {name} '{v}' is not a wrap mode; using 'useMetadata'")
        return "useMetadata"
    return v


def _texture_ref(
    tex: UsdShade.Shader, output: str, time: Usd.TimeCode, warn: list[str]
) -> TextureRef:
    resolved, authored = _resolved_file(tex, time)
    if not resolved:
        if authored:
            warn.append(f"texture <{tex.GetPath()}>: file '{authored}' not found; using fallback")
        else:
            warn.append(f"texture <{tex.GetPath()}>: no file; using fallback")
    cs = str(_value(tex, "sourceColorSpace", "auto", time) or "auto")
    if cs not in _COLOR_SPACES:
        warn.append(f"texture <{tex.GetPath()}>: sourceColorSpace '{cs}' unknown; using 'auto'")
        cs = "auto"
    st, xf = _st_of(tex, time, warn)
    return TextureRef(
        file=resolved,
        asset=authored,
        source_color_space=cs,
        wrap_s=_wrap(tex, "wrapS", time, warn),
        wrap_t=_wrap(tex, "wrapT", time, warn),
        channels=_OUTPUT_CHANNELS.get(output, "rgb"),
        scale=_vec(_value(tex, "scale", None, time), 4, (1.0, 1.0, 1.0, 1.0)),  # type: ignore[arg-type]
        bias=_vec(_value(tex, "bias", None, time), 4, (0.0, 0.0, 0.0, 0.0)),  # type: ignore[arg-type]
        fallback=_vec(_value(tex, "fallback", None, time), 4, (0.0, 0.0, 0.0, 1.0)),  # type: ignore[arg-type]
        st=st,
        st_transform=xf,  # type: ignore[arg-type]
        owner=str(tex.GetPath()),
    )


def _fallback_of(src: UsdShade.Shader, name: str, time: Usd.TimeCode) -> Any:
    v = _value(src, "fallback", None, time)
    if v is None:
        return _DEFAULTS[name]
    if name in _VECTOR_INPUTS:
        return _vec(v, 3, tuple(_DEFAULTS[name]))
    return _vec(v, 1, (float(_DEFAULTS[name]),))[0]


def _read_input(
    surface: UsdShade.Shader, name: str, time: Usd.TimeCode, mp: MaterialPrim, warn: list[str]
) -> Any:
    """Constant value of UsdPreviewSurface input ``name``; a texture or primvar reader
    driving it is recorded in ``mp`` (the constant is then the reader's fallback)."""
    inp = surface.GetInput(name)
    if not inp:
        return _DEFAULTS[name]
    src, output, const = _source_of(inp)
    if src is None:
        return _DEFAULTS[name] if const is None else const
    sid = _shader_id(src)
    if name not in _DRIVABLE:
        if name == "displacement":
            return _DEFAULTS[name]  # reported by the caller
        warn.append(f"input '{name}' is driven by <{src.GetPath()}>; only a constant is read")
        return _DEFAULTS[name]
    if sid == "UsdUVTexture":
        ref = _texture_ref(src, output, time, warn)
        if ref.file:
            mp.textures[name] = ref
        fb = ref.fallback
        return fb[:3] if name in _VECTOR_INPUTS else fb[_channel_index(ref.channels)]
    if sid in _PRIMVAR_READERS:
        pv = _primvar_name(src, time)
        fb = _fallback_of(src, name, time)
        fbt = tuple(fb) if name in _VECTOR_INPUTS else (float(fb),)
        mp.primvars[name] = PrimvarRef(pv, fbt, owner=str(src.GetPath()))  # type: ignore[arg-type]
        return fb
    warn.append(
        f"input '{name}' is driven by unsupported node <{src.GetPath()}> ('{sid}'); "
        "using its fallback"
    )
    return _fallback_of(src, name, time)


def _channel_index(channels: str) -> int:
    return {"r": 0, "g": 1, "b": 2, "a": 3}.get(channels, 0)


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
    """A UsdPreviewSurface material (constants, textures, primvar readers); a MaterialX
    network through :mod:`.materialx`; ``uses_defaults`` without either."""
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
    sid = _shader_id(shader)
    if sid != "UsdPreviewSurface":
        return _use_defaults(mp, f"surface shader '{sid}' is not UsdPreviewSurface")
    read_preview_surface(shader, time, mp)
    return mp


def read_preview_surface(shader: UsdShade.Shader, time: Usd.TimeCode, mp: MaterialPrim) -> None:
    """Fill ``mp`` from a UsdPreviewSurface shader prim (``source`` set)."""
    w: list[str] = []
    mp.source = "UsdPreviewSurface"

    def get(name: str) -> Any:
        return _read_input(shader, name, time, mp, w)

    mp.diffuse_color = _color(get("diffuseColor"))
    mp.roughness = _scalar(get("roughness"), 0.0, 1.0, 0.5)
    mp.metallic = _scalar(get("metallic"), 0.0, 1.0, 0.0)
    mp.emissive_color = _color(get("emissiveColor"))
    mp.opacity = _scalar(get("opacity"), 0.0, 1.0, 1.0)
    mp.opacity_threshold = _scalar(get("opacityThreshold"), 0.0, 1.0, 0.0)
    mp.use_specular_workflow = bool(_scalar(get("useSpecularWorkflow"), 0.0, 1.0, 0.0) > 0.5)
    mp.specular_color = _color(get("specularColor"))
    mp.ior = _scalar(get("ior"), 1.0, 4.0, 1.5)
    mp.clearcoat = _scalar(get("clearcoat"), 0.0, 1.0, 0.0)
    mp.clearcoat_roughness = _scalar(get("clearcoatRoughness"), 0.0, 1.0, 0.01)
    mp.occlusion = _scalar(get("occlusion"), 0.0, 1.0, 1.0)
    n = np.asarray(_vec(get("normal"), 3, (0.0, 0.0, 1.0)), dtype=np.float64)
    ln = float(np.linalg.norm(n))
    mp.normal = n / ln if ln > 1e-12 else np.array([0.0, 0.0, 1.0])
    disp = shader.GetInput("displacement")
    if disp:
        src, _o, const = _source_of(disp)
        if src is not None or _scalar(const if const is not None else 0.0, -1e30, 1e30, 0.0):
            w.append("displacement is not rendered")
    if mp.opacity_threshold <= 0.0 and (mp.opacity < 1.0 or "opacity" in mp.textures):
        w.append("translucent opacity is drawn opaque (cut-outs need opacityThreshold > 0)")
    mp.warnings.extend(f"material <{mp.path}>: {m}" for m in dict.fromkeys(w))


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
