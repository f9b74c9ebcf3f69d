"""Small area-light test stages (issue 20): a Lambertian floor, one box, one UsdLux
light, seen at an angle from 3.2 m. Shared by tests/test_area_lights.py and
tools/area_light_figures.py; Mitsuba renders them through tests/mitsuba_ref.py."""

from __future__ import annotations

from pxr import Usd
from stagegen import usda_stage

#: name -> light prim text (positions in metres; the box stands at (0.7, 0, 0.3)).
LIGHTS: dict[str, str] = {
    # 1 m x 0.5 m rect 0.6 m above the floor, facing down (-Z -> -Y).
    "rect": (
        'def RectLight "L" {\n    float inputs:intensity = 20000\n'
        "    float inputs:width = 1\n    float inputs:height = 0.5\n"
        "    double3 xformOp:translate = (0, 0.6, 0)\n    float xformOp:rotateX = -90\n"
        '    uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateX"]\n}\n'
    ),
    # 0.3 m radius disk 0.5 m up, tilted 30 degrees.
    "disk": (
        'def DiskLight "L" {\n    float inputs:intensity = 30000\n    float inputs:radius = 0.3\n'
        "    double3 xformOp:translate = (-0.2, 0.5, 0)\n"
        "    float3 xformOp:rotateXYZ = (-90, 0, 30)\n"
        '    uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateXYZ"]\n}\n'
    ),
    # 0.5 m radius sphere whose centre is 0.3 m above the floor: the floor's plane cuts it.
    "sphere": (
        'def SphereLight "L" {\n    float inputs:intensity = 8000\n    float inputs:radius = 0.5\n'
        "    double3 xformOp:translate = (-0.6, 0.3, -0.4)\n"
        '    uniform token[] xformOpOrder = ["xformOp:translate"]\n}\n'
    ),
    # 1.2 m long, 0.1 m radius tube 0.5 m up, along X rotated 20 degrees about Y.
    "cylinder": (
        'def CylinderLight "L" {\n    float inputs:intensity = 20000\n'
        "    float inputs:radius = 0.1\n"
        "    float inputs:length = 1.2\n"
        "    double3 xformOp:translate = (-0.3, 0.5, 0)\n    float xformOp:rotateY = 20\n"
        '    uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateY"]\n}\n'
    ),
    # Point and hard-edged spot lights (treatAsPoint): the point model stays exact.
    "point": (
        'def SphereLight "L" {\n    float inputs:intensity = 400000\n'
        "    float inputs:radius = 0.05\n"
        "    bool treatAsPoint = 1\n    double3 xformOp:translate = (-0.3, 1.2, 0)\n"
        '    uniform token[] xformOpOrder = ["xformOp:translate"]\n}\n'
    ),
    "spot": (
        'def SphereLight "L" (\n    prepend apiSchemas = ["ShapingAPI"]\n) {\n'
        "    float inputs:intensity = 400000\n    float inputs:radius = 0.05\n"
        "    bool treatAsPoint = 1\n    float inputs:shaping:cone:angle = 35\n"
        "    double3 xformOp:translate = (-0.3, 1.5, 0)\n    float xformOp:rotateX = -90\n"
        '    uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateX"]\n}\n'
    ),
}

SCENE_USDA = """#usda 1.0
(
    metersPerUnit = 1
    upAxis = "Y"
)
def Camera "Cam"
{{
    float focalLength = 18
    float horizontalAperture = 36
    float verticalAperture = 20.25
    float2 clippingRange = (0.05, 100)
    double3 xformOp:translate = (0, 2.4, 2.2)
    float xformOp:rotateX = -45
    uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateX"]
}}
def Mesh "Ground" (
    prepend apiSchemas = ["MaterialBindingAPI"]
)
{{
    int[] faceVertexCounts = [4]
    int[] faceVertexIndices = [0, 1, 2, 3]
    point3f[] points = [(-6, 0, -6), (-6, 0, 6), (6, 0, 6), (6, 0, -6)]
    rel material:binding = </Looks/Grey>
}}
def Cube "Box" (
    prepend apiSchemas = ["MaterialBindingAPI"]
)
{{
    double size = 0.4
    double3 xformOp:translate = (0.7, 0.2, 0.3)
    uniform token[] xformOpOrder = ["xformOp:translate"]
    rel material:binding = </Looks/Grey>
}}
def Scope "Looks"
{{
    def Material "Grey"
    {{
        token outputs:surface.connect = </Looks/Grey/PBR.outputs:surface>
        def Shader "PBR"
        {{
            uniform token info:id = "UsdPreviewSurface"
            color3f inputs:diffuseColor = (0.5, 0.5, 0.5)
            int inputs:useSpecularWorkflow = 1
            color3f inputs:specularColor = (0, 0, 0)
            float inputs:roughness = 1
            token outputs:surface
        }}
    }}
}}
{light}
"""


def area_stage(kind: str) -> Usd.Stage:
    """The floor + box stage lit by ``LIGHTS[kind]``."""
    return usda_stage(SCENE_USDA.format(light=LIGHTS[kind]))


def area_stage_no_box(kind: str) -> Usd.Stage:
    """``area_stage`` without the box: unshadowed area shading only."""
    text = SCENE_USDA.format(light=LIGHTS[kind])
    a = text.index('def Cube "Box"')
    b = text.index('def Scope "Looks"')
    return usda_stage(text[:a] + text[b:])


def glossy_stage(kind: str, roughness: float, light: str | None = None) -> Usd.Stage:
    """``area_stage_no_box`` with a pure GGX mirror-metal floor instead of the Lambert one
    (diffuse 0, specular colour 1: Schlick's Fresnel is exactly 1, what Mitsuba's
    ``roughconductor`` with ``material = none`` does), roughness ``roughness``
    (alpha = roughness^2). The light's diffuse multiplier plays no part; ``light``: prim
    text instead of ``LIGHTS[kind]``."""
    text = SCENE_USDA.format(light=light or LIGHTS[kind])
    a = text.index('def Cube "Box"')
    b = text.index('def Scope "Looks"')
    text = text[:a] + text[b:]
    text = text.replace(
        "color3f inputs:diffuseColor = (0.5, 0.5, 0.5)", "color3f inputs:diffuseColor = (0, 0, 0)"
    )
    text = text.replace(
        "color3f inputs:specularColor = (0, 0, 0)", "color3f inputs:specularColor = (1, 1, 1)"
    )
    text = text.replace("float inputs:roughness = 1", f"float inputs:roughness = {roughness}")
    return usda_stage(text)


def many_area_lights_stage(n: int = 24, seed: int = 3) -> Usd.Stage:
    """``n`` lights cycling through rect, disk, sphere and cylinder (0.1-0.5 m), 0.3-1 m
    above the floor of ``SCENE_USDA`` around its box: STB's unbiasedness on area lights."""
    import numpy as np

    rng = np.random.default_rng(seed)
    parts = []
    for i in range(n):
        x, z = rng.uniform(-1.6, 1.6, 2)
        y = rng.uniform(0.3, 1.0)
        s = rng.uniform(0.1, 0.5)
        e = rng.uniform(2000, 20000)
        xf = (
            f"    double3 xformOp:translate = ({x:.3f}, {y:.3f}, {z:.3f})\n"
            f"    float3 xformOp:rotateXYZ = (-90, 0, {rng.uniform(0, 180):.1f})\n"
            '    uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateXYZ"]\n'
        )
        t = ("RectLight", "DiskLight", "SphereLight", "CylinderLight")[i % 4]
        size = {
            "RectLight": f"    float inputs:width = {s:.3f}\n"
            f"    float inputs:height = {s / 2:.3f}\n",
            "DiskLight": f"    float inputs:radius = {s / 2:.3f}\n",
            "SphereLight": f"    float inputs:radius = {s / 3:.3f}\n",
            "CylinderLight": f"    float inputs:radius = {s / 8:.3f}\n"
            f"    float inputs:length = {s:.3f}\n",
        }[t]
        parts.append(f'def {t} "L{i}" {{\n    float inputs:intensity = {e:.1f}\n{size}{xf}}}\n')
    return usda_stage(SCENE_USDA.format(light="".join(parts)))
