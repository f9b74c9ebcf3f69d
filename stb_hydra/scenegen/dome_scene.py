"""A floor, two boxes and a sun-and-sky DomeLight (issue 37): the scene of
tests/test_dome.py's Mitsuba comparison and tools/bench_dome.py's timings.

``sun_and_sky`` is the HDRI (a lat-long map, OpenEXR convention); ``boxes_usda`` the
stage text naming it (Lambert albedo 0.5 everywhere, which Mitsuba converts too).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..scene.dome import latlong_directions

#: Floor + boxes, Lambert albedo 0.5, seen at an angle (Mitsuba converts all of it).
BOXES_USDA = """#usda 1.0
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
    double3 xformOp:translate = (0, 1.5, 2.2)
    float xformOp:rotateX = -32
    uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateX"]
}}
def Mesh "Ground" (
    prepend apiSchemas = ["MaterialBindingAPI"]
)
{{
    int[] faceVertexCounts = [4]
    int[] faceVertexIndices = [0, 1, 2, 3]
    point3f[] points = [(-3, 0, -3), (-3, 0, 3), (3, 0, 3), (3, 0, -3)]
    rel material:binding = </Looks/Grey>
}}
def Cube "Box" (
    prepend apiSchemas = ["MaterialBindingAPI"]
)
{{
    double size = 0.5
    double3 xformOp:translate = (0.5, 0.25, 0.2)
    uniform token[] xformOpOrder = ["xformOp:translate"]
    rel material:binding = </Looks/Grey>
}}
def Cube "Tall" (
    prepend apiSchemas = ["MaterialBindingAPI"]
)
{{
    double size = 0.3
    double3 xformOp:translate = (-0.4, 0.45, -0.3)
    double3 xformOp:scale = (1, 3, 1)
    uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:scale"]
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
def DomeLight "Sky"
{{
    asset inputs:texture:file = @{tex}@
    token inputs:texture:format = "latlong"
    float inputs:intensity = {intensity}
}}
"""


def sun_and_sky(h: int = 256, w: int = 512) -> np.ndarray:
    """A dim sky (brighter towards the zenith, dark ground) and a 3-degree-radius sun
    disc of radiance 1500 at 35 degrees elevation, from the front-left."""
    d = latlong_directions(h, w)
    y = d[..., 1]
    sky = np.where(y > 0, 0.3 + 0.7 * y, 0.05)
    el, az = math.radians(35.0), math.radians(35.0)
    sun = np.array([math.cos(el) * math.sin(-az), math.sin(el), math.cos(el) * math.cos(-az)])
    disc = (d @ sun) > math.cos(math.radians(3.0))
    img = np.where(disc, 1500.0, sky)
    rgb = np.repeat(img[..., None], 3, axis=2).astype(np.float32)
    rgb[..., 2] *= np.where(disc, 1.0, 1.15)  # a bluish sky (colour must survive too)
    return rgb


def write_scene(folder: Path, intensity: float = 0.5) -> Path:
    """Write ``sunsky.exr`` and ``boxes_dome.usda`` into ``folder``; returns the stage."""
    import OpenImageIO as oiio

    folder.mkdir(parents=True, exist_ok=True)
    img = sun_and_sky()
    tex = folder / "sunsky.exr"
    out = oiio.ImageOutput.create(str(tex))
    out.open(str(tex), oiio.ImageSpec(img.shape[1], img.shape[0], 3, oiio.FLOAT))
    out.write_image(img)
    out.close()
    path = folder / "boxes_dome.usda"
    path.write_text(BOXES_USDA.format(tex=tex.name, intensity=intensity))
    return path
