"""Small in-memory stages authored by the tests (Sdf API: fast in bulk)."""

from __future__ import annotations

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom

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


# --- inline .usda pieces shared by the GL tests ------------------------------------------

USDA_HEADER = """#usda 1.0
(
    metersPerUnit = 1
    upAxis = "Y"
)
"""


def usda_header(start: float, end: float) -> str:
    """``USDA_HEADER`` with a start and end time code."""
    return (
        '#usda 1.0\n(\n    metersPerUnit = 1\n    upAxis = "Y"\n'
        f"    startTimeCode = {start:g}\n    endTimeCode = {end:g}\n)\n"
    )


def camera_usda(
    translate: tuple[float, float, float],
    rotate_x: float,
    *,
    clipping: tuple[float, float] | None = None,
    ortho: bool = False,
) -> str:
    """``/Cam``: 18 mm lens on a 36 x 20.25 mm aperture (16:9), or an orthographic
    200 x 112.5 view; placed at ``translate`` and pitched by ``rotate_x`` degrees."""
    lens = (
        '    token projection = "orthographic"\n'
        "    float horizontalAperture = 200\n    float verticalAperture = 112.5\n"
        if ortho
        else "    float focalLength = 18\n"
        "    float horizontalAperture = 36\n    float verticalAperture = 20.25\n"
    )
    clip = f"    float2 clippingRange = ({clipping[0]:g}, {clipping[1]:g})\n" if clipping else ""
    x, y, z = translate
    return (
        'def Camera "Cam"\n{\n'
        + lens
        + clip
        + f"    double3 xformOp:translate = ({x:g}, {y:g}, {z:g})\n"
        f"    float xformOp:rotateX = {rotate_x:g}\n"
        '    uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateX"]\n}\n'
    )


def ground_usda(half: float = 20.0) -> str:
    """``/Ground``: a grey 2*half metre square quad at y = 0."""
    h = f"{half:g}"
    return (
        'def Mesh "Ground"\n{\n'
        "    int[] faceVertexCounts = [4]\n    int[] faceVertexIndices = [0, 1, 2, 3]\n"
        f"    point3f[] points = [(-{h}, 0, -{h}), (-{h}, 0, {h}), ({h}, 0, {h}), ({h}, 0, -{h})]\n"
        "    color3f[] primvars:displayColor = [(0.5, 0.5, 0.5)]\n}\n"
    )


BOX_USDA = (
    'def Cube "Box"\n{\n    double size = 2\n    double3 xformOp:translate = (0, 1, 0)\n'
    '    uniform token[] xformOpOrder = ["xformOp:translate"]\n}\n'
)
"""``/Box``: a 2 m cube standing on the ground at the origin."""


def plane_points(
    stage: Usd.Stage,
    width: int,
    height: int,
    *,
    camera: str = "/Cam",
    time: float | None = None,
) -> np.ndarray:
    """(height, width, 3) world point on the plane y = 0 seen through each pixel centre,
    top row first -- from USD's own camera (``Gf.Frustum.ComputePickRay``), never the
    renderer's projection code."""
    tc = Usd.TimeCode.Default() if time is None else Usd.TimeCode(time)
    fr = UsdGeom.Camera(stage.GetPrimAtPath(camera)).GetCamera(tc).frustum
    pts = np.zeros((height, width, 3))
    for j in range(height):
        for i in range(width):
            ray = fr.ComputePickRay(Gf.Vec2d(2 * (i + 0.5) / width - 1, 1 - 2 * (j + 0.5) / height))
            o, d = np.array(ray.startPoint), np.array(ray.direction)
            pts[j, i] = o - o[1] / d[1] * d
    return pts


#: A Lambertian floor (UsdPreviewSurface, diffuse ``{rho}``, roughness 1) seen straight
#: down from 4 m, plus ``{light}``; ``str.format`` it (braces of the text are doubled).
LAMBERT_FLOOR_USDA = """#usda 1.0
(
    metersPerUnit = 1
    upAxis = "Y"
)
def Camera "Cam"
{{
    float focalLength = 18
    float horizontalAperture = 36
    float verticalAperture = 20.25
    float2 clippingRange = (0.1, 100)
    double3 xformOp:translate = (0, 4, 0)
    float xformOp:rotateX = -90
    uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateX"]
}}
def Mesh "Ground" (
    prepend apiSchemas = ["MaterialBindingAPI"]
)
{{
    int[] faceVertexCounts = [4]
    int[] faceVertexIndices = [0, 1, 2, 3]
    point3f[] points = [(-20, 0, -20), (-20, 0, 20), (20, 0, 20), (20, 0, -20)]
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
            color3f inputs:diffuseColor = ({rho}, {rho}, {rho})
            float inputs:roughness = 1
            token outputs:surface
        }}
    }}
}}
{light}
"""


def bake_yard_usda(
    boxes: int = 24, lights: int = 64, half: float = 20.0, seed: int = 35, mpu: float = 1.0
) -> str:
    """Issue 35's bake scene: a ``2 half`` metre square ground quad (one Mesh, grey,
    roughness 0.8), ``boxes`` ``UsdGeom.Cube`` prims (0.8-2.4 m, on a jittered grid)
    and ``lights`` shadowed sphere lights (r = 0.1 m, 0.6-3 m up), every light
    ``stb:mobility = "static"``; a camera at 14 m looking 32 degrees down over it.
    ``mpu``: the layer's metersPerUnit (lengths are authored in units of it, so the
    scene is the same in metres)."""
    rng = np.random.default_rng(seed)
    u = 1.0 / mpu  # units per metre
    h = half * u
    out = [
        f'#usda 1.0\n(\n    metersPerUnit = {mpu:g}\n    upAxis = "Y"\n)\n',
        'def Camera "Cam"\n{\n    float focalLength = 18\n    float horizontalAperture = 36\n'
        "    float verticalAperture = 20.25\n"
        f"    float2 clippingRange = ({0.1 * u:g}, {200 * u:g})\n"
        f"    double3 xformOp:translate = (0, {14 * u:g}, {half * 1.25 * u:g})\n"
        "    float xformOp:rotateX = -32\n"
        '    uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateX"]\n}\n',
        'def Mesh "Ground" (\n    prepend apiSchemas = ["MaterialBindingAPI"]\n)\n{\n'
        "    int[] faceVertexCounts = [4]\n    int[] faceVertexIndices = [0, 1, 2, 3]\n"
        f"    point3f[] points = [(-{h:g}, 0, -{h:g}), (-{h:g}, 0, {h:g}), ({h:g}, 0, {h:g}), "
        f"({h:g}, 0, -{h:g})]\n    rel material:binding = </Looks/Grey>\n}}\n",
        'def Scope "Looks"\n{\n    def Material "Grey"\n    {\n'
        "        token outputs:surface.connect = </Looks/Grey/PBR.outputs:surface>\n"
        '        def Shader "PBR"\n        {\n'
        '            uniform token info:id = "UsdPreviewSurface"\n'
        "            color3f inputs:diffuseColor = (0.5, 0.5, 0.5)\n"
        "            float inputs:roughness = 0.8\n            token outputs:surface\n"
        "        }\n    }\n}\n",
        'def Xform "Boxes"\n{\n',
    ]
    cols = int(np.ceil(np.sqrt(boxes * 1.5)))
    rows = int(np.ceil(boxes / cols))
    for i in range(boxes):
        gx = (i % cols + 0.5) / cols * 2 - 1
        gz = (i // cols + 0.5) / rows * 2 - 1
        s = float(rng.uniform(0.8, 2.4))
        x = (gx * 0.8 + rng.uniform(-0.05, 0.05)) * half
        z = (gz * 0.8 + rng.uniform(-0.05, 0.05)) * half
        ry = float(rng.uniform(0, 90))
        out.append(
            f'    def Cube "Box{i:02d}" (\n        prepend apiSchemas = ["MaterialBindingAPI"]\n'
            f"    )\n    {{\n        double size = {s * u:.6g}\n"
            "        rel material:binding = </Looks/Grey>\n"
            f"        double3 xformOp:translate = ({x * u:.6g}, {s / 2 * u:.6g}, {z * u:.6g})\n"
            f"        float xformOp:rotateY = {ry:.4g}\n"
            '        uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateY"]\n'
            "    }\n"
        )
    out.append('}\ndef Xform "Lights"\n{\n')
    for i in range(lights):
        x, z = rng.uniform(-0.9, 0.9, 2) * half
        y = float(rng.uniform(0.6, 3.0))
        c = rng.uniform(0.6, 1.0, 3)
        nits = float(rng.uniform(4e2, 1.6e3))
        out.append(
            f'    def SphereLight "L{i:02d}" (\n        prepend apiSchemas = ["StbLightAPI"]\n'
            f"    )\n    {{\n        float inputs:intensity = {nits:.6g}\n"
            f"        color3f inputs:color = ({c[0]:.3f}, {c[1]:.3f}, {c[2]:.3f})\n"
            f"        float inputs:radius = {0.1 * u:g}\n"
            '        uniform token stb:mobility = "static"\n'
            f"        double3 xformOp:translate = ({x * u:.6g}, {y * u:.6g}, {z * u:.6g})\n"
            '        uniform token[] xformOpOrder = ["xformOp:translate"]\n    }\n'
        )
    out.append("}\n")
    return "".join(out)
