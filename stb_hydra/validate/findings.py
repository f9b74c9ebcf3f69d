"""Findings, severities and the rule table of ``stb validate``.

A *finding* is one problem at one prim: ``rule`` id, ``severity`` (error | warning |
info), ``prim`` path (or a layer identifier for layer-level problems), a one-line
``message`` and a ``hint`` saying how to fix it. Our rules are the ``RULES`` table;
OpenUSD's built-in validators produce findings whose rule id is the UsdValidation
error identifier (``validatorName.errorName``).

Inside UsdValidation an error carries only a name, a type, sites and a message, so
the hint travels in the message after :data:`HINT_SEP` and is split off again by
:func:`split_hint`.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

ERROR = "error"
WARNING = "warning"
INFO = "info"
SEVERITIES = (INFO, WARNING, ERROR)
_RANK = {INFO: 0, WARNING: 1, ERROR: 2}

#: Separator between message and fix hint inside a UsdValidation error message.
HINT_SEP = " Fix: "

#: Plugin (= Python module) that provides our validators; UsdValidation prefixes
#: plugin validator names with it: ``stb_hydra.validate:LightValues``.
PLUGIN_NAME = "stb_hydra.validate"
#: UsdValidation keyword shared by all our validators.
KEYWORD = "stb"


def severity_rank(sev: str) -> int:
    """0 info, 1 warning, 2 error (unknown -> error)."""
    return _RANK.get(sev, 2)


@dataclass(frozen=True)
class Rule:
    id: str
    severity: str
    validator: str  # short validator name (without the plugin prefix)
    summary: str
    hint: str


def _r(id_: str, sev: str, validator: str, summary: str, hint: str) -> Rule:
    return Rule(id_, sev, validator, summary, hint)


#: Every stb rule. Thresholds live in ``stb_hydra.limits`` ("Validation" section).
RULES: dict[str, Rule] = {
    r.id: r
    for r in (
        # -- LightValues (prim validator on UsdLuxLightAPI prims) --
        _r(
            "intensity_invalid",
            ERROR,
            "LightValues",
            "inputs:intensity is non-finite or negative (any authored time)",
            "author a finite intensity >= 0 (nits)",
        ),
        _r(
            "exposure_invalid",
            ERROR,
            "LightValues",
            "inputs:exposure is non-finite or beyond +-MAX_ABS_EXPOSURE stops",
            "keep exposure within +-30 stops; scale inputs:intensity instead",
        ),
        _r(
            "color_invalid",
            ERROR,
            "LightValues",
            "inputs:color has a non-finite or negative component, or colorTemperature "
            "is non-finite",
            "author a colour with finite components >= 0",
        ),
        _r(
            "shape_invalid",
            ERROR,
            "LightValues",
            "radius / width / height / length / angle is non-finite or negative",
            "author finite sizes >= 0 (stage units)",
        ),
        _r(
            "cone_angle_invalid",
            ERROR,
            "LightValues",
            "inputs:shaping:cone:angle outside (0, 180] degrees",
            "use a half-angle in (0, 180]; 180 (or no ShapingAPI) means no cone",
        ),
        _r(
            "focus_invalid",
            WARNING,
            "LightValues",
            "inputs:shaping:focus is negative or non-finite (renderers ignore it)",
            "author focus >= 0, or remove it",
        ),
        _r(
            "legacy_attribute",
            WARNING,
            "LightValues",
            "pre-21.02 un-namespaced light attribute (no 'inputs:' prefix)",
            "rename to the 'inputs:' name given in the message",
        ),
        _r(
            "dome_texture_missing",
            ERROR,
            "LightValues",
            "a DomeLight's (or RectLight's) inputs:texture:file does not resolve (any "
            "authored time): it renders as a uniform dome / a plain rect",
            "ship the texture inside the library and fix the relative path",
        ),
        # -- IesProfile --
        _r(
            "ies_missing",
            ERROR,
            "IesProfile",
            "inputs:shaping:ies:file does not resolve (checked at every authored time)",
            "ship the .ies file inside the library and fix the relative path",
        ),
        _r(
            "ies_malformed",
            ERROR,
            "IesProfile",
            "the IES file does not parse (the parser's message is quoted)",
            "re-export the profile as LM-63-2002 from the manufacturer's data",
        ),
        _r(
            "ies_zero_power",
            ERROR,
            "IesProfile",
            "the IES profile emits nothing (all candela values 0)",
            "use a profile with non-zero candela values",
        ),
        _r(
            "ies_angle_scale",
            WARNING,
            "IesProfile",
            "ies:angleScale inverts a downlight (negative scale anchors at the zenith) or "
            "is a value in degrees rather than a scale factor",
            "use 0 (no rescale) or a positive factor near 1; rotate the light to aim it",
        ),
        # -- Photometry (stage validator) --
        _r(
            "flux_light",
            WARNING,
            "Photometry",
            "a local light's luminous flux is outside the plausible band",
            "check intensity units (nits), exposure, radius and metersPerUnit",
        ),
        _r(
            "flux_prefab",
            WARNING,
            "Photometry",
            "a prefab's total luminous flux is implausibly high",
            "check intensity units and metersPerUnit of the prefab's lights",
        ),
        # -- StaticBake (stage validator; stb bake, docs/BAKE.md) --
        _r(
            "static_light_dynamic_geometry",
            WARNING,
            "StaticBake",
            "a static light's influence reaches dynamic geometry (lit unshadowed once baked)",
            "make the light dynamic, shrink its stb:range, or accept unshadowed light there",
        ),
        _r(
            "lightmap_density",
            WARNING,
            "StaticBake",
            "a baked mesh's lightmap texel density is under the threshold",
            "re-run stb bake with a higher --texel-density",
        ),
        _r(
            "bake_stale",
            WARNING,
            "StaticBake",
            "a baked light moved, changed or vanished since the bake (or is not in it)",
            "re-run stb bake on the edited scene",
        ),
        # -- LightLinks (stage validator; light and shadow linking, scene/links.py) --
        _r(
            "link_target_missing",
            WARNING,
            "LightLinks",
            "a light's light-link or shadow-link collection names a prim or collection "
            "that does not exist",
            "fix or remove the includes/excludes target (a typo, or a prim renamed or "
            "deleted since)",
        ),
        _r(
            "link_matches_nothing",
            WARNING,
            "LightLinks",
            "a light's light-link collection holds no geometry: the light lights nothing",
            "include the prims it should light, or author collection:lightLink:includeRoot = true",
        ),
        # -- ShadowBudget (stage validator) --
        _r(
            "shadow_count",
            WARNING,
            "ShadowBudget",
            "too many shadowed local lights in one prefab",
            "set inputs:shadow:enable = false on fill lights",
        ),
        _r(
            "shadow_dynamic",
            INFO,
            "ShadowBudget",
            "a light opts into dynamic shadows (stb:shadow:update = dynamic)",
            "keep dynamic shadows for lights near moving geometry only",
        ),
        _r(
            "shadow_dynamic_count",
            WARNING,
            "ShadowBudget",
            "too many dynamic-shadow opt-ins in one prefab",
            "use stb:shadow:update = static for lights that do not need moving shadows",
        ),
        _r(
            "shadow_atlas",
            WARNING,
            "ShadowBudget",
            "the prefab's estimated shadow-atlas area at the reference view is too large",
            "author a tighter stb:range or disable shadows on minor lights",
        ),
        # -- StbNoiseRisk (stage validator) --
        _r(
            "stb_overlap",
            WARNING,
            "StbNoiseRisk",
            "more lights overlap at a surface point than a 16-slot big tile represents well",
            "author smaller stb:range values, merge nearby lights, or drop fill lights",
        ),
        # -- StageUnits (stage validator) --
        _r(
            "units_missing",
            ERROR,
            "StageUnits",
            "the root layer does not author metersPerUnit and/or upAxis",
            "author metersPerUnit and upAxis in the layer's metadata",
        ),
        _r(
            "units_mismatch",
            WARNING,
            "StageUnits",
            "a referenced / payloaded / sublayered layer declares other units or up axis "
            "than the stage that uses it",
            "author the same metersPerUnit/upAxis, or compensate with a scale/rotate on "
            "the referencing prim",
        ),
        # -- AssetPaths (stage validator; also run on the raw layers before composing) --
        _r(
            "asset_path_unsafe",
            ERROR,
            "AssetPaths",
            "an asset path is absolute, a URL/expression, or escapes the library root; "
            "the stage is not opened",
            "use relative paths to files inside the library",
        ),
    )
}

#: Rules produced by the runner itself (not UsdValidation validators).
RUNNER_RULES: dict[str, Rule] = {
    r.id: r
    for r in (
        _r(
            "crash",
            ERROR,
            "",
            "validating the asset crashed the worker (segfault, Tf error, exception) or timed out",
            "open the asset in usdview; report the log",
        ),
        _r(
            "unreadable",
            ERROR,
            "",
            "the file is not a readable USD layer",
            "check the file format and permissions",
        ),
        _r(
            "thumbnail",
            INFO,
            "",
            "the --thumbnails render failed (validation is unaffected)",
            "see the message; thumbnails need stb_hydra.api and an OpenGL context",
        ),
    )
}


@dataclass
class Finding:
    """One problem; JSON-ready with :meth:`to_dict`."""

    rule: str
    severity: str
    prim: str
    message: str
    hint: str = ""
    #: UsdValidation validator that reported it ("" for the runner).
    validator: str = ""

    def to_dict(self) -> dict:
        return asdict(self)

    def key(self) -> tuple[str, str, str]:
        return (self.rule, self.prim, self.message)


@dataclass
class AssetReport:
    """Result of validating one file (JSON-ready with :meth:`to_dict`)."""

    path: str
    root: str
    status: str = "ok"
    opened: bool = False
    findings: list[Finding] = field(default_factory=list)
    #: Seconds per phase: scan, open, validate, thumbnail, total.
    timings: dict[str, float] = field(default_factory=dict)
    stats: dict[str, int] = field(default_factory=dict)
    thumbnail_png_b64: str | None = None

    def finish(self) -> AssetReport:
        """Dedupe and sort findings, set ``status`` from the worst severity."""
        seen: dict[tuple[str, str, str], Finding] = {}
        for f in self.findings:
            seen.setdefault(f.key(), f)
        self.findings = sorted(
            seen.values(), key=lambda f: (-severity_rank(f.severity), f.rule, f.prim, f.message)
        )
        if any(f.rule == "crash" for f in self.findings):
            self.status = "crash"
        elif self.findings:
            self.status = max((f.severity for f in self.findings), key=severity_rank)
            if self.status == INFO:
                self.status = "ok"
        else:
            self.status = "ok"
        return self

    def worst(self) -> int:
        return max((severity_rank(f.severity) for f in self.findings), default=-1)

    def to_dict(self) -> dict:
        d = {
            "path": self.path,
            "root": self.root,
            "status": self.status,
            "opened": self.opened,
            "findings": [f.to_dict() for f in self.findings],
            "timings": {k: round(v, 4) for k, v in self.timings.items()},
            "stats": dict(self.stats),
        }
        if self.thumbnail_png_b64 is not None:
            d["thumbnail_png_b64"] = self.thumbnail_png_b64
        return d

    @classmethod
    def from_dict(cls, d: dict) -> AssetReport:
        r = cls(d["path"], d.get("root", ""), d.get("status", "ok"), bool(d.get("opened")))
        r.findings = [Finding(**f) for f in d.get("findings", [])]
        r.timings = dict(d.get("timings", {}))
        r.stats = dict(d.get("stats", {}))
        r.thumbnail_png_b64 = d.get("thumbnail_png_b64")
        return r


def split_hint(message: str) -> tuple[str, str]:
    """``"msg Fix: hint"`` -> ("msg", "hint")."""
    i = message.rfind(HINT_SEP)
    if i < 0:
        return message, ""
    return message[:i], message[i + len(HINT_SEP) :]
