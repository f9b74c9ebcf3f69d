#!/usr/bin/env python3
"""Build stb_hydra's prefab library (usd_scenes/prefabs/*.usda) and the default scene
(usd_scenes/default.usda) that ``make demo`` renders.

The .usda files are checked in; this script is how they were made, and
``--check`` tells whether they still match it (tests/test_scenes.py runs that).
Nothing is random at run time: the few "random" values (torch flicker) come from
a fixed seed, so the output is byte-identical run to run.

Units and conventions: Y up, metres, UsdLux intensities in nits (cd/m^2). Every
light's doc string gives the photometry it was designed for: for a sphere light
of radius r and luminance L, I = L*pi*r^2 (cd) and an isotropic light emits
Phi = 4*pi*I (lm); with a *normalised hemispherical* IES profile (all our IES
files cover one hemisphere) Phi = 2*pi*I; a one-sided rect light emits
Phi = pi*L*w*h. Lumens are quoted for a white light (UsdLux colour and
blackbody colours are luminance-normalised only for colour temperature; a
saturated ``inputs:color`` lowers the lumens by its luminance, quoted too).
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from stb_hydra.scenegen.common import (
    MeshData,
    UsdaWriter,
    arch,
    box,
    box_c,
    convex_solid,
    cylinder,
    exposure_for_illuminance,
    luminance,
    merge,
    num,
    plane,
    sphere,
    sphere_cd,
    token_array,
    vec,
    write_text_atomic,
)

USD_SCENES = Path(__file__).resolve().parents[1] / "usd_scenes"  # this checkout's
PREFAB_DIR = USD_SCENES / "prefabs"

# --------------------------------------------------------------------------------------
# Photometric design of the prefab lights (single source of truth for docs and tests)
# --------------------------------------------------------------------------------------


@dataclass(frozen=True)
class LightDesign:
    prefab: str
    kind: str  # UsdLux type
    nits: float
    size: tuple[float, ...]  # (radius,) or (width, height)
    emission: str  # "isotropic" | "hemi-ies" | "one-sided"
    color: tuple[float, float, float] = (1.0, 1.0, 1.0)
    kelvin: float | None = None
    shadows: str = "static"  # "static" | "dynamic" | "off"

    @property
    def candela(self) -> float:
        """Far-field intensity: sphere I = L*pi*r^2 (before any IES shaping, i.e. the
        mean intensity over the emitting solid angle); rect: on-axis I = L*w*h."""
        if self.kind == "RectLight":
            return self.nits * self.size[0] * self.size[1]
        return sphere_cd(self.nits, self.size[0])

    @property
    def lumens(self) -> float:
        if self.emission == "isotropic":
            return 4 * math.pi * self.candela
        if self.emission == "hemi-ies":
            return 2 * math.pi * self.candela
        return math.pi * self.candela  # one-sided Lambertian emitter

    @property
    def colored_lumens(self) -> float:
        return self.lumens * luminance(self.color)

    def doc(self) -> str:
        s = ", ".join(f"{v:g}" for v in self.size)
        what = {
            "isotropic": "4*pi*I",
            "hemi-ies": "2*pi*I (normalised hemispherical IES)",
            "one-sided": "pi*I (one-sided Lambertian)",
        }[self.emission]
        col = ""
        if self.color != (1.0, 1.0, 1.0):
            col = f"; colour luminance {luminance(self.color):.3f} -> {self.colored_lumens:.0f} lm"
        kel = f", {self.kelvin:g} K" if self.kelvin else ""
        return (
            f"{self.kind} {self.nits:g} nits, size {s} m{kel}: I = {self.candela:.1f} cd, "
            f"Phi = {what} = {self.lumens:.0f} lm (white){col}. Shadows: {self.shadows}."
        )


DESIGNS: dict[str, LightDesign] = {
    d.prefab: d
    for d in (
        # 5000 lm class post-top roadway lantern, 3000 K, Type II IES, cone 90 / soft 0.1.
        LightDesign("street_lamp", "SphereLight", 40000.0, (0.08,), "hemi-ies", kelvin=3000),
        # ~300 lm open flame, 1900 K (candle/torch), isotropic.
        LightDesign("wall_torch", "SphereLight", 3000.0, (0.05,), "isotropic", kelvin=1900),
        # 800 lm narrow (25 deg) recessed downlight, 4000 K.
        LightDesign("ceiling_fixture", "SphereLight", 33000.0, (0.035,), "hemi-ies", kelvin=4000),
        # 1.2 m x 4 cm magenta neon tube, one-sided rect, no shadows.
        LightDesign(
            "neon_strip",
            "RectLight",
            1500.0,
            (1.2, 0.04),
            "one-sided",
            color=(1.0, 0.08, 0.75),
            shadows="off",
        ),
        # ~400 lm (white-equivalent) pink orb, dynamic shadows.
        LightDesign(
            "enemy_orb",
            "SphereLight",
            1000.0,
            (0.1,),
            "isotropic",
            color=(1.0, 0.35, 0.65),
            shadows="dynamic",
        ),
        # 600 lm in-ground uplight, 3000 K, 60 deg beam up.
        LightDesign("ground_uplight", "SphereLight", 34000.0, (0.03,), "hemi-ies", kelvin=3000),
        # 1500 lm asymmetric wall washer, 3500 K.
        LightDesign("wall_washer", "SphereLight", 47500.0, (0.04,), "hemi-ies", kelvin=3500),
    )
}

NEON_COLORS = {
    # name: (light colour, tube diffuse, tube emissive nits)
    "magenta": ((1.0, 0.08, 0.75), (0.85, 0.3, 0.75), (10.0, 0.8, 7.5)),
    "cyan": ((0.05, 0.85, 1.0), (0.3, 0.8, 0.9), (0.5, 8.5, 10.0)),
    "amber": ((1.0, 0.55, 0.08), (0.9, 0.6, 0.3), (10.0, 5.5, 0.8)),
}

PREFAB_HEADER = (
    "stb_hydra prefab '{name}'. Y up, metres. Reference it (ideally instanceable = true)"
    " and place it with translate/rotateY on the referencing prim; the root carries no"
    " transform of its own. Light intensities are UsdLux luminance in nits."
)

# --------------------------------------------------------------------------------------
# Small authoring helpers on top of UsdaWriter
# --------------------------------------------------------------------------------------


def _schemas(*names: str) -> str:
    return f"prepend apiSchemas = {token_array(names)}"


def _light_common(w: UsdaWriter, d: LightDesign, color: bool = True) -> None:
    if color:
        w.attr("color3f inputs:color", vec(d.color, 4))
    if d.kelvin:
        w.attr("float inputs:colorTemperature", num(d.kelvin))
        w.attr("bool inputs:enableColorTemperature", "1")
    w.attr("float inputs:intensity", num(d.nits))
    if d.kind == "RectLight":
        w.attr("float inputs:width", num(d.size[0]))
        w.attr("float inputs:height", num(d.size[1]))
    else:
        w.attr("float inputs:radius", num(d.size[0]))


def _ies_shaping(w: UsdaWriter, ies: str, cone: float, softness: float = 0.0) -> None:
    w.attr("float inputs:shaping:cone:angle", num(cone))
    if softness:
        w.attr("float inputs:shaping:cone:softness", num(softness))
    w.attr("asset inputs:shaping:ies:file", f"@../ies/{ies}.ies@")
    w.attr("bool inputs:shaping:ies:normalize", "1")


def _shadows(w: UsdaWriter, d: LightDesign) -> None:
    w.attr("bool inputs:shadow:enable", "0" if d.shadows == "off" else "1")
    if d.shadows != "off":
        w.attr("uniform token stb:shadow:update", f'"{d.shadows}"')


def _light_schemas(d: LightDesign, shaping: bool) -> list[str]:
    names = (["ShapingAPI"] if shaping else []) + ["ShadowAPI"]
    if d.shadows != "off":
        names.append("StbLightAPI")
    return [_schemas(*names)]


def _looks(w: UsdaWriter, root: str, mats: dict[str, dict]) -> None:
    with w.prim("Scope", "Looks"):
        for name, kw in mats.items():
            w.preview_material(name, f"/{root}/Looks/{name}", **kw)


def _mat(root: str, name: str) -> str:
    return f"/{root}/Looks/{name}"


def _prefab(name: str, root: str, doc: str, body, meta: Sequence[str] = ()) -> str:
    w = UsdaWriter()
    w.header(doc=PREFAB_HEADER.format(name=name) + "\n\n" + doc, default_prim=root)
    with w.prim("Xform", root, meta=['kind = "component"', *meta]):
        body(w)
    return w.text()


# --------------------------------------------------------------------------------------
# Prefabs
# --------------------------------------------------------------------------------------


def street_lamp() -> str:
    d = DESIGNS["street_lamp"]
    root = "StreetLamp"

    def body(w: UsdaWriter) -> None:
        w.comment(
            "Post-top roadway lantern, 5 m. The head hangs off the pole towards +X:\n"
            "+X is the IES 'street side' (H = 0), so rotate the instance about Y to aim it."
        )
        _looks(
            w,
            root,
            {
                "PaintedMetal": dict(diffuse=(0.07, 0.09, 0.08), roughness=0.45, metallic=0.6),
                "Concrete": dict(diffuse=(0.42, 0.41, 0.39), roughness=0.9),
                # Emissive glass: nits, chosen to read as a glowing lens at night exposures
                # (the physical lens luminance, ~40k nits, would just clip to white).
                "Lens": dict(diffuse=(0.8, 0.78, 0.7), roughness=0.2, emissive=(30.0, 22.0, 13.0)),
            },
        )
        with w.prim("Xform", "Geom"):
            w.mesh(
                "Base",
                box_c((0, 0.15, 0), (0.3, 0.3, 0.3), bottom=False),
                material=_mat(root, "Concrete"),
            )
            w.mesh(
                "Pole",
                cylinder(0.06, 0.3, 4.98, sides=12, bottom=False),
                material=_mat(root, "PaintedMetal"),
            )
            w.mesh(
                "Head",
                merge(
                    [
                        box((0.0, 4.9, -0.04), (0.4, 4.97, 0.04)),
                        box((0.3, 4.9, -0.14), (0.9, 5.02, 0.14)),
                    ]
                ),
                material=_mat(root, "PaintedMetal"),
            )
            w.mesh(
                "Lens", box((0.35, 4.885, -0.11), (0.85, 4.9, 0.11)), material=_mat(root, "Lens")
            )
        with w.prim("SphereLight", "Light", meta=_light_schemas(d, shaping=True), doc=d.doc()):
            w.comment(
                "rotateX -90 points the light's -Z (cone and IES axis) down; IES H = 0 stays +X.\n"
                "The sphere (r 8 cm) sits just under the lens: the lamp's own geometry is\n"
                "outside the light's radius, except the head above it (IES emits nothing up)."
            )
            _light_common(w, d)
            _ies_shaping(w, "streetlamp_typeII", cone=90.0, softness=0.1)
            _shadows(w, d)
            w.xform(translate=(0.6, 4.8, 0.0), rotate_xyz=(-90, 0, 0))

    return _prefab("street_lamp", root, "Post-top street lamp, ~5000 lm, Type II IES.", body)


def _flame() -> MeshData:
    """A small double pyramid (8 triangles): 4 cm wide, 8 cm tall, centred on 0."""
    r, top, bot = 0.02, 0.045, -0.035
    ring = [(r * math.cos(a), 0.0, r * math.sin(a)) for a in np.radians([0, 90, 180, 270])]
    faces = []
    for i in range(4):
        a, b = ring[i], ring[(i + 1) % 4]
        faces.append([(0, top, 0), a, b])
        faces.append([(0, bot, 0), a, b])
    return convex_solid(faces)


def wall_torch() -> str:
    d = DESIGNS["wall_torch"]
    root = "WallTorch"

    def body(w: UsdaWriter) -> None:
        w.comment("Wall at z = 0, torch sticks out along +Z. Origin = mounting point.")
        _looks(
            w,
            root,
            {
                "Iron": dict(diffuse=(0.05, 0.05, 0.05), roughness=0.55, metallic=0.8),
                "Wood": dict(diffuse=(0.3, 0.18, 0.09), roughness=0.8),
                "Flame": dict(diffuse=(0.05, 0.02, 0.0), roughness=1.0, emissive=(24.0, 9.0, 1.5)),
            },
        )
        with w.prim("Xform", "Geom"):
            w.mesh(
                "Bracket",
                merge(
                    [
                        box((-0.06, -0.12, 0.0), (0.06, 0.12, 0.02)),
                        box((-0.015, -0.06, 0.02), (0.015, -0.03, 0.2)),
                    ]
                ),
                material=_mat(root, "Iron"),
            )
            w.mesh(
                "Stick",
                cylinder(0.022, -0.28, 0.0, sides=8, center=(0.0, 0.22)),
                material=_mat(root, "Wood"),
            )
            w.mesh(
                "Cup",
                cylinder(0.04, 0.0, 0.035, sides=10, center=(0.0, 0.22), top=False),
                material=_mat(root, "Iron"),
            )
            w.mesh(
                "Flame",
                _flame().transformed(translate=(0.0, 0.09, 0.22)),
                material=_mat(root, "Flame"),
                doc="Emitter stand-in, entirely inside the light's 5 cm radius.",
            )
        with w.prim("SphereLight", "Light", meta=_light_schemas(d, shaping=False), doc=d.doc()):
            _light_common(w, d)
            w.rel("collection:shadowLink:excludes", f"/{root}/Geom/Flame")
            _shadows(w, d)
            w.xform(translate=(0.0, 0.09, 0.22))

    return _prefab("wall_torch", root, "Wall torch, ~300 lm, 1900 K, static shadows.", body)


def ceiling_fixture() -> str:
    d = DESIGNS["ceiling_fixture"]
    root = "CeilingFixture"

    def body(w: UsdaWriter) -> None:
        w.comment("Ceiling at y = 0, the can hangs below it (12 cm).")
        _looks(
            w,
            root,
            {
                "Housing": dict(diffuse=(0.8, 0.8, 0.78), roughness=0.4),
                "Reflector": dict(diffuse=(0.9, 0.9, 0.9), roughness=0.2, metallic=1.0),
                "Lens": dict(diffuse=(0.9, 0.9, 0.9), roughness=0.3, emissive=(20.0, 19.0, 17.0)),
            },
        )
        with w.prim("Xform", "Geom"):
            w.mesh(
                "Trim",
                cylinder(0.1, -0.02, 0.0, sides=16, top=False),
                material=_mat(root, "Housing"),
            )
            w.mesh(
                "Can",
                cylinder(0.07, -0.12, -0.02, sides=16, top=False, bottom=False),
                material=_mat(root, "Housing"),
            )
            w.mesh(
                "Reflector",
                cylinder(0.068, -0.12, -0.02, sides=16, top=False, bottom=False, inside=True),
                material=_mat(root, "Reflector"),
            )
            w.mesh(
                "Lens",
                cylinder(0.05, -0.035, -0.03, sides=16, top=False),
                material=_mat(root, "Lens"),
            )
        with w.prim("SphereLight", "Light", meta=_light_schemas(d, shaping=True), doc=d.doc()):
            w.comment("Axis down (rotateX -90); narrow 25 deg IES, normalised.")
            _light_common(w, d)
            _ies_shaping(w, "downlight_narrow", cone=90.0)
            _shadows(w, d)
            w.xform(translate=(0.0, -0.085, 0.0), rotate_xyz=(-90, 0, 0))

    return _prefab("ceiling_fixture", root, "Recessed-look downlight, 800 lm, 25 deg beam.", body)


def neon_strip() -> str:
    d = DESIGNS["neon_strip"]
    root = "NeonStrip"

    def body(w: UsdaWriter) -> None:
        w.comment(
            "Wall at z = 0, the 1.2 m tube runs along X and faces +Z.\n"
            "variantSet neonColor picks the colour (magenta default, cyan, amber)."
        )
        _looks(
            w,
            root,
            {
                "Rail": dict(diffuse=(0.08, 0.08, 0.08), roughness=0.5, metallic=0.5),
                # Colours come from the neonColor variant: a local opinion here would be
                # stronger than the variant's (LIVRPS) and pin every sign to one colour.
                "Tube": dict(diffuse=None, roughness=0.25),
            },
        )
        with w.prim("Xform", "Geom"):
            w.mesh(
                "Rail", box((-0.62, -0.03, 0.0), (0.62, 0.03, 0.02)), material=_mat(root, "Rail")
            )
            w.mesh("Tube", box((-0.6, -0.02, 0.02), (0.6, 0.02, 0.05)), material=_mat(root, "Tube"))
        with w.prim("RectLight", "Light", meta=_light_schemas(d, shaping=False), doc=d.doc()):
            w.comment(
                "RectLight emits along its -Z: rotateY 180 turns it to face +Z (out).\n"
                "inputs:color is set by the neonColor variant (magenta by default)."
            )
            _light_common(w, d, color=False)
            _shadows(w, d)
            w.xform(translate=(0.0, 0.0, 0.052), rotate_xyz=(0, 180, 0))
        with w.variant_set("neonColor"):
            for name, (light_c, diffuse, emissive) in NEON_COLORS.items():
                with w.variant(name):
                    with w.prim(None, "Light", specifier="over"):
                        w.attr("color3f inputs:color", vec(light_c))
                    with w.prim(None, "Looks", specifier="over"):
                        with w.prim(None, "Tube", specifier="over"):
                            with w.prim(None, "Surface", specifier="over"):
                                w.attr("color3f inputs:diffuseColor", vec(diffuse))
                                w.attr("color3f inputs:emissiveColor", vec(emissive))

    return _prefab(
        "neon_strip",
        root,
        "Neon tube sign, unshadowed RectLight.",
        body,
        meta=[
            'variants = {\n    string neonColor = "magenta"\n}',
            'prepend variantSets = "neonColor"',
        ],
    )


def enemy_orb() -> str:
    d = DESIGNS["enemy_orb"]
    root = "EnemyOrb"

    def body(w: UsdaWriter) -> None:
        w.comment(
            "Origin = orb centre. The shell (r 9 cm) is inside the light's 10 cm radius, so a\n"
            "shadow capture with its near plane at the light radius never sees it; it is\n"
            "also excluded by shadow linking. Marked dynamic: drawn into dynamic maps only."
        )
        _looks(
            w,
            root,
            {
                "Shell": dict(diffuse=(1.0, 0.45, 0.7), roughness=0.3, emissive=(12.0, 4.0, 8.0)),
            },
        )
        with w.prim("Xform", "Geom"):
            w.mesh(
                "Shell",
                sphere(0.09, rings=8, segments=12),
                material=_mat(root, "Shell"),
                api_schemas=["StbGeometryAPI"],
                extra_attrs=[("uniform bool stb:dynamic", "1")],
            )
        with w.prim("SphereLight", "Light", meta=_light_schemas(d, shaping=False), doc=d.doc()):
            _light_common(w, d)
            w.rel("collection:shadowLink:excludes", f"/{root}/Geom/Shell")
            _shadows(w, d)

    return _prefab("enemy_orb", root, "Enemy orb: pink light, dynamic shadow map.", body)


def ground_uplight() -> str:
    d = DESIGNS["ground_uplight"]
    root = "GroundUplight"

    def body(w: UsdaWriter) -> None:
        w.comment("Flush in-ground uplight: ground at y = 0, beam straight up.")
        _looks(
            w,
            root,
            {
                "Steel": dict(diffuse=(0.3, 0.3, 0.3), roughness=0.35, metallic=1.0),
                "Lens": dict(diffuse=(0.9, 0.9, 0.9), roughness=0.2, emissive=(10.0, 8.5, 6.5)),
            },
        )
        with w.prim("Xform", "Geom"):
            w.mesh(
                "Housing",
                box((-0.1, 0.0, -0.1), (0.1, 0.05, 0.1), bottom=False),
                material=_mat(root, "Steel"),
            )
            w.mesh(
                "Lens",
                cylinder(0.05, 0.05, 0.055, sides=16, bottom=False),
                material=_mat(root, "Lens"),
            )
        with w.prim("SphereLight", "Light", meta=_light_schemas(d, shaping=True), doc=d.doc()):
            w.comment(
                "Axis down like every IES light here (IES nadir = light -Z); the profile\n"
                "covers V 90-180, so it shines up. Cone 180 = no cone clipping at all."
            )
            _light_common(w, d)
            _ies_shaping(w, "uplight", cone=180.0)
            _shadows(w, d)
            w.xform(translate=(0.0, 0.09, 0.0), rotate_xyz=(-90, 0, 0))

    return _prefab("ground_uplight", root, "In-ground uplight, 600 lm, 60 deg beam.", body)


def wall_washer() -> str:
    d = DESIGNS["wall_washer"]
    root = "WallWasher"

    def body(w: UsdaWriter) -> None:
        w.comment("Wall at z = 0; the head sits 0.6 m out on an arm and washes the wall below.")
        _looks(
            w,
            root,
            {
                "PaintedMetal": dict(diffuse=(0.1, 0.1, 0.1), roughness=0.45, metallic=0.6),
                "Lens": dict(diffuse=(0.9, 0.9, 0.9), roughness=0.2, emissive=(15.0, 13.0, 10.0)),
            },
        )
        with w.prim("Xform", "Geom"):
            w.mesh(
                "Arm",
                merge(
                    [
                        box((-0.05, -0.05, 0.0), (0.05, 0.05, 0.02)),
                        box((-0.02, -0.02, 0.02), (0.02, 0.02, 0.62)),
                    ]
                ),
                material=_mat(root, "PaintedMetal"),
            )
            w.mesh(
                "Head",
                box((-0.09, -0.04, 0.5), (0.09, 0.03, 0.7)),
                material=_mat(root, "PaintedMetal"),
            )
            w.mesh(
                "Lens", box((-0.07, -0.05, 0.53), (0.07, -0.04, 0.67)), material=_mat(root, "Lens")
            )
        with w.prim("SphereLight", "Light", meta=_light_schemas(d, shaping=True), doc=d.doc()):
            w.comment(
                "rotateXYZ (-90, 90, 0): -Z (IES nadir) points down and +X (IES H = 0, the\n"
                "profile's wall side) points at the wall (-Z of the prefab)."
            )
            _light_common(w, d)
            _ies_shaping(w, "wallwash", cone=90.0)
            _shadows(w, d)
            w.xform(translate=(0.0, -0.1, 0.6), rotate_xyz=(-90, 90, 0))

    return _prefab("wall_washer", root, "Asymmetric wall washer, 1500 lm.", body)


PREFABS = {
    "street_lamp": street_lamp,
    "wall_torch": wall_torch,
    "ceiling_fixture": ceiling_fixture,
    "neon_strip": neon_strip,
    "enemy_orb": enemy_orb,
    "ground_uplight": ground_uplight,
    "wall_washer": wall_washer,
}

# --------------------------------------------------------------------------------------
# Default scene: a courtyard at dusk
# --------------------------------------------------------------------------------------

FRAMES = (1, 48)
FPS = 24.0

#: Camera exposure (stops) comes from this key illuminance. Unshadowed estimates of
#: the design: open ground 25-45 lx, walls 30-75 lx (lamps + torches), arcade
#: downlight pools ~300 lx, moon 3 lx + sky 1.3 lx where no local light reaches.
#: An 18 % card under 25 lx -> 0.18 gives -3 stops (scale 0.125); then cobbles
#: (albedo 0.3) at 30 lx -> 0.36, plaster (0.56) at 40 lx -> 0.9, moonlit plaster
#: -> 0.1, downlight pools -> ~3.6 (rolled off by the ACES tone scale).
DEFAULT_KEY_LUX = 25.0

# Street lamps towards the four corners (angle deg, radius m). Four 5000 lm lamps
# over 400 m^2 already give ~25-50 lx; eight flooded the courtyard (~100 lx) and
# drowned the torches, which is not what a many-light demo wants.
LAMP_RING = [(45.0 + 90.0 * k, 8.5) for k in range(4)]
COLUMNS_Z = (-8.5, -5.1, -1.7, 1.7, 5.1, 8.5)
GATE_X = -5.0  # gate arch in the south wall, off the camera's line of sight
COLUMN_X = 7.4
RUIN = dict(pos=(-5.0, 0.0, -4.0), yaw=25.0, width=2.4, pier=2.2, depth=0.5, thickness=0.4)


def _orb_paths() -> dict[str, np.ndarray]:
    """Closed 48-frame loops (metres), one row per frame 1..48."""
    t = 2 * math.pi * np.arange(FRAMES[1]) / FRAMES[1]
    paths = {}
    # A: circles the fountain, bobbing.
    paths["Orb_Fountain"] = np.stack(
        [3.4 * np.cos(t), 1.7 + 0.35 * np.sin(2 * t), -3.4 * np.sin(t)], -1
    )
    # B: figure-8 (Gerono lemniscate) threading the ruined arch at its crossing point.
    ax, az = 3.2, 1.4  # along the arch normal / along the arch plane
    w_, u_ = ax * np.sin(t), az * np.sin(t) * np.cos(t)
    a = math.radians(RUIN["yaw"])
    normal = np.array([math.sin(a), 0.0, math.cos(a)])  # arch plane is the local XY plane
    along = np.array([math.cos(a), 0.0, -math.sin(a)])
    c = np.array(RUIN["pos"]) + np.array([0.0, 1.5, 0.0])
    paths["Orb_Ruin"] = (
        c
        + w_[:, None] * normal
        + u_[:, None] * along
        + np.stack([np.zeros_like(t), 0.25 * np.sin(3 * t), np.zeros_like(t)], -1)
    )
    # C: ellipse in and out of the arcade, between the columns.
    paths["Orb_Arcade"] = np.stack(
        [7.6 + 1.6 * np.cos(t), 1.8 + 0.2 * np.sin(4 * t), 3.4 * np.sin(t)], -1
    )
    # D: Lissajous loop over the south-west quarter.
    paths["Orb_Gate"] = np.stack(
        [-3.2 + 1.8 * np.sin(t), 1.3 + 0.4 * np.sin(2 * t + 1.0), 7.0 + 1.1 * np.sin(2 * t)], -1
    )
    return paths


STATIC_ORBS = {
    "Orb_Alcove": (8.6, 1.4, -8.0),  # hovering in the arcade's north end
    "Orb_Crates": (-7.2, 2.1, -7.2),  # over the crates in the north-west corner
}


def _obstacles_2d() -> list[tuple[float, float, float]]:
    """(x, z, radius) keep-out circles for the orb paths (poles, columns, fountain)."""
    obs = []
    for ang, r in LAMP_RING:
        a = math.radians(ang)
        obs.append((r * math.cos(a), r * math.sin(a), 0.1))
    obs += [(COLUMN_X, z, 0.3) for z in COLUMNS_Z]
    obs.append((0.0, 0.0, 2.05))
    a = math.radians(RUIN["yaw"])
    along = np.array([math.cos(a), -math.sin(a)])
    half = RUIN["width"] / 2 + RUIN["thickness"] / 2
    for s in (-1, 1):
        x, z = np.array([RUIN["pos"][0], RUIN["pos"][2]]) + s * half * along
        obs.append((float(x), float(z), RUIN["thickness"] / 2 + 0.26))
    return obs


def check_orb_paths(clearance: float = 0.12) -> None:
    """Raise if an orb (r 0.1) flies through a pole, column, pier or the fountain."""
    for name, p in _orb_paths().items():
        for x, z, r in _obstacles_2d():
            dmin = np.hypot(p[:, 0] - x, p[:, 2] - z).min()
            if dmin < r + clearance:
                raise AssertionError(f"{name} passes {dmin:.2f} m from obstacle at ({x}, {z})")
        if np.abs(p[:, [0, 2]]).max() > 9.7:
            raise AssertionError(f"{name} leaves the courtyard")


def _courtyard_geometry() -> dict[str, tuple[MeshData, str, str]]:
    """name -> (mesh, material, doc). A few thousand triangles in all."""
    g: dict[str, tuple[MeshData, str, str]] = {}
    g["Ground"] = (plane(30.0, 30.0), "Cobble", "30 x 30 m ground, the courtyard is 20 x 20 m.")
    # North building with a cornice, a door and a row of windows.
    windows_lit = [
        merge(
            [box((x - 0.4, 4.0, -10.0), (x + 0.4, 5.2, -9.98)) for x in (-10.0, -4.0, 4.0, 10.0)]
        ),
        merge([box((-10.02, 2.6, z - 0.4), (-10.0, 3.8, z + 0.4)) for z in (-8.0, 8.0)]),
    ]
    windows_dark = [
        merge(
            [
                box((x - 0.4, 4.0, -10.0), (x + 0.4, 5.2, -9.98))
                for x in (-8.0, -6.0, -1.2, 1.2, 6.0, 8.0)
            ]
        ),
        merge([box((-10.02, 2.6, z - 0.4), (-10.0, 3.8, z + 0.4)) for z in (0.0, 4.0)]),
    ]
    g["NorthBuilding"] = (
        merge(
            [
                box((-15.0, 0.0, -16.0), (10.0, 6.5, -10.0), bottom=False),
                box((-15.0, 6.2, -10.0), (10.0, 6.5, -9.75)),
            ]
        ),
        "Plaster",
        "Facade at z = -10 (faces +Z), 6.5 m tall.",
    )
    g["NorthDoor"] = (box((-1.0, 0.0, -10.0), (1.0, 2.4, -9.95), bottom=False), "Wood", "")
    g["WestBuilding"] = (
        box((-16.0, 0.0, -10.0), (-10.0, 5.0, 11.0), bottom=False),
        "Brick",
        "Facade at x = -10 (faces +X), 5 m tall.",
    )
    g["WindowsLit"] = (merge(windows_lit), "WindowLit", "Warm lit windows (emissive only).")
    g["WindowsDark"] = (merge(windows_dark), "Glass", "")
    # East: arcade (columns, lintel, roof) in front of a taller building.
    g["EastBuilding"] = (
        box((10.0, 0.0, -16.0), (16.0, 7.0, 11.0), bottom=False),
        "Plaster",
        "Arcade back wall at x = 10 (faces -X), 7 m tall.",
    )
    cols = [
        cylinder(0.25, 0.0, 3.2, sides=16, center=(COLUMN_X, z), top=False, bottom=False)
        for z in COLUMNS_Z
    ]
    caps = [box_c((COLUMN_X, 3.1, z), (0.6, 0.2, 0.6)) for z in COLUMNS_Z]
    g["ArcadeColumns"] = (merge(cols + caps), "Stone", "Six columns, r 0.25 m, x = 7.4.")
    g["ArcadeRoof"] = (
        merge(
            [box((7.05, 3.2, -10.0), (7.75, 3.5, 10.0)), box((7.05, 3.5, -10.0), (10.0, 3.8, 10.0))]
        ),
        "Stone",
        "Lintel + roof slab; its underside (y = 3.5) carries the downlights.",
    )
    # South: low wall with a gate arch.
    g["SouthWall"] = (
        merge(
            [
                box((-10.0, 0.0, 10.0), (GATE_X - 2.2, 1.1, 10.5), bottom=False),
                box((GATE_X + 2.2, 0.0, 10.0), (10.0, 1.1, 10.5), bottom=False),
            ]
        ),
        "Stone",
        "Low wall along z = 10.",
    )
    g["Gate"] = (
        arch(3.2, 2.4, 0.6, 0.5).transformed(translate=(GATE_X, 0.0, 10.25)),
        "Stone",
        "Round-arched gate, 3.2 m opening.",
    )
    # Fountain at the centre.
    g["Fountain"] = (
        merge(
            [
                cylinder(2.0, 0.0, 0.55, sides=24, bottom=False),
                cylinder(0.35, 0.55, 1.6, sides=12, top=False, bottom=False),
                cylinder(0.8, 1.6, 1.8, sides=16),
                sphere(0.2, rings=6, segments=10, center=(0.0, 2.0, 0.0)),
            ]
        ),
        "Stone",
        "Basin r 2 m, pedestal and bowl.",
    )
    g["Water"] = (cylinder(1.85, 0.55, 0.56, sides=24, bottom=False), "Water", "")
    # Ruined arch, crates and barrels: shadow casters.
    r = RUIN
    g["Ruin"] = (
        arch(r["width"], r["pier"], r["depth"], r["thickness"], top_flat=False).transformed(
            translate=r["pos"], yaw_deg=r["yaw"]
        ),
        "Stone",
        "Free-standing ruined arch; Orb_Ruin flies through it.",
    )
    crates = [
        box_c((-8.5, 0.5, -8.4), (1.0, 1.0, 1.0), bottom=False),
        box_c((-7.3, 0.45, -8.7), (0.9, 0.9, 0.9), bottom=False),
        box_c((-8.4, 1.4, -8.4), (0.8, 0.8, 0.8)),
        box_c((-8.7, 0.4, -6.9), (0.8, 0.8, 0.8), bottom=False),
        box_c((4.0, 0.45, 8.3), (0.9, 0.9, 0.9), bottom=False).transformed(yaw_deg=0),
        box_c((5.1, 0.35, 8.6), (0.7, 0.7, 0.7), bottom=False),
        box_c((-6.5, 0.5, 2.0), (1.0, 1.0, 1.0), bottom=False),
    ]
    g["Crates"] = (merge(crates), "Wood", "")
    barrels = [
        cylinder(0.33, 0.0, 0.9, sides=12, center=c, bottom=False)
        for c in ((-6.4, -8.8), (3.0, 8.9), (-6.3, 3.3))
    ]
    g["Barrels"] = (merge(barrels), "DarkWood", "")
    return g


MATERIALS = {
    "Cobble": dict(diffuse=(0.3, 0.28, 0.26), roughness=0.85),
    "Plaster": dict(diffuse=(0.62, 0.56, 0.48), roughness=0.9),
    "Brick": dict(diffuse=(0.42, 0.2, 0.14), roughness=0.85),
    "Stone": dict(diffuse=(0.5, 0.48, 0.44), roughness=0.75),
    "Wood": dict(diffuse=(0.36, 0.23, 0.13), roughness=0.7),
    "DarkWood": dict(diffuse=(0.2, 0.12, 0.07), roughness=0.6),
    "Water": dict(diffuse=(0.03, 0.05, 0.06), roughness=0.05),
    "Glass": dict(diffuse=(0.04, 0.05, 0.06), roughness=0.1, metallic=0.0),
    # Lit windows: emissive nits, ~0.75 scene-linear after the camera's 0.125 scale.
    "WindowLit": dict(diffuse=(0.1, 0.08, 0.05), roughness=0.3, emissive=(6.0, 3.8, 1.8)),
}


def _instance(
    w: UsdaWriter,
    name: str,
    prefab: str,
    pos,
    yaw: float = 0.0,
    instanceable: bool = True,
    variant: tuple[str, str] | None = None,
    body=None,
):
    meta = [
        f"instanceable = {'true' if instanceable else 'false'}",
        f"prepend references = @./prefabs/{prefab}.usda@",
    ]
    if variant:
        meta.append(f'variants = {{\n    string {variant[0]} = "{variant[1]}"\n}}')
    with w.prim("Xform", name, meta=meta):
        if body:
            body(w)
        w.xform(translate=pos, rotate_xyz=(0, yaw, 0) if yaw else None, nd=3)


# Placement tables (metres, degrees of yaw about +Y). Prefab +Z faces out of walls.
TORCHES = (
    [(f"North_{i + 1}", (x, 2.4, -10.0), 0.0) for i, x in enumerate((-8.0, -4.0, 4.0, 8.0))]
    + [(f"West_{i + 1}", (-10.0, 2.4, z), 90.0) for i, z in enumerate((-6.0, -2.0, 2.0, 6.0))]
    + [(f"Arcade_{i + 1}", (10.0, 2.2, z), -90.0) for i, z in enumerate((-6.8, 6.8))]
)
FLICKER_TORCHES = (
    ("Gate_W", (GATE_X - 1.85, 2.0, 9.95), 180.0),
    ("Gate_E", (GATE_X + 1.85, 2.0, 9.95), 180.0),
)
DOWNLIGHTS_Z = (-7.5, -4.5, -1.5, 1.5, 4.5, 7.5)
UPLIGHTS_Z = COLUMNS_Z
WASHERS_X = (-2.6, 2.6)
NEONS = (
    ("West_Magenta", (-10.0, 3.3, -4.0), 90.0, "magenta"),
    ("West_Cyan", (-10.0, 3.3, 4.0), 90.0, "cyan"),
    ("North_Amber", (0.0, 2.9, -10.0), 0.0, "amber"),
    ("Arcade_Cyan", (10.0, 2.9, 0.0), -90.0, "cyan"),
)


def inventory() -> dict[str, int]:
    """Local light counts by prefab (what default.usda holds)."""
    return {
        "street_lamp": len(LAMP_RING),
        "wall_torch": len(TORCHES) + len(FLICKER_TORCHES),
        "ceiling_fixture": len(DOWNLIGHTS_Z),
        "ground_uplight": len(UPLIGHTS_Z),
        "wall_washer": len(WASHERS_X),
        "neon_strip": len(NEONS),
        "enemy_orb": len(_orb_paths()) + len(STATIC_ORBS),
    }


def default_scene() -> str:
    check_orb_paths()
    inv = inventory()
    key_exposure = exposure_for_illuminance(DEFAULT_KEY_LUX)
    w = UsdaWriter()
    w.header(
        doc=(
            f"stb_hydra default scene: a 20 x 20 m courtyard at dusk lit by "
            f"{sum(inv.values())} local lights\n("
            + ", ".join(f"{n} {k}" for k, n in inv.items())
            + ")\nplus a low moon (DistantLight, 3 lx) and a dim blue sky (DomeLight, 1 nit).\n"
            "Local lights are references to usd_scenes/prefabs, instanceable except the\n"
            f"two flickering gate torches. Animated (frames {FRAMES[0]}-{FRAMES[1]} at "
            f"{FPS:g} fps, a loop): {len(_orb_paths())} orbs fly closed paths\n"
            "(time-sampled translate), 2 torches flicker (time-sampled intensity).\n"
            f"Camera exposure {key_exposure:g} stops (see /Camera).\n"
            "Written by tools/gen_prefab_library.py - edit that, not this file."
        ),
        default_prim="World",
        start=FRAMES[0],
        end=FRAMES[1],
        fps=FPS,
    )
    with w.prim("Xform", "World", meta=['kind = "assembly"']):
        with w.prim("Scope", "Looks"):
            for name, kw in MATERIALS.items():
                w.preview_material(name, f"/World/Looks/{name}", **kw)
        with w.prim("Xform", "Geometry", doc="Static geometry, a few thousand triangles."):
            for name, (mesh, mat, doc) in _courtyard_geometry().items():
                w.mesh(name, mesh, material=f"/World/Looks/{mat}", doc=doc or None, nd=3)
        with w.prim("Xform", "Lights"):
            _sky_lights(w)
            _local_lights(w)
    w.camera(
        "Camera",
        eye=CAMERA_EYE,
        target=CAMERA_TARGET,
        focal_length=CAMERA_FOCAL_MM,
        clipping=(0.1, 200.0),
        exposure=key_exposure,
        doc="Raised view from beyond the south wall, 20 mm lens, 36 x 20.25 mm (16:9) aperture.",
        comment=(
            f"exposure {key_exposure:g} stops -> ComputeLinearExposureScale() = "
            f"{2**key_exposure:g} (fStop 1, time 1 s, iso 100, responsivity 1).\n"
            f"Chosen so an 18 % grey card under ~{DEFAULT_KEY_LUX:g} lx -> 0.18 scene-linear:\n"
            "lamp- and torch-lit surfaces here (25-75 lx) land at ~0.3-1.0, moonlit ones ~0.1."
        ),
    )
    return w.text()


CAMERA_EYE = (3.5, 8.0, 17.5)
CAMERA_TARGET = (-1.5, 1.0, -3.0)
CAMERA_FOCAL_MM = 20.0


def _sky_lights(w: UsdaWriter) -> None:
    with w.prim("Xform", "Sky"):
        with w.prim(
            "DistantLight",
            "Moon",
            meta=[_schemas("ShadowAPI")],
            doc="Low moon / last dusk light: 3 lux on a surface facing it, 9000 K, "
            "from the south-south-east at 18 deg elevation.",
        ):
            w.comment("normalize = 1: intensity is the illuminance (lux) of a facing surface.")
            w.attr("float inputs:angle", "0.53")
            w.attr("float inputs:colorTemperature", "9000")
            w.attr("bool inputs:enableColorTemperature", "1")
            w.attr("float inputs:intensity", "3")
            w.attr("bool inputs:normalize", "1")
            w.attr("bool inputs:shadow:enable", "1")
            w.xform(rotate_xyz=(-18, 20, 0))
        sky = (0.3, 0.42, 0.75)
        with w.prim(
            "DomeLight",
            "SkyDome",
            doc=f"Uniform dusk sky, no texture: radiance 1 nit x colour "
            f"(luminance {luminance(sky):.2f} nits), ~1.3 lx on open ground.",
        ):
            w.attr("color3f inputs:color", vec(sky))
            w.attr("float inputs:intensity", "1")


def _local_lights(w: UsdaWriter) -> None:
    with w.prim("Xform", "StreetLamps", doc="street_lamp x 4 towards the corners, heads inward."):
        for k, (ang, r) in enumerate(LAMP_RING):
            a = math.radians(ang)
            x, z = r * math.cos(a), r * math.sin(a)
            yaw = math.degrees(math.atan2(z, -x))  # prefab +X (street side) -> centre
            _instance(w, f"Lamp_{k + 1:02d}", "street_lamp", (x, 0.0, z), round(yaw, 2))

    with w.prim(
        "Xform",
        "Torches",
        doc="wall_torch at ~2.4 m; the two gate torches flicker "
        "(not instanceable: their light's intensity is overridden with time samples).",
    ):
        for name, pos, yaw in TORCHES:
            _instance(w, name, "wall_torch", pos, yaw)
        rng = np.random.default_rng(1900)
        base = DESIGNS["wall_torch"].nits
        for name, pos, yaw in FLICKER_TORCHES:
            noise = rng.uniform(-1.0, 1.0, FRAMES[1])
            flicker = base * (1.0 + 0.22 * (0.6 * noise + 0.4 * np.roll(noise, 1)))
            samples = [(f, num(v, 0)) for f, v in zip(range(FRAMES[0], FRAMES[1] + 1), flicker)]

            def body(w: UsdaWriter, samples=samples) -> None:
                with w.prim(None, "Light", specifier="over"):
                    w.comment(f"Flicker: +-22 % around {base:g} nits, one value per frame.")
                    w.time_samples("float inputs:intensity", samples)

            _instance(w, name, "wall_torch", pos, yaw, instanceable=False, body=body)

    with w.prim("Xform", "ArcadeDownlights", doc="ceiling_fixture under the arcade roof."):
        for i, z in enumerate(DOWNLIGHTS_Z):
            _instance(w, f"Downlight_{i + 1}", "ceiling_fixture", (8.6, 3.5, z))

    with w.prim("Xform", "ColumnUplights", doc="ground_uplight in front of each column."):
        for i, z in enumerate(UPLIGHTS_Z):
            _instance(w, f"Uplight_{i + 1}", "ground_uplight", (COLUMN_X - 0.55, 0.0, z))

    with w.prim("Xform", "WallWashers", doc="wall_washer on the north facade."):
        for i, x in enumerate(WASHERS_X):
            _instance(w, f"Washer_{i + 1}", "wall_washer", (x, 6.0, -10.0))

    with w.prim("Xform", "NeonSigns", doc="neon_strip, colour picked by variant, no shadows."):
        for name, pos, yaw, color in NEONS:
            _instance(w, name, "neon_strip", pos, yaw, variant=("neonColor", color))

    with w.prim("Xform", "Orbs", doc="enemy_orb (dynamic shadows); the first ones fly loops."):
        for name, path in _orb_paths().items():
            samples = [(f, vec(p, 3)) for f, p in zip(range(FRAMES[0], FRAMES[1] + 1), path)]
            meta = ["instanceable = true", "prepend references = @./prefabs/enemy_orb.usda@"]
            with w.prim("Xform", name, meta=meta):
                w.time_samples("double3 xformOp:translate", samples)
                w.attr("uniform token[] xformOpOrder", '["xformOp:translate"]')
        for name, pos in STATIC_ORBS.items():
            _instance(w, name, "enemy_orb", pos)


# --------------------------------------------------------------------------------------
# CLI
# --------------------------------------------------------------------------------------


def outputs() -> dict[Path, str]:
    files = {PREFAB_DIR / f"{name}.usda": fn() for name, fn in PREFABS.items()}
    files[USD_SCENES / "default.usda"] = default_scene()
    return files


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument(
        "--check",
        action="store_true",
        help="write nothing; exit 1 if a checked-in file differs from the generator",
    )
    args = ap.parse_args(argv)
    stale = []
    for path, text in outputs().items():
        if args.check:
            if not path.is_file() or path.read_text(encoding="utf-8") != text:
                stale.append(path)
            continue
        write_text_atomic(path, text)
        print(f"wrote {path.relative_to(USD_SCENES.parent)} ({len(text.encode())} bytes)")
    for p in stale:
        print(f"stale: {p}", file=sys.stderr)
    if not args.check:
        for d in DESIGNS.values():
            print(f"  {d.prefab:16s} {d.doc()}")
    return 1 if stale else 0


if __name__ == "__main__":
    sys.exit(main())
