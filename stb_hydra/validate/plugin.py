"""Registration of our rules as UsdValidation validators (keyword ``stb``).

``plugInfo.json`` next to this file declares a Python plugin named
``stb_hydra.validate`` with one entry per validator (doc, keywords, schemaTypes), so
the registry knows our validators by name and keyword, and any UsdValidation client
that selects them makes Plug import ``stb_hydra.validate``, which registers the task
functions here (``RegisterPluginPrimValidator`` / ``RegisterPluginStageValidator``).

The registry reads plugInfo metadata once, when it is first constructed. If it was
constructed before our plugin path was registered, the plugin entries are unknown
and we register the same validators at run time (``RegisterPrimValidator`` with
metadata built from the same plugInfo.json), under the same names.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from importlib import resources
from pathlib import Path

from pxr import Plug, Sdf, Usd, UsdValidation

from .asset_paths import check_asset_paths
from .common import crash_hook
from .findings import ERROR, HINT_SEP, INFO, KEYWORD, PLUGIN_NAME, WARNING, Finding
from .rules_bake import check_bake
from .rules_lights import check_ies, check_light_values
from .rules_links import check_links
from .rules_overlap import check_overlap
from .rules_photometry import check_photometry
from .rules_shadows import check_shadows
from .rules_units import check_units

#: The folder of this plugin's plugInfo.json (package data, through importlib.resources).
PLUGIN_DIR = Path(str(resources.files("stb_hydra.validate")))

_TYPE = {
    ERROR: UsdValidation.ValidationErrorType.Error,
    WARNING: UsdValidation.ValidationErrorType.Warn,
    INFO: UsdValidation.ValidationErrorType.Info,
}

#: short name -> ("prim" | "stage", body)
TASKS: dict[str, tuple[str, Callable]] = {
    "LightValues": ("prim", check_light_values),
    "IesProfile": ("prim", check_ies),
    "Photometry": ("stage", check_photometry),
    "ShadowBudget": ("stage", check_shadows),
    "StbNoiseRisk": ("stage", check_overlap),
    "StageUnits": ("stage", check_units),
    "AssetPaths": ("stage", check_asset_paths),
    "StaticBake": ("stage", check_bake),
    "LightLinks": ("stage", check_links),
}


def full_name(short: str) -> str:
    return f"{PLUGIN_NAME}:{short}"


def to_error(stage: Usd.Stage, f: Finding) -> UsdValidation.ValidationError:
    """A UsdValidation error for one finding; the hint rides in the message."""
    path = Sdf.Path(f.prim) if Sdf.Path.IsValidPathString(f.prim) else Sdf.Path()
    msg = f.message
    if path.isEmpty or not path.IsAbsoluteRootOrPrimPath() or not stage.GetPrimAtPath(path):
        if f.prim not in ("", "/"):
            msg = f"<{f.prim}>: {msg}"
        path = Sdf.Path.absoluteRootPath
    if f.hint:
        msg += HINT_SEP + f.hint
    site = UsdValidation.ValidationErrorSite(stage, path)
    return UsdValidation.ValidationError(f.rule, _TYPE[f.severity], [site], msg)


def _task(short: str, kind: str, body: Callable) -> Callable:
    def run(obj, stage: Usd.Stage) -> list:
        ident = stage.GetRootLayer().identifier
        try:
            crash_hook("raise", ident)
            found = body(obj)
        except Exception as exc:  # noqa: BLE001 - a rule bug must surface as a finding
            where = str(obj.GetPath()) if kind == "prim" else "/"
            found = [
                Finding(
                    "crash",
                    ERROR,
                    where,
                    f"validator {full_name(short)} raised {type(exc).__name__}: {exc}",
                    "report this as a bug with the asset attached",
                    full_name(short),
                )
            ]
        return [to_error(stage, f) for f in found]

    if kind == "prim":
        return lambda prim, time_range: run(prim, prim.GetStage())
    return lambda stage, time_range: run(stage, stage)


def _plugin_metadata() -> dict[str, dict]:
    info = json.loads((PLUGIN_DIR / "plugInfo.json").read_text())
    vals = info["Plugins"][0]["Info"]["Validators"]
    return {k: v for k, v in vals.items() if k != "keywords"}


def register_plugin() -> None:
    """Make the plugInfo known to Plug (this process) and to child processes."""
    Plug.Registry().RegisterPlugins(str(PLUGIN_DIR))
    paths = os.environ.get("PXR_PLUGINPATH_NAME", "")
    if str(PLUGIN_DIR) not in paths.split(os.pathsep):
        os.environ["PXR_PLUGINPATH_NAME"] = os.pathsep.join(
            p for p in (paths, str(PLUGIN_DIR)) if p
        )


def register_validators() -> list[str]:
    """Register every validator once (idempotent). Returns their full names."""
    reg = UsdValidation.ValidationRegistry()
    meta = _plugin_metadata()
    names = []
    for short, (kind, body) in TASKS.items():
        name = full_name(short)
        names.append(name)
        if reg.HasValidator(name):
            continue
        fn = _task(short, kind, body)
        if reg.GetValidatorMetadata(name) is not None:
            if kind == "prim":
                reg.RegisterPluginPrimValidator(name, fn)
            else:
                reg.RegisterPluginStageValidator(name, fn)
            continue
        m = meta[short]
        md = UsdValidation.ValidatorMetadata(
            name=name,
            doc=m["doc"],
            keywords=[KEYWORD],
            schemaTypes=m.get("schemaTypes", []),
            isTimeDependent=False,
            isSuite=False,
        )
        if kind == "prim":
            reg.RegisterPrimValidator(md, fn)
        else:
            reg.RegisterStageValidator(md, fn)
    return names
