"""Small in-memory stages authored by the tests (Sdf API: fast in bulk)."""

from __future__ import annotations

import numpy as np
from pxr import Sdf, Usd

import stb_hydra  # noqa: F401  (schema registration)


def _attr(spec, name, tname, value, uniform=False):
    a = Sdf.AttributeSpec(
        spec,
        name,
        tname,
        variability=Sdf.VariabilityUniform if uniform else Sdf.VariabilityVarying,
    )
    if value is not None:
        a.default = value
    return a


def many_lights_stage(
    n: int,
    animated: int = 0,
    seed: int = 1,
    animated_group: bool = False,
    meters_per_unit: float = 1.0,
) -> Usd.Stage:
    """``n`` SphereLights under /World/Lights; the first ``animated`` have a
    time-sampled translate (frames 1..48). With ``animated_group`` an extra
    /World/Moving group with an animated transform holds 10 static lights."""
    layer = Sdf.Layer.CreateAnonymous(".usda")
    rng = np.random.default_rng(seed)
    pos = rng.uniform(-50, 50, (n, 3))
    with Sdf.ChangeBlock():
        root = Sdf.PrimSpec(layer, "World", Sdf.SpecifierDef, "Xform")
        grp = Sdf.PrimSpec(root, "Lights", Sdf.SpecifierDef, "Xform")
        for i in range(n):
            ps = Sdf.PrimSpec(grp, f"L{i}", Sdf.SpecifierDef, "SphereLight")
            a = _attr(ps, "xformOp:translate", Sdf.ValueTypeNames.Double3, None)
            if i < animated:
                layer.SetTimeSample(a.path, 1.0, tuple(pos[i]))
                layer.SetTimeSample(a.path, 48.0, tuple(pos[i] + 1.0))
            else:
                a.default = tuple(pos[i])
            _attr(ps, "xformOpOrder", Sdf.ValueTypeNames.TokenArray, ["xformOp:translate"], True)
            _attr(ps, "inputs:intensity", Sdf.ValueTypeNames.Float, float(1000 + i % 7))
            _attr(ps, "inputs:radius", Sdf.ValueTypeNames.Float, 0.05)
        if animated_group:
            mv = Sdf.PrimSpec(root, "Moving", Sdf.SpecifierDef, "Xform")
            a = _attr(mv, "xformOp:translate", Sdf.ValueTypeNames.Double3, None)
            layer.SetTimeSample(a.path, 1.0, (0.0, 0.0, 0.0))
            layer.SetTimeSample(a.path, 48.0, (0.0, 5.0, 0.0))
            _attr(mv, "xformOpOrder", Sdf.ValueTypeNames.TokenArray, ["xformOp:translate"], True)
            for i in range(10):
                ps = Sdf.PrimSpec(mv, f"M{i}", Sdf.SpecifierDef, "SphereLight")
                _attr(ps, "inputs:intensity", Sdf.ValueTypeNames.Float, 500.0)
    layer.pseudoRoot.SetInfo("metersPerUnit", meters_per_unit)
    layer.pseudoRoot.SetInfo("upAxis", "Y")
    layer.pseudoRoot.SetInfo("startTimeCode", 1.0)
    layer.pseudoRoot.SetInfo("endTimeCode", 48.0)
    return Usd.Stage.Open(layer)


def usda_stage(text: str) -> Usd.Stage:
    """A stage from inline .usda text (header added when missing)."""
    if not text.lstrip().startswith("#usda"):
        text = "#usda 1.0\n" + text
    layer = Sdf.Layer.CreateAnonymous(".usda")
    layer.ImportFromString(text)
    return Usd.Stage.Open(layer)
