"""Validate one asset file: pre-compose asset-path scan, open, one UsdValidation
context with the built-in and stb validators, findings.

Rule selection (``--rules``): tokens, comma- or space-separated --

* ``default``: :data:`DEFAULT_BUILTINS` + every stb validator;
* ``stb``: every stb validator; ``usd``: :data:`DEFAULT_BUILTINS`;
  ``usd:all``: every registered non-stb validator except the usdz-package ones;
* an stb rule id (``stb_overlap``): its validator, keeping only that rule's findings;
* a validator name (``LightValues``, ``stb_hydra.validate:LightValues``,
  ``usdShadeValidators:ShaderSdrCompliance``) or a UsdValidation keyword
  (``UsdShadeValidators``).

The asset-path safety scan always runs first (an unsafe asset is never opened), and
``crash`` / ``unreadable`` are always reported.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field

from pxr import Tf, Usd, UsdValidation

from . import analysis
from .asset_paths import scan_asset_paths
from .common import crash_hook
from .findings import (
    ERROR,
    INFO,
    KEYWORD,
    PLUGIN_NAME,
    RULES,
    RUNNER_RULES,
    WARNING,
    AssetReport,
    Finding,
    split_hint,
)
from .plugin import full_name

#: Built-in validators run by default: composition errors, unresolvable dependencies,
#: stage metadata (defaultPrim), UsdLux encapsulation, attribute types vs schema.
#: usdGeomValidators:StageMetadataChecker is superseded by our StageUnits.
DEFAULT_BUILTINS = (
    "usdValidation:CompositionErrorTest",
    "usdUtilsValidators:MissingReferenceValidator",
    "usdValidation:StageMetadataChecker",
    "usdValidation:AttributeTypeMismatch",
    "usdLuxValidators:EncapsulationRulesValidator",
)
_USDZ_KEYWORD = "UsdzValidators"
#: Run by the CLI before composing, so not inside the context.
_PRESCAN = full_name("AssetPaths")

_SEV = {
    UsdValidation.ValidationErrorType.Error: ERROR,
    UsdValidation.ValidationErrorType.Warn: WARNING,
    UsdValidation.ValidationErrorType.Info: INFO,
}


class SelectionError(ValueError):
    """An unknown ``--rules`` token (one-line message)."""


@dataclass
class Selection:
    """Which validators run and which of their findings are kept."""

    #: Validators whose every finding is kept.
    full: set[str] = field(default_factory=set)
    #: stb rule ids kept from validators not in ``full``.
    rules: set[str] = field(default_factory=set)

    @property
    def validators(self) -> list[str]:
        names = set(self.full) | {full_name(RULES[r].validator) for r in self.rules}
        names.discard(_PRESCAN)
        return sorted(names)

    def keeps(self, f: Finding) -> bool:
        if f.rule in RUNNER_RULES or f.rule == "asset_path_unsafe":
            return True
        return f.validator in self.full or f.rule in self.rules

    @classmethod
    def parse(cls, tokens: list[str] | None) -> Selection:
        """Selection from ``--rules`` tokens (None/empty = ``default``)."""
        reg = UsdValidation.ValidationRegistry()
        all_meta = reg.GetAllValidatorMetadata()
        known = {m.name for m in all_meta}
        ours = {full_name(v) for v in {r.validator for r in RULES.values()}}
        sel = cls()
        flat = [t for tok in (tokens or ["default"]) for t in tok.replace(",", " ").split()]
        for tok in flat or ["default"]:
            if tok == "default":
                sel.full |= ours | {b for b in DEFAULT_BUILTINS if b in known}
            elif tok == KEYWORD:
                sel.full |= ours
            elif tok == "usd":
                sel.full |= {b for b in DEFAULT_BUILTINS if b in known}
            elif tok == "usd:all":
                sel.full |= {
                    m.name
                    for m in all_meta
                    if not m.isSuite
                    and not m.name.startswith(PLUGIN_NAME + ":")
                    and _USDZ_KEYWORD not in list(m.GetKeywords())
                }
            elif tok in RULES:
                sel.rules.add(tok)
            elif full_name(tok) in ours:
                sel.full.add(full_name(tok))
            elif tok in known:
                sel.full.add(tok)
            else:
                kw = [m.name for m in reg.GetValidatorMetadataForKeyword(tok) if not m.isSuite]
                if not kw:
                    raise SelectionError(
                        f"unknown rule '{tok}' (an stb rule id, validator name or keyword; "
                        "see docs/VALIDATE.md)"
                    )
                sel.full |= set(kw)
        return sel


_ctx_cache: dict[tuple[str, ...], UsdValidation.ValidationContext] = {}


def _context(sel: Selection) -> UsdValidation.ValidationContext | None:
    key = tuple(sel.validators)
    if not key:
        return None
    ctx = _ctx_cache.get(key)
    if ctx is None:
        vals = UsdValidation.ValidationRegistry().GetOrLoadValidatorsByName(list(key))
        ctx = UsdValidation.ValidationContext(vals)
        _ctx_cache[key] = ctx
    return ctx


def finding_from_error(err: UsdValidation.ValidationError) -> Finding:
    """Convert a UsdValidation error: stb errors keep their rule id, built-in ones are
    named by their identifier (``validator.errorName``)."""
    v = err.GetValidator()
    vname = v.GetMetadata().name if v is not None else ""
    ours = vname.startswith(PLUGIN_NAME + ":")
    rule = err.GetName() if ours else err.GetIdentifier()
    msg, hint = split_hint(err.GetMessage()) if ours else (err.GetMessage(), "")
    prim = "/"
    for site in err.GetSites():
        if site.IsPrim():
            prim = str(site.GetPrim().GetPath())
            break
        if site.IsProperty():
            prim = str(site.GetProperty().GetPath())
            break
    sev = _SEV.get(err.GetType(), INFO)
    return Finding(rule, sev, prim, " ".join(msg.split()), hint, vname)


def _runner_finding(rule: str, prim: str, message: str) -> Finding:
    r = RUNNER_RULES[rule]
    return Finding(rule, r.severity, prim, message, r.hint)


def _render_thumbnail(stage: Usd.Stage, rep: AssetReport) -> None:
    from .thumbnails import render_thumbnail

    t = time.perf_counter()
    try:
        rep.thumbnail_png_b64 = render_thumbnail(stage)
    except Exception as exc:  # noqa: BLE001 - a thumbnail never fails validation
        msg = " ".join(f"{type(exc).__name__}: {exc}".split())[:500]
        rep.findings.append(_runner_finding("thumbnail", "/", f"no thumbnail: {msg}"))
    rep.timings["thumbnail"] = time.perf_counter() - t


def validate_file(
    path: str | os.PathLike[str],
    library_root: str | os.PathLike[str] | None = None,
    selection: Selection | None = None,
    thumbnails: bool = False,
) -> AssetReport:
    """Validate one asset file (see the module docstring). Exceptions propagate: the
    caller (worker) turns them into ``crash`` findings."""
    t0 = time.perf_counter()
    p = os.path.abspath(os.fspath(path))
    root = os.path.abspath(os.fspath(library_root)) if library_root else os.path.dirname(p)
    sel = selection or Selection.parse(None)
    rep = AssetReport(p, root)
    crash_hook("segv", p)
    crash_hook("abort", p)
    crash_hook("hang", p)
    found, readable = scan_asset_paths(p, root)
    rep.timings["scan"] = time.perf_counter() - t0
    rep.findings.extend(found)
    if not readable or found:
        rep.timings["total"] = time.perf_counter() - t0
        return rep.finish()
    t = time.perf_counter()
    try:
        stage = Usd.Stage.Open(p)
    except Tf.ErrorException as exc:
        stage = None
        msg = " ".join(str(exc).split())
    else:
        msg = "not a USD stage"
    rep.timings["open"] = time.perf_counter() - t
    if stage is None:
        rep.findings.append(_runner_finding("unreadable", "/", f"cannot open stage: {msg}"))
        rep.timings["total"] = time.perf_counter() - t0
        return rep.finish()
    rep.opened = True
    t = time.perf_counter()
    try:
        ctx = _context(sel)
        errors = ctx.Validate(stage) if ctx is not None else []
        rep.findings.extend(f for f in map(finding_from_error, errors) if sel.keeps(f))
        ana = analysis.cached(stage)
        if ana is not None:
            rep.stats["lights"] = len(ana.lights)
            rep.stats["meshes"] = len(ana.meshes)
        rep.timings["validate"] = time.perf_counter() - t
        if thumbnails:
            _render_thumbnail(stage, rep)
    finally:
        analysis.clear_cache()
        del stage
    rep.timings["total"] = time.perf_counter() - t0
    return rep.finish()


def crash_report(path: str, root: str, message: str, seconds: float = 0.0) -> AssetReport:
    """Report for an asset whose worker died or raised."""
    rep = AssetReport(path, root)
    rep.findings.append(_runner_finding("crash", "/", message))
    rep.timings["total"] = seconds
    return rep.finish()


def validate_in_process(path: str, root: str, sel: Selection, thumbnails: bool) -> AssetReport:
    """:func:`validate_file` with exceptions (Tf errors included) as ``crash`` findings."""
    t0 = time.perf_counter()
    try:
        return validate_file(path, root, sel, thumbnails)
    except Exception as exc:  # noqa: BLE001 - one bad asset must not stop the run
        analysis.clear_cache()
        msg = " ".join(f"{type(exc).__name__}: {exc}".split())
        return crash_report(path, root, msg[:2000], time.perf_counter() - t0)
