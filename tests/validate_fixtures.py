"""Test library for ``stb validate``: every planted prefab of
``stb_hydra.validate.synth.PLANTS`` plus multi-file scenes (references, native
instances, a PointInstancer) -- each with the exact (rule, prim) stb findings it must
give. Built in a temp dir by the tests."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from stb_hydra.validate.synth import PLANTS, clean_prefab, write_planted

UNITS_M = '(\n    defaultPrim = "{dp}"\n    metersPerUnit = {mpu}\n    upAxis = "{up}"\n)\n'


@dataclass
class Expected:
    """What validating one file must give."""

    stb: set[tuple[str, str]] = field(default_factory=set)
    #: Built-in rule-id prefixes allowed (and required) on this file.
    builtin: tuple[str, ...] = ()
    opened: bool = True


def _w(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def _header(dp: str, mpu: float = 1.0, up: str = "Y") -> str:
    return "#usda 1.0\n" + UNITS_M.format(dp=dp, mpu=f"{mpu:g}", up=up) + "\n"


def _light(name: str, intensity: str, extra: str = "", indent: str = "    ") -> str:
    return (
        f'{indent}def SphereLight "{name}"\n{indent}{{\n'
        f"{indent}    float inputs:intensity = {intensity}\n"
        f"{indent}    float inputs:radius = 0.05\n"
        f"{indent}    bool inputs:shadow:enable = 0\n"
        f"{indent}    float stb:range = 3\n{extra}"
        f"{indent}    double3 xformOp:translate = (0, 1.5, 0)\n"
        f'{indent}    uniform token[] xformOpOrder = ["xformOp:translate"]\n{indent}}}\n'
    )


def build_library(lib: Path, ies_src: Path) -> dict[str, Expected]:
    """Write the library under ``lib``; returns path (relative to lib) -> Expected."""
    exp: dict[str, Expected] = {}
    clean_prefab(4).write(lib / "prefabs" / "clean.usda")
    exp["prefabs/clean.usda"] = Expected()
    for name, plant in PLANTS.items():
        write_planted(lib, name, ies_src)
        exp[f"prefabs/{name}.usda"] = Expected(set(plant.expect), plant.builtin, plant.opened)

    # A centimetre part (geometry only) referenced into a metre scene, once without and
    # once with a compensating scale.
    _w(
        lib / "parts" / "cm_geo.usda",
        _header("Geo", 0.01)
        + """def Xform "Geo"
{
    def Cube "Block"
    {
        double size = 50
    }
}
""",
    )
    exp["parts/cm_geo.usda"] = Expected()
    _w(
        lib / "scenes" / "units_mismatch.usda",
        _header("Scene")
        + """def Xform "Scene"
{
    def "Part" (
        references = @../parts/cm_geo.usda@
    )
    {
    }

    def "Scaled" (
        references = @../parts/cm_geo.usda@
    )
    {
        double3 xformOp:scale = (0.01, 0.01, 0.01)
        uniform token[] xformOpOrder = ["xformOp:scale"]
    }
}
""",
    )
    exp["scenes/units_mismatch.usda"] = Expected({("units_mismatch", "/Scene/Part")})

    # A bad torch referenced twice as a native instance: the light inside the
    # instance prototype is found through both instance proxies.
    _w(
        lib / "parts" / "torch_bad.usda",
        _header("Torch") + 'def Xform "Torch"\n{\n' + _light("Light", "-1") + "}\n",
    )
    exp["parts/torch_bad.usda"] = Expected({("intensity_invalid", "/Torch/Light")})
    _w(
        lib / "scenes" / "instanced.usda",
        _header("Scene")
        + """def Xform "Scene"
{
    def "TorchA" (
        instanceable = true
        references = @../parts/torch_bad.usda@
    )
    {
    }

    def "TorchB" (
        instanceable = true
        references = @../parts/torch_bad.usda@
    )
    {
        double3 xformOp:translate = (3, 0, 0)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }
}
""",
    )
    exp["scenes/instanced.usda"] = Expected(
        {
            ("intensity_invalid", "/Scene/TorchA/Light"),
            ("intensity_invalid", "/Scene/TorchB/Light"),
        }
    )

    # PointInstancer: 3 instances of a dim lamp (0.1 lm) and of a lamp with a bad
    # exposure; reported once, on the prototype light prims.
    protos = (
        '        def Xform "Protos"\n        {\n'
        '            def Xform "Dim"\n            {\n'
        + _light("Bulb", "1", indent="                ")
        + '            }\n            def Xform "Hot"\n            {\n'
        + _light(
            "Bulb",
            "8000",
            "                    float inputs:exposure = 40\n",
            indent="                ",
        )
        + "            }\n        }\n"
    )
    _w(
        lib / "scenes" / "point_instancer.usda",
        _header("Prefab")
        + """def Xform "Prefab"
{
    def PointInstancer "Lamps"
    {
        rel prototypes = [</Prefab/Lamps/Protos/Dim>, </Prefab/Lamps/Protos/Hot>]
        int[] protoIndices = [0, 0, 0, 1, 1, 1]
        point3f[] positions = [(0, 0, 0), (2, 0, 0), (4, 0, 0), (0, 0, 2), (2, 0, 2), (4, 0, 2)]
"""
        + protos
        + "    }\n}\n",
    )
    exp["scenes/point_instancer.usda"] = Expected(
        {
            ("flux_light", "/Prefab/Lamps/Protos/Dim/Bulb"),
            ("exposure_invalid", "/Prefab/Lamps/Protos/Hot/Bulb"),
        }
    )

    # StaticBake (stb bake, issue 17): a static light over dynamic geometry, a coarse
    # lightmap, and a light marked baked whose fingerprint no longer matches the record.
    static = '    uniform token stb:mobility = "static"\n'
    _w(
        lib / "scenes" / "bake_dynamic.usda",
        _header("Scene")
        + 'def Xform "Scene"\n{\n'
        + _light("Lamp", "5000", static)
        + """    def Cube "Crate" (
        prepend apiSchemas = ["StbGeometryAPI"]
    )
    {
        double size = 0.5
        uniform bool stb:dynamic = 1
    }
}
""",
    )
    exp["scenes/bake_dynamic.usda"] = Expected({("static_light_dynamic_geometry", "/Scene/Lamp")})
    _w(
        lib / "scenes" / "bake_coarse.usda",
        _header("Scene")
        + """def Xform "Scene"
{
    def Mesh "Floor"
    {
        int[] faceVertexCounts = [4]
        int[] faceVertexIndices = [0, 1, 2, 3]
        point3f[] points = [(-1, 0, -1), (-1, 0, 1), (1, 0, 1), (1, 0, -1)]
        uniform float stb:lightmap:texelDensity = 1
    }
}
""",
    )
    exp["scenes/bake_coarse.usda"] = Expected({("lightmap_density", "/Scene/Floor")})
    stale = (
        "#usda 1.0\n(\n    customLayerData = {\n"
        '        dictionary "stb:bake" = {\n'
        '            dictionary lights = {\n                string "/Scene/Lamp" = "0"\n'
        '            }\n            string time = "2026-01-01T00:00:00Z"\n        }\n    }\n'
        '    defaultPrim = "Scene"\n    metersPerUnit = 1\n    upAxis = "Y"\n)\n\n'
    )
    _w(
        lib / "scenes" / "bake_stale.usda",
        stale
        + 'def Xform "Scene"\n{\n'
        + _light("Lamp", "5000", static + "    uniform bool stb:baked = 1\n")
        + "}\n",
    )
    exp["scenes/bake_stale.usda"] = Expected({("bake_stale", "/Scene/Lamp")})

    # Light / shadow linking: a misspelt exclude target, and a light-link that holds no
    # geometry (an Xform with nothing under it), next to a light linked correctly.
    floor = (
        '    def Mesh "Floor"\n    {\n'
        "        int[] faceVertexCounts = [4]\n        int[] faceVertexIndices = [0, 1, 2, 3]\n"
        "        point3f[] points = [(-1, 0, -1), (-1, 0, 1), (1, 0, 1), (1, 0, -1)]\n    }\n"
    )
    _w(
        lib / "scenes" / "link_missing.usda",
        _header("Scene")
        + 'def Xform "Scene"\n{\n'
        + floor
        + _light("Lamp", "5000", "        rel collection:shadowLink:excludes = </Scene/Flor>\n")
        + "}\n",
    )
    exp["scenes/link_missing.usda"] = Expected({("link_target_missing", "/Scene/Lamp")})
    only = "        uniform bool collection:lightLink:includeRoot = 0\n"
    _w(
        lib / "scenes" / "link_nothing.usda",
        _header("Scene")
        + 'def Xform "Scene"\n{\n'
        + floor
        + '    def Xform "Rig"\n    {\n    }\n'
        + _light(
            "Lamp", "5000", "        rel collection:lightLink:includes = </Scene/Rig>\n" + only
        )
        + _light(
            "Good", "5000", "        rel collection:lightLink:includes = </Scene/Floor>\n" + only
        )
        + "}\n",
    )
    exp["scenes/link_nothing.usda"] = Expected({("link_matches_nothing", "/Scene/Lamp")})

    # Not USD at all, and a layer the runner must survive.
    _w(lib / "broken" / "garbage.usda", '#usda 1.0\ndef Xform "A" {\n  this is not usda\n')
    exp["broken/garbage.usda"] = Expected({("unreadable", "/")}, opened=False)
    return exp
