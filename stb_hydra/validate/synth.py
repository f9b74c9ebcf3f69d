"""Synthetic prefab layers for the validation tests and ``tools/bench_validate.py``.

A prefab is one small ``.usda`` file: metres, Y up, ``defaultPrim = "Prefab"``, a
10 m x 10 m ground quad (normal +Y), a 1 m box, and N sphere lights of radius 5 cm
1.5 m above the ground on a 2 m grid. A *clean* light emits ~790 lm
(8000 nits: I = L pi r^2 = 62.8 cd, Phi = 4 pi I), has shadows off except the first
two, and an authored ``stb:range`` of 3 m, so a clean prefab triggers no rule.
:data:`PLANTS` lists the problems that can be planted, each with the rule it must
trigger and the prim it must be reported on.
"""

from __future__ import annotations

import math
import shutil
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

CLEAN_NITS = 8000.0
RADIUS_M = 0.05
HEADER = '#usda 1.0\n(\n    defaultPrim = "Prefab"\n{units})\n\n'
UNITS = '    metersPerUnit = {mpu}\n    upAxis = "Y"\n'

#: A valid LM-63 profile that emits nothing (all candela 0).
ZERO_IES = (
    "IESNA:LM-63-2002\n[TEST] zero output\nTILT=NONE\n1 -1 1 3 1 1 2 0 0 0\n1 1 0\n"
    "0 45 90\n0\n0 0 0\n"
)


@dataclass
class LightSpec:
    name: str
    pos: tuple[float, float, float]
    attrs: dict[str, str] = field(default_factory=dict)  # "type name" -> usda value
    schemas: list[str] = field(default_factory=list)

    def usda(self, indent: str = "        ") -> str:
        api = ""
        if self.schemas:
            api = (
                " (\n"
                + indent
                + "    prepend apiSchemas = ["
                + ", ".join(f'"{s}"' for s in self.schemas)
                + "]\n"
                + indent
                + ")"
            )
        lines = [f'{indent}def SphereLight "{self.name}"{api}', indent + "{"]
        for decl, val in self.attrs.items():
            lines.append(f"{indent}    {decl} = {val}")
        x, y, z = self.pos
        lines.append(f"{indent}    double3 xformOp:translate = ({x:g}, {y:g}, {z:g})")
        lines.append(f'{indent}    uniform token[] xformOpOrder = ["xformOp:translate"]')
        lines.append(indent + "}")
        return "\n".join(lines)


def clean_light(i: int, n: int, shadowed: bool) -> LightSpec:
    side = max(1, math.ceil(math.sqrt(n)))
    x = (i % side - (side - 1) / 2) * 2.0
    z = (i // side - (side - 1) / 2) * 2.0
    attrs = {
        "float inputs:intensity": f"{CLEAN_NITS:g}",
        "float inputs:radius": f"{RADIUS_M:g}",
        "float stb:range": "3",
    }
    if not shadowed:
        attrs["bool inputs:shadow:enable"] = "0"
    return LightSpec(f"L{i}", (x, 1.5, z), attrs)


GROUND = """    def Mesh "Ground"
    {
        int[] faceVertexCounts = [4]
        int[] faceVertexIndices = [0, 1, 2, 3]
        point3f[] points = [(-5, 0, 5), (5, 0, 5), (5, 0, -5), (-5, 0, -5)]
        float3[] extent = [(-5, 0, -5), (5, 0, 5)]
    }

    def Cube "Box"
    {
        double size = 1
        double3 xformOp:translate = (0, 0.5, 0)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }
"""


@dataclass
class Prefab:
    """A prefab being authored; ``write`` makes the .usda file."""

    lights: list[LightSpec]
    mpu: float | None = 1.0
    extra: str = ""  # more prim text inside /Prefab
    scale: float = 1.0  # geometry scale (for cm prefabs)

    def text(self) -> str:
        units = UNITS.format(mpu=f"{self.mpu:g}") if self.mpu is not None else ""
        body = "\n\n".join(lt.usda() for lt in self.lights)
        ground = GROUND
        if self.scale != 1.0:
            ground = ground.replace(
                'def Mesh "Ground"\n    {',
                'def Mesh "Ground"\n    {\n        double3 xformOp:scale = '
                f"({self.scale:g}, {self.scale:g}, {self.scale:g})\n"
                '        uniform token[] xformOpOrder = ["xformOp:scale"]',
            )
        return (
            HEADER.format(units=units)
            + 'def Xform "Prefab" (\n    kind = "component"\n)\n{\n'
            + ground
            + '\n    def Xform "Lights"\n    {\n'
            + body
            + "\n    }\n"
            + self.extra
            + "}\n"
        )

    def write(self, path: Path) -> Path:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(self.text())
        return path


def clean_prefab(n: int = 4, shadowed: int = 2) -> Prefab:
    return Prefab([clean_light(i, n, i < shadowed) for i in range(n)])


# --- planted problems -----------------------------------------------------------------

L0 = "/Prefab/Lights/L0"


PlantFn = Callable[[Prefab, Path, Path], None]


def _set(attr: str, val: str, light: int = 0) -> PlantFn:
    def plant(p: Prefab, lib: Path, ies_src: Path) -> None:
        p.lights[light].attrs[attr] = val

    return plant


def _ies(name: str, src: str | None, extra: dict[str, str] | None = None) -> PlantFn:
    """IES profile ``name`` in <lib>/ies: ``src`` file of ``ies_src``, "zero", or None
    (missing)."""

    def plant(p: Prefab, lib: Path, ies_src: Path) -> None:
        (lib / "ies").mkdir(parents=True, exist_ok=True)
        if src == "zero":
            (lib / "ies" / name).write_text(ZERO_IES)
        elif src is not None:
            shutil.copyfile(ies_src / src, lib / "ies" / name)
        lt = p.lights[0]
        lt.schemas.append("ShapingAPI")
        lt.attrs["asset inputs:shaping:ies:file"] = f"@../ies/{name}@"
        lt.attrs["bool inputs:shaping:ies:normalize"] = "1"
        lt.attrs.update(extra or {})

    return plant


def _legacy(p: Prefab, lib: Path, ies_src: Path) -> None:
    lt = p.lights[0]
    lt.attrs.pop("float inputs:radius")
    lt.attrs["float radius"] = f"{RADIUS_M:g}"


def _flux_prefab(p: Prefab, lib: Path, ies_src: Path) -> None:
    # 6 lights of ~190 klm each (in band) -> 1.14 Mlm per prefab.
    nits = 190_000.0 / (4 * math.pi * math.pi * RADIUS_M**2)
    p.lights = [clean_light(i, 6, False) for i in range(6)]
    for lt in p.lights:
        lt.attrs["float inputs:intensity"] = f"{nits:.6g}"


def _shadow_count(p: Prefab, lib: Path, ies_src: Path) -> None:
    p.lights = [clean_light(i, 10, True) for i in range(10)]


def _dynamic(count: int) -> PlantFn:
    def plant(p: Prefab, lib: Path, ies_src: Path) -> None:
        for lt in p.lights[:count]:
            lt.attrs["uniform token stb:shadow:update"] = '"dynamic"'
            lt.attrs.pop("bool inputs:shadow:enable", None)

    return plant


def _atlas(p: Prefab, lib: Path, ies_src: Path) -> None:
    p.lights = [clean_light(i, 5, True) for i in range(5)]
    for lt in p.lights:
        lt.attrs.pop("float stb:range")  # automatic range ~35 m -> 1024^2 maps


def _overlap(p: Prefab, lib: Path, ies_src: Path) -> None:
    p.lights = [clean_light(i, 20, False) for i in range(20)]
    for lt in p.lights:
        lt.attrs.pop("float stb:range")


def _units_missing(p: Prefab, lib: Path, ies_src: Path) -> None:
    # Authored as a centimetre asset (USD's fallback) so only the metadata is at fault.
    p.mpu = None
    for lt in p.lights:
        lt.attrs["float inputs:radius"] = f"{RADIUS_M * 100:g}"
        lt.attrs["float stb:range"] = "300"
        lt.pos = tuple(100 * c for c in lt.pos)


def _unsafe_abs(p: Prefab, lib: Path, ies_src: Path) -> None:
    _ies("abs.ies", None)(p, lib, ies_src)
    p.lights[0].attrs["asset inputs:shaping:ies:file"] = "@/etc/stb_validate_abs.ies@"
    p.lights[1 % len(p.lights)].attrs["float inputs:intensity"] = "-1"  # must stay unseen


def _unsafe_escape(p: Prefab, lib: Path, ies_src: Path) -> None:
    p.extra += (
        '\n    def Xform "Outside" (\n        references = @../../outside.usda@\n    )\n'
        "    {\n    }\n"
    )
    p.lights[1 % len(p.lights)].attrs["float inputs:intensity"] = "-1"  # must stay unseen


@dataclass(frozen=True)
class Plant:
    """A planted problem: how to plant it and the (rule, prim) findings it must give."""

    plant: PlantFn
    expect: tuple[tuple[str, str], ...]
    #: Built-in (non-stb) findings it also gives, as rule-id prefixes.
    builtin: tuple[str, ...] = ()
    #: The stage must not be opened (asset-path safety).
    opened: bool = True


def _dome_missing(p: Prefab, lib: Path, ies_src: Path) -> None:
    p.extra += (
        '    def DomeLight "Sky"\n    {\n'
        "        asset inputs:texture:file = @../textures/missing_sky.exr@\n    }\n"
    )


PLANTS: dict[str, Plant] = {
    "intensity_nan": Plant(_set("float inputs:intensity", "nan"), (("intensity_invalid", L0),)),
    "intensity_negative": Plant(_set("float inputs:intensity", "-5"), (("intensity_invalid", L0),)),
    "exposure": Plant(_set("float inputs:exposure", "40"), (("exposure_invalid", L0),)),
    "color": Plant(_set("color3f inputs:color", "(1, -0.5, 1)"), (("color_invalid", L0),)),
    "radius": Plant(_set("float inputs:radius", "-0.1"), (("shape_invalid", L0),)),
    "cone": Plant(_set("float inputs:shaping:cone:angle", "200"), (("cone_angle_invalid", L0),)),
    "focus": Plant(_set("float inputs:shaping:focus", "-2"), (("focus_invalid", L0),)),
    "legacy": Plant(_legacy, (("legacy_attribute", L0),)),
    "ies_missing": Plant(
        _ies("missing.ies", None),
        (("ies_missing", L0),),
        builtin=("usdUtilsValidators:MissingReferenceValidator",),
    ),
    "ies_malformed": Plant(
        _ies("bad.ies", "mdlsdk__test_file_format_error.ies"), (("ies_malformed", L0),)
    ),
    "ies_zero": Plant(_ies("zero.ies", "zero"), (("ies_zero_power", L0),)),
    "ies_angle_scale": Plant(
        _ies(
            "down.ies", "luxtest__bega_84693k4.ies", {"float inputs:shaping:ies:angleScale": "-0.3"}
        ),
        (("ies_angle_scale", L0),),
    ),
    "dome_texture_missing": Plant(
        _dome_missing,
        (("dome_texture_missing", "/Prefab/Sky"),),
        builtin=("usdUtilsValidators:MissingReferenceValidator",),
    ),
    "flux_low": Plant(_set("float inputs:intensity", "1"), (("flux_light", L0),)),
    "flux_prefab": Plant(_flux_prefab, (("flux_prefab", "/Prefab"),)),
    "shadow_count": Plant(_shadow_count, (("shadow_count", "/Prefab"),)),
    "shadow_dynamic": Plant(_dynamic(1), (("shadow_dynamic", L0),)),
    "shadow_dynamic_count": Plant(
        _dynamic(3),
        (
            ("shadow_dynamic", L0),
            ("shadow_dynamic", "/Prefab/Lights/L1"),
            ("shadow_dynamic", "/Prefab/Lights/L2"),
            ("shadow_dynamic_count", "/Prefab"),
        ),
    ),
    "shadow_atlas": Plant(_atlas, (("shadow_atlas", "/Prefab"),)),
    "stb_overlap": Plant(
        _overlap, (("stb_overlap", "/Prefab/Box"), ("stb_overlap", "/Prefab/Ground"))
    ),
    "units_missing": Plant(_units_missing, (("units_missing", "/"),)),
    "unsafe_absolute": Plant(_unsafe_abs, (("asset_path_unsafe", L0),), opened=False),
    "unsafe_escape": Plant(
        _unsafe_escape, (("asset_path_unsafe", "/Prefab/Outside"),), opened=False
    ),
}


def write_planted(lib: Path, name: str, ies_src: Path, n_lights: int = 4) -> Path:
    """Write ``<lib>/prefabs/<name>.usda``: a clean prefab with the problem ``name``
    planted (IES sources are copied from ``ies_src`` into ``<lib>/ies``)."""
    p = clean_prefab(n_lights)
    PLANTS[name].plant(p, lib, ies_src)
    return p.write(lib / "prefabs" / f"{name}.usda")
