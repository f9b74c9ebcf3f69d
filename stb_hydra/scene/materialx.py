"""MaterialX looks -> :class:`MaterialPrim` (no GL).

usd-core ships no usdMtlx plugin, so a reference such as
``def Scope "Materials" (prepend references = @./Bishop_mat.mtlx@</MaterialX/Materials>)``
does not compose ("Cannot determine file format") and meshes bound to
``</Bishop/Materials/M_Bishop_B>`` find no Material. This module stands in for it:

* :func:`mtlx_references` finds the ``.mtlx`` references and payloads in a prim's
  composed prim stack (variant specs included), resolved against the layer that
  authored them; :func:`material_prim_paths` names the Material prims usdMtlx would
  have composed there (``pxr/usd/usdMtlx/reader.cpp``: a document's materials live at
  ``/MaterialX/Materials/<name>``, a ``:`` in a name becoming ``__``).
* :class:`MtlxDocumentCache` reads documents (``MaterialX.readFromXmlFile``, upgraded
  to the package's version on read) once per resolved file (re-read when the file
  changes), with the package's standard data libraries as their data library (node
  definitions and input defaults).
* Each ``surfacematerial`` is translated onto our UsdPreviewSurface-shaped
  :class:`MaterialPrim` (``source="MaterialX"``) following MaterialX's own
  ``standard_surface`` -> UsdPreviewSurface translation graph
  (``libraries/bxdf/translation/standard_surface_to_usd.mtlx``); ``UsdPreviewSurface``
  nodes map one to one. Node graphs are reduced to one :class:`TextureRef` per input
  (``image``/``tiledimage``/``UsdUVTexture`` with constant ``multiply``/``add``/
  ``subtract``/``divide``/``mix`` folded into ``scale``/``bias``, channel picks, texture
  coordinates from ``texcoord``/``geompropvalue``/``UsdPrimvarReader`` with constant
  affine maps and ``UsdTransform2d`` folded into ``st_transform``, ``normalmap`` as a
  tangent-space normal). Anything else falls back to the input's constant with one
  warning naming the material and the node. Inputs with no lobe in our BRDF
  (subsurface, transmission, sheen, thin film, anisotropy, ...) become
  ``MaterialPrim.notes``, not warnings.
* :func:`read_usd_materialx` reads the same networks authored directly in USD
  (shaders whose ``info:id`` is a MaterialX node definition, e.g.
  ``ND_standard_surface_surfaceshader``, the ``mtlx`` render context).

The translation table and its limits are in ``docs/MATERIALS.md``.
"""

from __future__ import annotations

import glob
import math
import os
import threading
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from pxr import Ar, Sdf, Usd, UsdShade

from .prims import ST_IDENTITY, MaterialPrim, TextureRef

SOURCE = "MaterialX"
#: Node definitions of the surface shaders we translate.
STANDARD_SURFACE = "standard_surface"
USD_PREVIEW_SURFACE = "UsdPreviewSurface"

Vec = tuple[float, ...]
Affine = tuple[float, float, float, float, float, float]

# --- the standard data libraries --------------------------------------------------------

_LIB_LOCK = threading.Lock()
_LIB: Any = None


def standard_library() -> Any:
    """The ``materialx`` package's data libraries (stdlib, pbrlib, bxdf, ...) as one
    ``MaterialX.Document``, loaded once. The wheel ships them in its own folder
    (``MaterialX/libraries``), which is ``getDefaultDataSearchPath()``."""
    global _LIB
    with _LIB_LOCK:
        if _LIB is None:
            import MaterialX as mx

            lib = mx.createDocument()
            mx.loadLibraries(mx.getDefaultDataLibraryFolders(), mx.getDefaultDataSearchPath(), lib)
            _LIB = lib
        return _LIB


# --- values -------------------------------------------------------------------------------

_SIZES = {
    "float": 1,
    "integer": 1,
    "boolean": 1,
    "vector2": 2,
    "color3": 3,
    "vector3": 3,
    "color4": 4,
    "vector4": 4,
}
_COLOR_TYPES = ("color3", "color4")


def _vec(v: Any) -> Vec | None:
    """A MaterialX / USD value as a tuple of floats (None when not numeric)."""
    if v is None or isinstance(v, (str, bytes)):
        return None
    if hasattr(v, "asTuple"):
        v = v.asTuple()
    try:
        arr = np.asarray(v, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        return None
    if arr.size == 0 or not np.all(np.isfinite(arr)):
        return None
    return tuple(float(x) for x in arr)


def _fmt(v: Vec) -> str:
    return ", ".join(f"{x:.4g}" for x in v)


def _bcast(v: Vec, n: int) -> Vec:
    if len(v) == n:
        return v
    if len(v) == 1:
        return v * n
    if len(v) > n:
        return v[:n]
    raise _Unreducible("", f"a {len(v)}-component value where {n} are expected")


class _Unreducible(Exception):
    """A node graph that is not one texture lookup (or a constant)."""

    def __init__(self, node: str, why: str) -> None:
        super().__init__(why)
        self.node = node
        self.why = why


@dataclass(frozen=True)
class _Tex:
    """A texture lookup after constant affine maps: component ``i`` is
    ``texel[chan[i]] * scale[i] + bias[i]``."""

    ref: TextureRef  # file, colour space, wrap, st, owner (scale/bias/channels unset)
    default: tuple[float, float, float, float]  # the reader's default, texel space (rgba)
    chan: str
    scale: Vec
    bias: Vec

    @property
    def n(self) -> int:
        return len(self.chan)


Value = Vec | _Tex


def _size(v: Value) -> int:
    return v.n if isinstance(v, _Tex) else len(v)


def _tex_bcast(t: _Tex, n: int) -> _Tex:
    if t.n == n:
        return t
    if t.n == 1:
        return replace(t, chan=t.chan * n, scale=t.scale * n, bias=t.bias * n)
    if t.n > n:
        return replace(t, chan=t.chan[:n], scale=t.scale[:n], bias=t.bias[:n])
    raise _Unreducible(t.ref.owner, f"a {t.n}-channel texture where {n} channels are expected")


def _to(v: Value, n: int) -> Value:
    return _tex_bcast(v, n) if isinstance(v, _Tex) else _bcast(v, n)


def _affine(t: _Tex, s: Vec, b: Vec) -> _Tex:
    n = max(t.n, len(s), len(b))
    t = _tex_bcast(t, n)
    s, b = _bcast(s, n), _bcast(b, n)
    return replace(
        t,
        scale=tuple(t.scale[i] * s[i] for i in range(n)),
        bias=tuple(t.bias[i] * s[i] + b[i] for i in range(n)),
    )


def _mul(a: Value, b: Value, where: str = "") -> Value:
    if isinstance(a, _Tex) and isinstance(b, _Tex):
        raise _Unreducible(where, "the product of two textures")
    if isinstance(a, _Tex):
        return _affine(a, b, (0.0,))  # type: ignore[arg-type]
    if isinstance(b, _Tex):
        return _affine(b, a, (0.0,))
    n = max(len(a), len(b))
    a, b = _bcast(a, n), _bcast(b, n)
    return tuple(a[i] * b[i] for i in range(n))


def _add(a: Value, b: Value, where: str = "") -> Value:
    if isinstance(a, _Tex) and isinstance(b, _Tex):
        raise _Unreducible(where, "the sum of two textures")
    if isinstance(a, _Tex):
        return _affine(a, (1.0,), b)  # type: ignore[arg-type]
    if isinstance(b, _Tex):
        return _affine(b, (1.0,), a)
    n = max(len(a), len(b))
    a, b = _bcast(a, n), _bcast(b, n)
    return tuple(a[i] + b[i] for i in range(n))


def _neg(a: Value) -> Value:
    return _mul(a, (-1.0,))


def _mix(fg: Value, bg: Value, m: Value, where: str = "") -> Value:
    """``fg * m + bg * (1 - m)`` (MaterialX ``mix``)."""
    if fg == bg:
        return fg
    if not isinstance(m, _Tex):
        if all(x == 0.0 for x in m):
            return bg
        if all(x == 1.0 for x in m):
            return fg
        one_minus = tuple(1.0 - x for x in m)
        return _add(_mul(fg, m, where), _mul(bg, one_minus, where), where)
    if isinstance(fg, _Tex) or isinstance(bg, _Tex):
        raise _Unreducible(where, "a texture-weighted mix of textures")
    return _add(bg, _mul(m, _add(fg, _neg(bg))), where)


def _pick(v: Value, i: int, where: str = "") -> Value:
    if i < 0 or i >= _size(v):
        raise _Unreducible(where, f"channel {i} of a {_size(v)}-component value")
    if isinstance(v, _Tex):
        return replace(v, chan=v.chan[i], scale=(v.scale[i],), bias=(v.bias[i],))
    return (v[i],)


def _is_const(v: Value | None, value: float) -> bool:
    return v is not None and not isinstance(v, _Tex) and all(x == value for x in v)


_CHANNEL_INDEX = {"r": 0, "g": 1, "b": 2, "a": 3}


def _with_output_default(t: _Tex, target: Vec) -> _Tex:
    """``t`` whose default (missing file) reads as ``target`` after scale and bias."""
    d = list(t.default)
    for i, c in enumerate(t.chan):
        if t.scale[i] != 0.0:
            d[_CHANNEL_INDEX[c]] = (target[i] - t.bias[i]) / t.scale[i]
    return replace(t, default=tuple(d))  # type: ignore[arg-type]


def texture_ref(t: _Tex, n: int) -> TextureRef:
    """The :class:`TextureRef` of ``t`` feeding an ``n``-component input. A single
    channel gives the same value in every lane of ``scale``/``bias``/``fallback`` (so
    either reading of them -- by texel channel, as UsdUVTexture does, or by output
    component -- is the same); a colour input fed by one channel (``channels`` "r"
    on a colour input) sees that channel in r, g and b and needs a uniform scale."""
    t = _tex_bcast(t, n)
    fb = [t.default[_CHANNEL_INDEX[c]] * t.scale[i] + t.bias[i] for i, c in enumerate(t.chan)]
    if len(set(t.chan)) == 1:
        if len(set(t.scale)) > 1 or len(set(t.bias)) > 1:
            raise _Unreducible(t.ref.owner, "one texture channel with a per-component scale")
        s, b, f = t.scale[0], t.bias[0], fb[0]
        return replace(t.ref, channels=t.chan[0], scale=(s,) * 4, bias=(b,) * 4, fallback=(f,) * 4)
    if t.chan not in ("rgb", "rgba"):
        raise _Unreducible(t.ref.owner, f"the channel order '{t.chan}'")
    pad_s = (1.0,) * (4 - n)
    pad_b = (0.0,) * (4 - n)
    fallback = tuple(fb) + ((1.0,) if n == 3 else ())
    return replace(
        t.ref,
        channels=t.chan,
        scale=tuple(t.scale) + pad_s,  # type: ignore[arg-type]
        bias=tuple(t.bias) + pad_b,  # type: ignore[arg-type]
        fallback=fallback,  # type: ignore[arg-type]
    )


# --- texture coordinates ------------------------------------------------------------------


def _compose(outer: Affine, inner: Affine) -> Affine:
    """``outer(inner(st))`` of two row-major 2x3 affines."""
    a, b, c, d, e, f = outer
    A, B, C, D, E, F = inner
    return (
        a * A + b * D,
        a * B + b * E,
        a * C + b * F + c,
        d * A + e * D,
        d * B + e * E,
        d * C + e * F + f,
    )


def _scale_st(s: Vec, t: Vec = (0.0, 0.0)) -> Affine:
    s, t = _bcast(s, 2), _bcast(t, 2)
    return (s[0], 0.0, t[0], 0.0, s[1], t[1])


def uv_set_name(index: int) -> str:
    """The mesh primvar of MaterialX texture-coordinate set ``index``: ``st`` for 0 (the
    primary UV set, as usdMtlx and Storm read ``texcoord``), ``st<index>`` above."""
    return "st" if index <= 0 else f"st{index}"


# --- node adapters ------------------------------------------------------------------------


@dataclass(frozen=True)
class _Conn:
    """An upstream node's output (``output`` "" = its only output)."""

    node: Any  # _MxNode | _UsdNode
    output: str = ""


class _MxNode:
    """A node of a MaterialX document."""

    __slots__ = ("doc", "node", "nodedef")

    def __init__(self, doc: MtlxDocument, node: Any) -> None:
        self.doc = doc
        self.node = node
        self.nodedef = node.getNodeDef()

    @property
    def label(self) -> str:
        return f"{os.path.basename(self.doc.path)}:{self.node.getNamePath()}"

    @property
    def name(self) -> str:
        return str(self.node.getName())

    @property
    def category(self) -> str:
        return str(self.node.getCategory())

    @property
    def type(self) -> str:
        return str(self.node.getType())

    def authored(self) -> list[str]:
        return [str(i.getName()) for i in self.node.getInputs()]

    def source(self, name: str) -> _Conn | Any | None:
        inp = self.node.getInput(name)
        return None if inp is None else self._resolve(inp, 0)

    def _resolve(self, elem: Any, depth: int) -> _Conn | Any | None:
        import MaterialX as mx

        if depth > 64:
            raise _Unreducible(self.label, "a connection cycle")
        parent = elem.getParent()
        iface = elem.getInterfaceName()
        if iface:
            graph = parent.getParent() if isinstance(elem, mx.Input) else parent
            gi = graph.getInput(iface) if isinstance(graph, mx.NodeGraph) else None
            if gi is None:
                nd = graph.getNodeDef() if isinstance(graph, mx.NodeGraph) else None
                di = nd.getActiveInput(iface) if nd is not None else None
                return None if di is None or not di.hasValue() else di.getValue()
            return self._resolve(gi, depth + 1)
        node_name = elem.getNodeName()
        graph_name = elem.getNodeGraphString()
        out = elem.getOutputString()
        if node_name:
            scope = parent.getParent() if isinstance(elem, mx.Input) else parent
            target = scope.getNode(node_name) if scope is not None else None
            if target is None:
                raise _Unreducible(self.label, f"a connection to a missing node '{node_name}'")
            return _Conn(_MxNode(self.doc, target), out)
        if graph_name:
            graph = elem.getDocument().getNodeGraph(graph_name)
            if graph is None:
                raise _Unreducible(
                    self.label, f"a connection to a missing nodegraph '{graph_name}'"
                )
            outs = graph.getOutputs()
            o = graph.getOutput(out) if out else (outs[0] if len(outs) == 1 else None)
            if o is None:
                raise _Unreducible(self.label, f"a missing output '{out}' of '{graph_name}'")
            return self._resolve(o, depth + 1)
        if out and isinstance(elem, mx.Input):
            o = elem.getDocument().getOutput(out)
            if o is None:
                raise _Unreducible(self.label, f"a missing output '{out}'")
            return self._resolve(o, depth + 1)
        if isinstance(elem, mx.Output):
            raise _Unreducible(self.label, f"an unconnected output '{elem.getName()}'")
        if not elem.getValueString():
            return None
        try:
            return elem.getValue()
        except Exception:  # noqa: BLE001 - a malformed value is an unauthored one
            return None

    def default(self, name: str) -> Any | None:
        nd = self.nodedef
        di = nd.getActiveInput(name) if nd is not None else None
        if di is None or not di.getValueString():
            return None
        try:
            return di.getValue()
        except Exception:  # noqa: BLE001
            return None

    def string(self, name: str) -> str | None:
        v = self.source(name)
        if v is None:
            v = self.default(name)
        return v if isinstance(v, str) else None

    def filename(self, name: str) -> tuple[str, str]:
        """(resolved path, authored value): ``fileprefix`` applied (MaterialX's string
        resolver), relative to the document's folder; "" when it does not exist
        (``<UDIM>`` kept: it resolves when any tile exists)."""
        inp = self.node.getInput(name)
        if inp is None:
            return "", ""
        if inp.getInterfaceName():
            src = self._interface_element(inp)
            if src is not None:
                inp = src
        authored = str(inp.getValueString())
        if not authored:
            return "", ""
        try:
            value = str(inp.getResolvedValueString())
        except Exception:  # noqa: BLE001
            value = authored
        path = (
            value if os.path.isabs(value) else os.path.join(os.path.dirname(self.doc.path), value)
        )
        return _existing(os.path.normpath(path)), authored

    def _interface_element(self, inp: Any) -> Any | None:
        import MaterialX as mx

        graph = inp.getParent().getParent()
        if isinstance(graph, mx.NodeGraph):
            return graph.getInput(inp.getInterfaceName())
        return None

    def colorspace(self, name: str) -> str:
        inp = self.node.getInput(name)
        if inp is not None and inp.getInterfaceName():
            inp = self._interface_element(inp) or inp
        if inp is None:
            return str(self.node.getActiveColorSpace())
        return str(inp.getActiveColorSpace())


class _UsdNode:
    """A UsdShade shader whose ``info:id`` is a MaterialX node definition."""

    __slots__ = ("nodedef", "shader", "time")

    def __init__(self, shader: UsdShade.Shader, time: Usd.TimeCode) -> None:
        self.shader = shader
        self.time = time
        sid = shader.GetShaderId() or ""
        self.nodedef = standard_library().getNodeDef(sid) if sid else None

    @property
    def label(self) -> str:
        return str(self.shader.GetPath())

    @property
    def name(self) -> str:
        return str(self.shader.GetPrim().GetName())

    @property
    def category(self) -> str:
        nd = self.nodedef
        return str(nd.getNodeString()) if nd is not None else str(self.shader.GetShaderId() or "")

    @property
    def type(self) -> str:
        nd = self.nodedef
        return str(nd.getType()) if nd is not None else ""

    def authored(self) -> list[str]:
        return [str(i.GetBaseName()) for i in self.shader.GetInputs() if _usd_authored(i)]

    def source(self, name: str) -> _Conn | Any | None:
        inp = self.shader.GetInput(name)
        if not inp:
            return None
        try:
            attrs = inp.GetValueProducingAttributes(False)
        except Exception:  # noqa: BLE001
            return None
        if not attrs:
            return None
        a = attrs[0]
        if UsdShade.Output.IsOutput(a):
            out = UsdShade.Output(a)
            return _Conn(_UsdNode(UsdShade.Shader(a.GetPrim()), self.time), str(out.GetBaseName()))
        return a.Get(self.time)

    def default(self, name: str) -> Any | None:
        nd = self.nodedef
        di = nd.getActiveInput(name) if nd is not None else None
        if di is None or not di.getValueString():
            return None
        try:
            return di.getValue()
        except Exception:  # noqa: BLE001
            return None

    def string(self, name: str) -> str | None:
        v = self.source(name)
        if v is None:
            v = self.default(name)
        return str(v) if isinstance(v, str) else None

    def _value_attr(self, name: str) -> Usd.Attribute | None:
        inp = self.shader.GetInput(name)
        if not inp:
            return None
        attrs = inp.GetValueProducingAttributes(False)
        return attrs[0] if attrs and not UsdShade.Output.IsOutput(attrs[0]) else None

    def filename(self, name: str) -> tuple[str, str]:
        a = self._value_attr(name)
        v = a.Get(self.time) if a is not None else None
        if not isinstance(v, Sdf.AssetPath) or not v.path:
            return "", ""
        if v.resolvedPath:
            return v.resolvedPath, v.path
        if "<UDIM>" in v.path and a is not None:
            stack = a.GetPropertyStack(self.time)
            if stack:
                p = Sdf.ComputeAssetPathRelativeToLayer(stack[0].layer, v.path)
                return _existing(p), v.path
        return "", v.path

    def colorspace(self, name: str) -> str:
        a = self._value_attr(name)
        if a is not None and a.HasColorSpace():
            return str(a.GetColorSpace())
        return "auto"


def _usd_authored(inp: UsdShade.Input) -> bool:
    return bool(inp.HasConnectedSource() or inp.GetAttr().HasAuthoredValue())


def _existing(path: str) -> str:
    """``path`` when the file (or, with ``<UDIM>``, any tile) exists, else ""."""
    if "<UDIM>" in path:
        pattern = glob.escape(path).replace("<UDIM>", "[1-9][0-9][0-9][0-9]")
        return path if glob.glob(pattern) else ""
    return path if os.path.isfile(path) else ""


# --- evaluation ---------------------------------------------------------------------------

_WRAP = {"periodic": "repeat", "clamp": "clamp", "mirror": "mirror", "constant": "black"}
_USD_WRAP = {"repeat": "repeat", "periodic": "repeat", "clamp": "clamp", "mirror": "mirror"}
_USD_WRAP.update({"black": "black", "useMetadata": "useMetadata"})
_SEPARATE_OUT = {"outx": 0, "outy": 1, "outz": 2, "outw": 3}
_SEPARATE_OUT.update({"outr": 0, "outg": 1, "outb": 2, "outa": 3})
_USD_UV_OUT = {"r": "r", "g": "g", "b": "b", "a": "a", "rgb": "rgb", "rgba": "rgba"}
#: Longest node chain followed (a cycle ends there).
_MAX_DEPTH = 64
#: Nodes that pass their ``in`` through unchanged.
_PASSTHROUGH = ("dot",)


class _Ctx:
    """One material's translation: messages and the graph evaluator."""

    def __init__(self, label: str) -> None:
        self.label = label
        self.warnings: list[str] = []
        self.notes: list[str] = []
        self.normal_tangent = False
        self._depth = 0

    def warn(self, msg: str) -> None:
        line = f"{self.label}: {msg}"
        if line not in self.warnings:
            self.warnings.append(line)

    def note(self, msg: str) -> None:
        line = f"{self.label}: {msg}"
        if line not in self.notes:
            self.notes.append(line)

    # -- inputs --
    def const(self, node: Any, name: str, fallback: Vec = (0.0,)) -> Vec:
        """The constant of ``node.name``: its value, else the node definition's default."""
        src = None
        try:
            src = node.source(name)
        except _Unreducible:
            pass
        v = None if isinstance(src, _Conn) else _vec(src)
        if v is None:
            v = _vec(node.default(name))
        return v if v is not None else fallback

    def input(self, node: Any, name: str, fallback: Vec = (0.0,)) -> Value:
        """``node.name`` reduced to a constant or one texture lookup; anything else is
        its constant (value or default) and one warning naming the node."""
        src: Any = None
        try:
            src = node.source(name)
            if isinstance(src, _Conn):
                return self.eval(src)
            v = _vec(src)
            if v is not None:
                return v
        except _Unreducible as exc:
            c = self.const(node, name, fallback)
            where = exc.node or node.label
            if isinstance(src, _Conn):
                first = f"<{src.node.category} '{src.node.label}'>"
                where = first if where == first else f"{first} via {where}"
            self.warn(
                f"input '{name}' is driven by {where} ({exc.why}), not one texture lookup; "
                f"using the constant {_fmt(c)}"
            )
            return c
        return self.const(node, name, fallback)

    # -- nodes --
    def eval(self, conn: _Conn) -> Value:
        if self._depth > _MAX_DEPTH:
            raise _Unreducible(f"<{conn.node.category} '{conn.node.label}'>", "a cycle")
        self._depth += 1
        try:
            return self._eval(conn)
        finally:
            self._depth -= 1

    def _eval(self, conn: _Conn) -> Value:
        node = conn.node
        cat = node.category
        where = f"<{cat} '{node.label}'>"
        if cat in ("image", "tiledimage"):
            return self._image(node, tiled=cat == "tiledimage")
        if cat == "UsdUVTexture":
            return self._usd_uv_texture(node, conn.output)
        if cat == "constant":
            return self._value(node, "value")
        if cat in _PASSTHROUGH:
            return self._value(node, "in")
        if cat == "convert":
            return _to(self._value(node, "in"), _SIZES.get(node.type, 1))
        if cat in ("multiply", "add", "subtract", "divide"):
            a, b = self._value(node, "in1"), self._value(node, "in2")
            if cat == "multiply":
                return _mul(a, b, where)
            if cat == "add":
                return _add(a, b, where)
            if cat == "subtract":
                return _add(a, _neg(b), where)
            if isinstance(b, _Tex) or any(x == 0.0 for x in b):
                raise _Unreducible(where, "a division by a texture or by zero")
            return _mul(a, tuple(1.0 / x for x in b), where)
        if cat == "mix":
            fg, bg, m = (self._value(node, k) for k in ("fg", "bg", "mix"))
            return _mix(fg, bg, m, where)
        if cat == "extract":
            idx = self.const(node, "index")[0]
            return _pick(self._value(node, "in"), int(idx), where)
        if cat in ("separate2", "separate3", "separate4"):
            i = _SEPARATE_OUT.get(conn.output)
            if i is None:
                raise _Unreducible(where, f"output '{conn.output}'")
            return _pick(self._value(node, "in"), i, where)
        if cat in ("combine2", "combine3", "combine4"):
            parts = [self._value(node, f"in{i}") for i in range(1, int(cat[-1]) + 1)]
            texs = [p for p in parts if isinstance(p, _Tex)]
            if not texs:
                return tuple(x for p in parts for x in p)  # type: ignore[union-attr]
            t0 = texs[0]
            if len(texs) < len(parts) or any(
                (t.ref, t.default) != (t0.ref, t0.default) for t in texs
            ):
                raise _Unreducible(where, "a combine of texture channels and other values")
            # Channels of one lookup (a 1.38 ``channels`` swizzle upgrades to this).
            return replace(
                t0,
                chan="".join(t.chan for t in texs),
                scale=tuple(x for t in texs for x in t.scale),
                bias=tuple(x for t in texs for x in t.bias),
            )
        if cat == "normalmap":
            return self._normalmap(node, where)
        raise _Unreducible(where, f"'{cat}' is not a node we reduce")

    def _value(self, node: Any, name: str) -> Value:
        """Like :meth:`input` but unreducible graphs propagate (one warning, at the
        shader input they feed)."""
        src = node.source(name)
        if isinstance(src, _Conn):
            return self.eval(src)
        v = _vec(src)
        if v is None:
            v = _vec(node.default(name))
        if v is None:
            raise _Unreducible(f"<{node.category} '{node.label}'>", f"no value for '{name}'")
        return v

    def _normalmap(self, node: Any, where: str) -> Value:
        for k in ("normal", "tangent", "bitangent"):
            if isinstance(node.source(k), _Conn):
                raise _Unreducible(where, f"a connected '{k}' frame")
        space = node.string("space")
        if space not in (None, "", "tangent"):
            raise _Unreducible(where, f"space '{space}'")
        v = self._value(node, "in")
        s = _bcast(self._value_const(node, "scale", where), 2)
        # out = (in * 2 - 1) * (scale.x, scale.y, 1), tangent space (mx_normalmap).
        out = _mul(_add(_mul(v, (2.0,)), (-1.0,)), (s[0], s[1], 1.0), where)
        self.normal_tangent = True
        if isinstance(v, _Tex) and isinstance(out, _Tex):
            d = [
                v.default[_CHANNEL_INDEX[c]] * v.scale[i] + v.bias[i] for i, c in enumerate(v.chan)
            ]
            if not any(d):  # mx_normalmap reads a zero vector as the flat normal
                out = _with_output_default(out, (0.0, 0.0, 1.0))
        return out

    def _value_const(self, node: Any, name: str, where: str) -> Vec:
        v = self._value(node, name)
        if isinstance(v, _Tex):
            raise _Unreducible(where, f"a textured '{name}'")
        return v

    def _st(self, node: Any, name: str) -> tuple[str, Affine]:
        """Texture coordinates feeding ``node.name``: (primvar, st transform)."""
        src = node.source(name)
        if src is None:
            return "st", ST_IDENTITY
        if not isinstance(src, _Conn):
            raise _Unreducible(f"<{node.category} '{node.label}'>", "constant texture coordinates")
        return self._st_of(src)

    def _st_of(self, conn: _Conn) -> tuple[str, Affine]:
        if self._depth > _MAX_DEPTH:
            raise _Unreducible(f"<{conn.node.category} '{conn.node.label}'>", "a cycle")
        self._depth += 1
        try:
            return self._st_of_node(conn)
        finally:
            self._depth -= 1

    def _st_of_node(self, conn: _Conn) -> tuple[str, Affine]:
        node = conn.node
        cat = node.category
        where = f"<{cat} '{node.label}'>"
        if cat == "texcoord":
            return uv_set_name(int(self.const(node, "index")[0])), ST_IDENTITY
        if cat in ("geompropvalue", "UsdPrimvarReader"):
            key = "geomprop" if cat == "geompropvalue" else "varname"
            name = node.string(key)
            if not name:
                raise _Unreducible(where, f"no '{key}'")
            return name, ST_IDENTITY
        if cat in _PASSTHROUGH or cat == "convert":
            src = node.source("in")
            if not isinstance(src, _Conn):
                raise _Unreducible(where, "constant texture coordinates")
            return self._st_of(src)
        if cat in ("multiply", "add", "subtract", "divide"):
            a, b = node.source("in1"), node.source("in2")
            if isinstance(a, _Conn) and not isinstance(b, _Conn):
                name, m = self._st_of(a)
                k = self._value_const(node, "in2", where)
            elif isinstance(b, _Conn) and not isinstance(a, _Conn) and cat != "divide":
                name, m = self._st_of(b)
                k = self._value_const(node, "in1", where)
                if cat == "subtract":  # k - st
                    return name, _compose(_scale_st((-1.0,), k), m)
            else:
                raise _Unreducible(where, "texture coordinates from two sources")
            if cat == "multiply":
                return name, _compose(_scale_st(k), m)
            if cat == "add":
                return name, _compose(_scale_st((1.0,), k), m)
            if cat == "subtract":
                return name, _compose(_scale_st((1.0,), tuple(-x for x in k)), m)
            if any(x == 0.0 for x in k):
                raise _Unreducible(where, "a division by zero")
            return name, _compose(_scale_st(tuple(1.0 / x for x in k)), m)
        if cat == "UsdTransform2d":
            src = node.source("in")
            if not isinstance(src, _Conn):
                raise _Unreducible(where, "constant texture coordinates")
            name, m = self._st_of(src)
            s = _bcast(self._value_const(node, "scale", where), 2)
            t = _bcast(self._value_const(node, "translation", where), 2)
            r = math.radians(self._value_const(node, "rotation", where)[0])
            c, sn = math.cos(r), math.sin(r)
            # UsdTransform2d: scale, then rotate (counter-clockwise), then translate.
            xf = (c * s[0], -sn * s[1], t[0], sn * s[0], c * s[1], t[1])
            return name, _compose(xf, m)
        raise _Unreducible(where, f"'{cat}' texture coordinates")

    def _image(self, node: Any, tiled: bool) -> Value:
        n = _SIZES.get(node.type, 0)
        where = f"<{node.category} '{node.label}'>"
        if n == 0:
            raise _Unreducible(where, f"type '{node.type}'")
        default = _bcast(self.const(node, "default", (0.0,)), n)
        resolved, asset = node.filename("file")
        if not asset:
            return default  # no file: MaterialX returns the default
        if not resolved:
            self.warn(f"{where}: file '{asset}' not found; the texture reads as its default")
        st, m = self._st(node, "texcoord")
        if tiled:
            tiling = _bcast(self._value_const(node, "uvtiling", where), 2)
            offset = _bcast(self._value_const(node, "uvoffset", where), 2)
            img = _bcast(self._value_const(node, "realworldimagesize", where), 2)
            tile = _bcast(self._value_const(node, "realworldtilesize", where), 2)
            if 0.0 in img:
                raise _Unreducible(where, "a zero realworldimagesize")
            k = (tiling[0] * tile[0] / img[0], tiling[1] * tile[1] / img[1])
            off = (-offset[0] * tile[0] / img[0], -offset[1] * tile[1] / img[1])
            m = _compose(_scale_st(k, off), m)
            wrap_s = wrap_t = "repeat"
        else:
            wrap_s = _WRAP.get(node.string("uaddressmode") or "periodic", "repeat")
            wrap_t = _WRAP.get(node.string("vaddressmode") or "periodic", "repeat")
        # MaterialX colour-manages colour images only; float/vector images are data.
        cs = (node.colorspace("file") or "raw") if node.type in _COLOR_TYPES else "raw"
        ref = TextureRef(
            file=resolved,
            asset=asset,
            source_color_space=cs,
            wrap_s=wrap_s,
            wrap_t=wrap_t,
            st=st,
            st_transform=m,
            owner=node.label,
        )
        dflt: tuple[float, ...] = {
            1: (default[0],) * 4,
            2: (*default, 0.0, 1.0),
            3: (*default, 1.0),
        }.get(n, default)
        chan = "rgba"[:n] if n > 1 else "r"
        return _Tex(ref, dflt, chan, (1.0,) * n, (0.0,) * n)  # type: ignore[arg-type]

    def _usd_uv_texture(self, node: Any, output: str) -> Value:
        where = f"<UsdUVTexture '{node.label}'>"
        chan = _USD_UV_OUT.get(output or "rgb")
        if chan is None:
            raise _Unreducible(where, f"output '{output}'")
        fb = _bcast(self.const(node, "fallback", (0.0, 0.0, 0.0, 1.0)), 4)
        resolved, asset = node.filename("file")
        if not asset:
            return tuple(fb[_CHANNEL_INDEX[c]] for c in chan)
        if not resolved:
            self.warn(f"{where}: file '{asset}' not found; the texture reads as its fallback")
        st, m = self._st(node, "st")
        scale = _bcast(self._value_const(node, "scale", where), 4)
        bias = _bcast(self._value_const(node, "bias", where), 4)
        ref = TextureRef(
            file=resolved,
            asset=asset,
            source_color_space=node.string("sourceColorSpace") or node.colorspace("file"),
            wrap_s=_USD_WRAP.get(node.string("wrapS") or "periodic", "repeat"),
            wrap_t=_USD_WRAP.get(node.string("wrapT") or "periodic", "repeat"),
            st=st,
            st_transform=m,
            owner=node.label,
        )
        idx = [_CHANNEL_INDEX[c] for c in chan]
        # The fallback is the reader's output (scale/bias not applied): texel-space default
        # = (fallback - bias) / scale keeps texture_ref's output-space fallback exact.
        dflt = tuple((fb[i] - bias[i]) / scale[i] if scale[i] != 0.0 else 0.0 for i in range(4))
        return _Tex(
            ref,
            dflt,  # type: ignore[arg-type]
            chan,
            tuple(scale[i] for i in idx),
            tuple(bias[i] for i in idx),
        )


# --- the shaders --------------------------------------------------------------------------

#: standard_surface inputs without a lobe in our BRDF -> why (a note each when authored).
_UNMODELLED = {
    "diffuse_roughness": "diffuse is Lambertian",
    "specular_anisotropy": "specular is isotropic",
    "specular_rotation": "specular is isotropic",
    "transmission": "no transmission lobe",
    "transmission_color": "no transmission lobe",
    "transmission_depth": "no transmission lobe",
    "transmission_scatter": "no transmission lobe",
    "transmission_scatter_anisotropy": "no transmission lobe",
    "transmission_dispersion": "no transmission lobe",
    "transmission_extra_roughness": "no transmission lobe",
    "subsurface": "no subsurface lobe",
    "subsurface_color": "no subsurface lobe",
    "subsurface_radius": "no subsurface lobe",
    "subsurface_scale": "no subsurface lobe",
    "subsurface_anisotropy": "no subsurface lobe",
    "sheen": "no sheen lobe",
    "sheen_color": "no sheen lobe",
    "sheen_roughness": "no sheen lobe",
    "coat_anisotropy": "the clearcoat is isotropic",
    "coat_rotation": "the clearcoat is isotropic",
    "coat_IOR": "the clearcoat has a fixed IOR",
    "coat_normal": "the clearcoat uses the base normal",
    "coat_affect_color": "the clearcoat does not darken the base",
    "coat_affect_roughness": "the clearcoat does not roughen the base",
    "thin_film_thickness": "no thin-film interference",
    "thin_film_IOR": "no thin-film interference",
    "thin_walled": "surfaces are not thin-walled",
    "tangent": "specular is isotropic",
}
_SCALARS = {
    "roughness": ("roughness", 0.5),
    "metallic": ("metallic", 0.0),
    "opacity": ("opacity", 1.0),
    "clearcoat": ("clearcoat", 0.0),
    "clearcoatRoughness": ("clearcoat_roughness", 0.01),
    "occlusion": ("occlusion", 1.0),
}
_COLORS = {"diffuseColor": "diffuse_color", "emissiveColor": "emissive_color"}
_COLORS["specularColor"] = "specular_color"


def _set(ctx: _Ctx, mp: MaterialPrim, name: str, v: Value, const: Vec) -> None:
    """Input ``name`` (UsdPreviewSurface) of ``mp`` is ``v``; a texture also sets the
    constant to ``const`` (the input's value without its connection)."""
    if isinstance(v, _Tex):
        n = 3 if name in _COLORS or name == "normal" else 1
        try:
            mp.textures[name] = texture_ref(v, n)
        except _Unreducible as exc:
            ctx.warn(
                f"input '{name}' is driven by {exc.node} ({exc.why}), not one texture "
                f"lookup; using the constant {_fmt(const)}"
            )
        v = const
    if name == "normal":
        return
    if name in _COLORS:
        arr = np.asarray(_bcast(v, 3), dtype=np.float64)
        setattr(mp, _COLORS[name], np.maximum(arr, 0.0))
    elif name in _SCALARS:
        attr, _d = _SCALARS[name]
        setattr(mp, attr, min(max(float(v[0]), 0.0), 1.0))


def _mean(v: Value) -> Value:
    if isinstance(v, _Tex):
        if len(set(v.chan)) == 1 and len(set(v.scale)) == 1 and len(set(v.bias)) == 1:
            return _pick(v, 0)
        raise _Unreducible(v.ref.owner, "the mean of a colour texture")
    return (sum(v) / len(v),)


def _or(v: Value, const: Vec) -> Vec:
    return const if isinstance(v, _Tex) else v


def _standard_surface(ctx: _Ctx, node: Any, mp: MaterialPrim) -> None:
    """MaterialX's standard_surface -> UsdPreviewSurface translation (see the module
    doc and docs/MATERIALS.md)."""

    def inp(name: str) -> Value:
        return ctx.input(node, name)

    def c(name: str) -> Vec:
        return ctx.const(node, name)

    def fold(what: str, f: Any, *args: Value, keep: Value) -> Value:
        try:
            return f(*args)
        except _Unreducible as exc:
            ctx.warn(f"{what}: {exc.why}; using the first alone")
            return keep

    # Diffuse: base * base_color, blended toward subsurface_color by subsurface, tinted by
    # the coat colour where coated (mix(1, coat_color, coat)).
    base_color, base = inp("base_color"), inp("base")
    diffuse = fold("'base_color' * 'base'", _mul, base_color, base, keep=base_color)
    diffuse_const = _mul(_or(base_color, c("base_color")), _or(base, c("base")))
    sss, sss_color = inp("subsurface"), inp("subsurface_color")
    if not _is_const(sss, 0.0) and sss_color != diffuse:
        try:
            diffuse = _mix(sss_color, diffuse, sss)
        except _Unreducible:
            ctx.note("subsurface_color is not blended into diffuseColor (textured subsurface)")
    coat, coat_color = inp("coat"), inp("coat_color")
    attenuation: Value = (1.0,)
    if not _is_const(coat, 0.0):
        try:
            attenuation = _mix(coat_color, (1.0, 1.0, 1.0), coat)
        except _Unreducible:
            ctx.note("the coat colour does not tint diffuse and emission (textured coat)")
        try:
            clearcoat = _mul(coat, _mean(coat_color))
        except _Unreducible as exc:
            ctx.warn(f"'coat_color' ({exc.why}); using its constant")
            clearcoat = _mul(coat, _mean(c("coat_color")))
    else:
        clearcoat = (0.0,)
    try:
        diffuse = _mul(diffuse, attenuation)
    except _Unreducible:
        ctx.note("the coat colour does not tint diffuseColor (both are textured)")
    _set(ctx, mp, "diffuseColor", diffuse, _mul(diffuse_const, _or(attenuation, (1.0,))))
    _set(ctx, mp, "metallic", inp("metalness"), c("metalness"))
    _set(ctx, mp, "roughness", inp("specular_roughness"), c("specular_roughness"))
    _set(ctx, mp, "clearcoat", clearcoat, (0.0,))
    _set(ctx, mp, "clearcoatRoughness", inp("coat_roughness"), c("coat_roughness"))

    # Specular: metallic workflow; F0 = specular * mean(specular_color) * F0(specular_IOR)
    # folded into an effective IOR (the translation graph passes specular_IOR alone).
    spec, spec_color, spec_ior = (
        _const_only(ctx, node, k) for k in ("specular", "specular_color", "specular_IOR")
    )
    mp.use_specular_workflow = False
    ior = max(spec_ior[0], 1.0)
    weight = spec[0] * (sum(spec_color) / len(spec_color))
    if weight != 1.0:
        f0 = max(weight, 0.0) * ((ior - 1.0) / (ior + 1.0)) ** 2
        r = math.sqrt(min(f0, 0.81))
        ior = (1.0 + r) / (1.0 - r)
    if len(set(spec_color)) > 1:
        ctx.note("specular_color's tint is not modelled (its mean scales F0)")
    mp.ior = min(max(ior, 1.0), 4.0)

    # Emission: emission * emission_color, tinted by the coat.
    em_color, em = inp("emission_color"), inp("emission")
    emissive = fold("'emission_color' * 'emission'", _mul, em_color, em, keep=em_color)
    em_const = _mul(_or(em_color, c("emission_color")), _or(em, c("emission")))
    try:
        emissive = _mul(emissive, attenuation)
    except _Unreducible:
        ctx.note("the coat colour does not tint emissiveColor (both are textured)")
    _set(ctx, mp, "emissiveColor", emissive, em_const)

    # Opacity: colour -> one channel (the translation averages r, g, b).
    opacity = inp("opacity")
    if isinstance(opacity, _Tex):
        try:
            opacity = _mean(opacity)
        except _Unreducible:
            ctx.note("opacity reads the red channel of its colour texture")
            opacity = _pick(opacity, 0)
    else:
        opacity = _mean(opacity)
    _set(ctx, mp, "opacity", opacity, _mean(c("opacity")))  # type: ignore[arg-type]

    # Normal: a normalmap gives a tangent-space normal; anything else is taken as an
    # encoded normal ((n - 0.5) * 2, as the translation graph does).
    src = None
    try:
        src = node.source("normal")
    except _Unreducible:
        pass
    if isinstance(src, _Conn) and src.node.category not in ("normal",):
        ctx.normal_tangent = False
        n = ctx.input(node, "normal", (0.5, 0.5, 1.0))
        if isinstance(n, _Tex) and not ctx.normal_tangent:
            ctx.note("'normal' is not fed by a normalmap; read as a tangent-space map")
            n = _add(_mul(n, (2.0,)), (-1.0,))
        if isinstance(n, _Tex):
            _set(ctx, mp, "normal", n, (0.0, 0.0, 1.0))

    for name in node.authored():
        why = _UNMODELLED.get(name)
        if why is None:
            continue
        v: Any = None
        try:
            v = node.source(name)
        except _Unreducible:
            pass
        if not isinstance(v, _Conn):
            vv, dv = _vec(v), _vec(node.default(name))
            if vv is None or vv == dv:
                continue  # the default: no effect
            what = f"= {_fmt(vv)}"
        else:
            what = "textured"
        ctx.note(f"input '{name}' ({what}) is not modelled: {why}")


def _const_only(ctx: _Ctx, node: Any, name: str) -> Vec:
    v = ctx.input(node, name)
    if isinstance(v, _Tex):
        c = ctx.const(node, name)
        ctx.warn(f"input '{name}' is textured ({v.ref.owner}); it is a constant here: {_fmt(c)}")
        return c
    return v


_PREVIEW_INPUTS = (
    "diffuseColor",
    "emissiveColor",
    "specularColor",
    "metallic",
    "roughness",
    "clearcoat",
    "clearcoatRoughness",
    "opacity",
    "occlusion",
)


def _preview_surface(ctx: _Ctx, node: Any, mp: MaterialPrim) -> None:
    """A MaterialX ``UsdPreviewSurface`` node: its inputs are ours."""
    for name in _PREVIEW_INPUTS:
        _set(ctx, mp, name, ctx.input(node, name), ctx.const(node, name))
    mp.use_specular_workflow = bool(_const_only(ctx, node, "useSpecularWorkflow")[0])
    mp.ior = min(max(_const_only(ctx, node, "ior")[0], 1.0), 4.0)
    mp.opacity_threshold = min(max(_const_only(ctx, node, "opacityThreshold")[0], 0.0), 1.0)
    src = node.source("normal")
    if isinstance(src, _Conn):
        n = ctx.input(node, "normal", (0.0, 0.0, 1.0))
        if isinstance(n, _Tex):
            _set(ctx, mp, "normal", n, (0.0, 0.0, 1.0))
    for name, why in (("displacement", "no displacement"), ("opacityMode", "opacity is coverage")):
        v = node.source(name)
        if isinstance(v, _Conn) or (_vec(v) is not None and _vec(v) != _vec(node.default(name))):
            ctx.note(f"input '{name}' is not modelled: {why}")


def translate_shader(node: Any, mp: MaterialPrim, label: str) -> MaterialPrim:
    """Fill ``mp`` from a surface shader node (``_MxNode``/``_UsdNode``)."""
    ctx = _Ctx(label)
    cat = node.category
    try:
        if cat == STANDARD_SURFACE:
            _standard_surface(ctx, node, mp)
        elif cat == USD_PREVIEW_SURFACE:
            _preview_surface(ctx, node, mp)
        else:
            mp.uses_defaults = True
            ctx.warn(f"surface shader '{cat}' is not supported; using defaults")
    except Exception as exc:  # noqa: BLE001 - bad input never crashes
        mp.uses_defaults = True
        ctx.warn(f"could not be translated ({type(exc).__name__}: {exc}); using defaults")
    mp.warnings.extend(ctx.warnings)
    mp.notes.extend(ctx.notes)
    return mp


# --- documents ----------------------------------------------------------------------------


@dataclass
class MtlxDocument:
    """One read ``.mtlx`` file: its materials (``surfacematerial`` names) or the error."""

    path: str
    doc: Any = None
    error: str = ""
    materials: list[str] = field(default_factory=list)
    _translated: dict[str, MaterialPrim] = field(default_factory=dict)

    def material(self, name: str, path: str) -> MaterialPrim:
        """Material ``name`` translated, as a fresh record at scene path ``path``."""
        mp = self._translated.get(name)
        if mp is None:
            mp = self._translate(name)
            self._translated[name] = mp
        return replace(
            mp,
            path=path,
            diffuse_color=mp.diffuse_color.copy(),
            emissive_color=mp.emissive_color.copy(),
            specular_color=mp.specular_color.copy(),
            textures=dict(mp.textures),
            warnings=list(mp.warnings),
            notes=list(mp.notes),
        )

    def _translate(self, name: str) -> MaterialPrim:
        label = f"MaterialX material '{name}' ({os.path.basename(self.path)})"
        try:
            return self._translate_node(name, label)
        except Exception as exc:  # noqa: BLE001 - bad input never crashes
            mp = MaterialPrim(path="", source=SOURCE, uses_defaults=True)
            mp.warnings.append(f"{label}: could not be read ({exc}); using defaults")
            return mp

    def _translate_node(self, name: str, label: str) -> MaterialPrim:
        import MaterialX as mx

        mp = MaterialPrim(path="", source=SOURCE)
        node = self.doc.getNode(name) if self.doc is not None else None
        if node is None:
            mp.uses_defaults = True
            mp.warnings.append(f"{label}: not found in the document; using defaults")
            return mp
        shaders = mx.getShaderNodes(node, mx.SURFACE_SHADER_TYPE_STRING)
        if not shaders:
            mp.uses_defaults = True
            mp.warnings.append(f"{label}: no surface shader; using defaults")
            return mp
        if node.getInput("displacementshader") is not None:
            mp.notes.append(f"{label}: its displacement shader is not modelled")
        return translate_shader(_MxNode(self, shaders[0]), mp, label)


def load_document(path: str) -> MtlxDocument:
    """Read ``path`` (never raises: a failure is :attr:`MtlxDocument.error`)."""
    out = MtlxDocument(path)
    try:
        import MaterialX as mx

        doc = mx.createDocument()
        mx.readFromXmlFile(doc, path)
        doc.setDataLibrary(standard_library())
        out.doc = doc
        out.materials = [str(m.getName()) for m in doc.getMaterialNodes()]
    except Exception as exc:  # noqa: BLE001 - an unreadable document is one warning
        out.doc = None
        out.error = " ".join(str(exc).split()) or type(exc).__name__
    return out


class MtlxDocumentCache:
    """Parsed documents per resolved file, re-read when the file's size or mtime
    changes."""

    def __init__(self) -> None:
        self._docs: dict[str, tuple[tuple[int, int], MtlxDocument]] = {}

    def get(self, path: str) -> MtlxDocument:
        try:
            st = os.stat(path)
            key = (st.st_mtime_ns, st.st_size)
        except OSError as exc:
            return MtlxDocument(path, error=exc.strerror or "cannot be read")
        hit = self._docs.get(path)
        if hit is not None and hit[0] == key:
            return hit[1]
        doc = load_document(path)
        self._docs[path] = (key, doc)
        return doc


# --- stage: references to .mtlx files -----------------------------------------------------


@dataclass(frozen=True)
class MtlxReference:
    """A reference (or payload) from a prim to a ``.mtlx`` document."""

    #: Scene path of the referencing prim (an instance proxy's own path).
    prim_path: str
    #: The authored asset path and the layer that authored it.
    asset: str
    layer: str
    #: The resolved file ("" when it does not resolve).
    resolved: str
    #: The reference's target prim path ("" = the default prim).
    target: str
    arc: str = "reference"


def _is_mtlx(asset: str) -> bool:
    return asset.lower().endswith(".mtlx")


def mtlx_references(prim: Usd.Prim) -> list[MtlxReference]:
    """The ``.mtlx`` references and payloads of ``prim``'s composed prim stack (variant
    specs included), strongest first; an item deleted by a stronger spec is dropped.
    Cheap to skip: call it for prims with authored references or payloads only."""
    out: list[MtlxReference] = []
    deleted: set[tuple[str, str, str]] = set()
    seen: set[tuple[str, str, str, str]] = set()
    path = str(prim.GetPath())
    try:
        stack = prim.GetPrimStack()
    except Exception:  # noqa: BLE001
        return out
    for spec in stack:
        for arc, lst in (("reference", spec.referenceList), ("payload", spec.payloadList)):
            if lst is None:
                continue
            for item in lst.deletedItems:
                deleted.add((arc, item.assetPath, str(item.primPath)))
            items = [
                *lst.explicitItems,
                *lst.prependedItems,
                *lst.appendedItems,
                *lst.addedItems,
            ]
            for item in items:
                asset = item.assetPath
                if not asset or not _is_mtlx(asset):
                    continue
                target = str(item.primPath) if item.primPath != Sdf.Path.emptyPath else ""
                key = (arc, asset, target)
                layer = spec.layer
                if key in deleted or (*key, layer.identifier) in seen:
                    continue
                seen.add((*key, layer.identifier))
                out.append(
                    MtlxReference(
                        path, asset, layer.identifier, _resolve(layer, asset), target, arc
                    )
                )
    return out


def _resolve(layer: Sdf.Layer, asset: str) -> str:
    try:
        p = layer.ComputeAbsolutePath(asset)
        r = str(Ar.GetResolver().Resolve(p))
    except Exception:  # noqa: BLE001
        return ""
    return r if r and os.path.isfile(r) else ""


def usd_name(mtlx_name: str) -> str:
    """usdMtlx's prim name for a MaterialX element name (the first ``:`` -> ``__``)."""
    return mtlx_name.replace(":", "__", 1)


def material_prim_paths(
    prim_path: str, target: str, materials: list[str]
) -> list[tuple[str, str]] | None:
    """(scene path, MaterialX name) of each material a reference to a document with
    ``materials`` composes under ``prim_path``, by usdMtlx's layout (``/MaterialX`` ->
    ``Materials/<name>``): target ``/MaterialX/Materials`` -> ``<prim>/<name>``;
    ``/MaterialX`` or none -> ``<prim>/Materials/<name>``;
    ``/MaterialX/Materials/<name>`` -> the prim itself. None for any other target
    (``/MaterialX/Shaders``, a look's ``/ModelRoot``, ...): no materials we translate."""
    t = target.rstrip("/") if target != "/" else target
    by_usd = {usd_name(m): m for m in materials}
    if t in ("", "/MaterialX"):
        base = prim_path.rstrip("/") + "/Materials"
    elif t == "/MaterialX/Materials":
        base = prim_path.rstrip("/")
    elif t.startswith("/MaterialX/Materials/") and t.count("/") == 3:
        name = t.rsplit("/", 1)[1]
        return [(prim_path, by_usd[name])] if name in by_usd else []
    else:
        return None
    return [(f"{base}/{u}", m) for u, m in by_usd.items() if Sdf.Path.IsValidIdentifier(u)]


# --- MaterialX networks authored in USD ---------------------------------------------------


def read_usd_materialx(prim: Usd.Prim, time: Usd.TimeCode) -> MaterialPrim | None:
    """A UsdShade Material whose surface (``mtlx`` render context, else universal) is a
    MaterialX node definition (``ND_standard_surface_surfaceshader``,
    ``ND_UsdPreviewSurface_surfaceshader``, ...) -> :class:`MaterialPrim`; None when it
    is not a MaterialX network (the caller reads it as UsdPreviewSurface)."""
    try:
        src = UsdShade.Material(prim).ComputeSurfaceSource("mtlx")  # else universal
        shader = src[0] if src and src[0] else None
    except Exception:  # noqa: BLE001
        return None
    if shader is None or not shader.GetPrim().IsValid():
        return None
    sid = shader.GetShaderId() or ""
    if not sid.startswith("ND_"):
        return None
    try:
        node = _UsdNode(shader, time)
    except Exception:  # noqa: BLE001 - the libraries could not be loaded
        return None
    if node.nodedef is None:
        return None
    mp = MaterialPrim(path=str(prim.GetPath()), source=SOURCE)
    return translate_shader(node, mp, f"material <{prim.GetPath()}>")
