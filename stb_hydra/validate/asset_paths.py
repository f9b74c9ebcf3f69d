"""Asset-path safety of untrusted content, checked on the raw layers *before* composing.

Starting from the asset's root layer (opened with ``Sdf.Layer.FindOrOpen``, which
reads that one file and resolves nothing), every authored asset path is collected
with ``UsdUtils.ExtractExternalReferences`` -- sublayers, references, payloads and
asset-valued attributes (default and time samples), clips -- and checked:

* absolute paths, URLs (``scheme:``) and variable expressions (backquoted; their
  value depends on the environment) are unsafe;
* a relative path is anchored at its layer (``Sdf.Layer.ComputeAbsolutePath``; for a
  path inside a .usdz the package file counts) and must stay inside the library
  root after resolving symlinks (``os.path.realpath``).

Safe layer dependencies inside the root are opened and scanned the same way
(recursively); nothing outside the root is ever opened. Missing files are left to
the composed-stage validators (MissingReferenceValidator, CompositionErrorTest).
One ``asset_path_unsafe`` error per offending path names the layer and, where the
layer's own specs say so, the prim that authors it.
"""

from __future__ import annotations

import os
import re

from pxr import Sdf, Tf, Usd, UsdUtils

from .common import finding
from .findings import Finding

LAYER_EXTENSIONS = (".usd", ".usda", ".usdc", ".usdz")
_URL = re.compile(r"^[A-Za-z][A-Za-z0-9+.\-]+:")
_WIN_ABS = re.compile(r"^(?:[A-Za-z]:[\\/]|\\\\)")


def _inside(path: str, root: str) -> bool:
    try:
        return os.path.commonpath([path, root]) == root
    except ValueError:
        return False


def _asset_strings(v: object) -> list[str]:
    if isinstance(v, Sdf.AssetPath):
        return [v.path]
    if isinstance(v, str):
        return [v]
    try:
        return [a.path if isinstance(a, Sdf.AssetPath) else str(a) for a in v]  # type: ignore[union-attr]
    except TypeError:
        return []


def _prims_authoring(layer: Sdf.Layer) -> dict[str, str]:
    """Authored asset path -> first prim path whose specs author it (best effort)."""
    out: dict[str, str] = {}

    def visit(path: Sdf.Path) -> None:
        if path.IsPrimPath() or path.IsPrimVariantSelectionPath():
            spec = layer.GetPrimAtPath(path)
            if spec is None:
                return
            prim = str(path.StripAllVariantSelections())
            for lst in (spec.referenceList, spec.payloadList):
                for item in lst.GetAddedOrExplicitItems():
                    if item.assetPath:
                        out.setdefault(item.assetPath, prim)
        elif path.IsPropertyPath():
            spec = layer.GetAttributeAtPath(path)
            if spec is None or spec.typeName not in (
                Sdf.ValueTypeNames.Asset,
                Sdf.ValueTypeNames.AssetArray,
            ):
                return
            prim = str(path.GetPrimPath().StripAllVariantSelections())
            vals = [spec.default] if spec.HasDefaultValue() else []
            vals += [layer.QueryTimeSample(path, t) for t in layer.ListTimeSamplesForPath(path)]
            for v in vals:
                for p in _asset_strings(v):
                    if p:
                        out.setdefault(p, prim)

    layer.Traverse(Sdf.Path.absoluteRootPath, visit)
    return out


def classify(authored: str, layer: Sdf.Layer, root: str) -> tuple[str | None, str]:
    """(problem or None, anchored filesystem path) for one authored asset path."""
    if authored.startswith("`"):
        return "is a variable expression (its target depends on the environment)", ""
    if os.path.isabs(authored) or _WIN_ABS.match(authored):
        return "is absolute", authored
    if _URL.match(authored):
        return "is a URL", authored
    anchored = layer.ComputeAbsolutePath(authored)
    fs = anchored.split("[", 1)[0]
    real = os.path.realpath(fs)
    if not _inside(real, root):
        return f"escapes the library root (resolves to '{real}')", anchored
    return None, anchored


def scan_asset_paths(path: str, library_root: str) -> tuple[list[Finding], bool]:
    """Scan ``path`` and its in-root layer dependencies.

    Returns (findings, readable): ``readable`` is False when the root file itself is
    not a USD layer (one ``unreadable`` finding)."""
    from .. import limits
    from .findings import RUNNER_RULES

    root = os.path.realpath(library_root)
    start = os.path.realpath(path)
    out: list[Finding] = []
    if not _inside(start, root):  # a symlink out of the library: never opened
        return [
            finding(
                "asset_path_unsafe",
                "/",
                f"'{os.path.basename(path)}' is a symlink that escapes the library root "
                f"(resolves to '{start}'); not opened",
            )
        ], True
    todo, seen = [start], set()
    while todo:
        ident = todo.pop()
        if ident in seen:
            continue
        seen.add(ident)
        if len(seen) > limits.VALIDATE_MAX_LAYERS:
            r = RUNNER_RULES["unreadable"]
            msg = (
                f"more than {limits.VALIDATE_MAX_LAYERS} layers (nested sublayers, references "
                "or payloads); stage not opened"
            )
            return [*out, Finding("unreadable", r.severity, "/", msg, r.hint)], True
        size = _size(ident)
        if size > limits.VALIDATE_LAYER_MAX_BYTES:
            r = RUNNER_RULES["unreadable"]
            msg = (
                f"layer '{os.path.relpath(ident.split('[', 1)[0], root)}' is {size / 2**20:.0f} "
                f"MiB, over the {limits.VALIDATE_LAYER_MAX_BYTES / 2**20:.0f} MiB limit; "
                "not opened"
            )
            return [*out, Finding("unreadable", r.severity, "/", msg, r.hint)], ident != start
        try:
            layer = Sdf.Layer.FindOrOpen(ident)
        except Tf.ErrorException as exc:
            layer = None
            err = " ".join(str(exc).split())
        else:
            err = "not a USD layer"
        if layer is None:
            if ident == start:
                r = RUNNER_RULES["unreadable"]
                return [
                    Finding("unreadable", r.severity, "/", f"cannot read layer: {err}", r.hint)
                ], False
            continue
        subs, refs, pays = UsdUtils.ExtractExternalReferences(layer.identifier)
        where = None
        for kind, items in (("sublayer", subs), ("reference", refs), ("payload", pays)):
            for authored in items:
                if not authored:
                    continue
                problem, anchored = classify(authored, layer, root)
                if problem:
                    if where is None:
                        where = _prims_authoring(layer)
                    prim = "/" if kind == "sublayer" else where.get(authored, "/")
                    out.append(
                        finding(
                            "asset_path_unsafe",
                            prim,
                            f"{kind if kind != 'reference' else 'asset'} path @{authored}@ in "
                            f"layer '{_rel(layer, root)}' {problem}; stage not opened",
                        )
                    )
                    continue
                if (
                    kind in ("sublayer", "payload")
                    or anchored.lower().endswith(LAYER_EXTENSIONS)
                    or anchored.endswith("]")
                ) and _exists(anchored):
                    todo.append(anchored)
    return out, True


def _size(ident: str) -> int:
    """Size (bytes) of a layer file (a .usdz's package for a path inside one); 0 when
    it cannot be read (left to the open)."""
    try:
        return os.path.getsize(ident.split("[", 1)[0])
    except OSError:
        return 0


def _exists(anchored: str) -> bool:
    return os.path.exists(anchored.split("[", 1)[0])


def _rel(layer: Sdf.Layer, root: str) -> str:
    p = layer.realPath or layer.identifier
    try:
        return os.path.relpath(p, root)
    except ValueError:
        return p


#: Library root for the AssetPaths validator when run from a plain UsdValidation client
#: (default: the root layer's directory). ``stb validate`` scans before composing and
#: uses its PATH argument instead.
LIBRARY_ROOT_ENV = "STB_VALIDATE_LIBRARY_ROOT"


def check_asset_paths(stage: Usd.Stage) -> list[Finding]:
    """AssetPaths stage validator: the scan of the stage's root layer (see
    :data:`LIBRARY_ROOT_ENV` for the library root)."""
    rl = stage.GetRootLayer()
    if not rl.realPath:
        return []
    root = os.environ.get(LIBRARY_ROOT_ENV) or os.path.dirname(rl.realPath)
    findings, _ = scan_asset_paths(rl.realPath, root)
    for f in findings:
        f.message = f.message.replace("; stage not opened", "")
    return findings
