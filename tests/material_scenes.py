"""Textured-material stages written to disk for the material tests (texture files are
resolved against the layer, so the layer and its images live in one folder).

The standard set-up: a unit quad in the XY plane (0..1 x 0..1, normal +Z) with
``st = (x, y)``, seen straight on by an orthographic camera that frames exactly the
quad, so pixel (row r, column c) of a W x H image (top row first) sees
``st = ((c + 0.5) / W, 1 - (r + 0.5) / H)`` (times the st extent for ``st_scale``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import OpenImageIO as oiio

HEADER = '#usda 1.0\n(\n    metersPerUnit = 1\n    upAxis = "Y"\n)\n'


def write_image(path: Path, pixels: np.ndarray) -> Path:
    """Write (h, w, c) pixels (top row first; uint8, uint16 or float32) with OIIO."""
    px = np.ascontiguousarray(pixels)
    if px.ndim == 2:
        px = px[:, :, None]
    h, w, c = px.shape
    fmt = {np.dtype(np.uint8): "uint8", np.dtype(np.uint16): "uint16"}.get(px.dtype, "float")
    out = oiio.ImageOutput.create(str(path))
    assert out is not None, oiio.geterror()
    assert out.open(str(path), oiio.ImageSpec(w, h, c, fmt)), out.geterror()
    assert out.write_image(px), out.geterror()
    out.close()
    return path


def cells(n: int, cell: int, channels: int = 3, seed: int = 1) -> np.ndarray:
    """(n*cell, n*cell, channels) uint8 image of n x n constant cells (random values):
    bilinear filtering returns each cell's value exactly away from its edges."""
    rng = np.random.default_rng(seed)
    v = rng.integers(8, 248, (n, n, channels), dtype=np.uint8)
    return np.repeat(np.repeat(v, cell, 0), cell, 1)


def srgb_to_linear(v: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1, written out here (not imported from the code under test)."""
    v = np.asarray(v, dtype=np.float64)
    return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)


def ortho_camera(x0: float = 0.0, y0: float = 0.0, size: float = 1.0, z: float = 5.0) -> str:
    """An orthographic camera looking down -Z that frames [x0, x0+size]^2 exactly."""
    ap = size * 10.0  # apertures are in tenths of a scene unit
    return (
        'def Camera "Cam"\n{\n    token projection = "orthographic"\n'
        f"    float horizontalAperture = {ap:g}\n    float verticalAperture = {ap:g}\n"
        f"    float2 clippingRange = (0.1, 100)\n"
        f"    double3 xformOp:translate = ({x0 + size / 2:g}, {y0 + size / 2:g}, {z:g})\n"
        '    uniform token[] xformOpOrder = ["xformOp:translate"]\n}\n'
    )


def quad(
    name: str,
    material: str | None,
    x0: float = 0.0,
    y0: float = 0.0,
    size: float = 1.0,
    z: float = 0.0,
    st_scale: float = 1.0,
    st_name: str = "st",
    extra: str = "",
) -> str:
    """A quad [x0, x0+size] x [y0, y0+size] at depth z, normal +Z, st = (0..st_scale)."""
    x1, y1, s = x0 + size, y0 + size, st_scale
    bind = f"    rel material:binding = </{material}>\n" if material else ""
    api = ' (prepend apiSchemas = ["MaterialBindingAPI"])' if material else ""
    return (
        f'def Mesh "{name}"{api}\n{{\n'
        "    int[] faceVertexCounts = [4]\n    int[] faceVertexIndices = [0, 1, 2, 3]\n"
        f"    point3f[] points = [({x0:g}, {y0:g}, {z:g}), ({x1:g}, {y0:g}, {z:g}), "
        f"({x1:g}, {y1:g}, {z:g}), ({x0:g}, {y1:g}, {z:g})]\n"
        "    normal3f[] normals = [(0, 0, 1), (0, 0, 1), (0, 0, 1), (0, 0, 1)] "
        '(interpolation = "vertex")\n'
        f"    texCoord2f[] primvars:{st_name} = [(0, 0), ({s:g}, 0), ({s:g}, {s:g}), (0, {s:g})] "
        '(interpolation = "vertex")\n' + extra + bind + "}\n"
    )


def preview_material(
    name: str,
    inputs: str = "",
    textures: dict[str, str] | None = None,
    nodes: str = "",
) -> str:
    """A UsdPreviewSurface material ``/name``. ``inputs``: extra surface input lines;
    ``textures``: surface input declaration -> "Node.outputs:x" connections (lines
    like ``color3f inputs:diffuseColor``); ``nodes``: shader prims inside it."""
    conn = "".join(
        f"        {decl}.connect = </{name}/{src}>\n" for decl, src in (textures or {}).items()
    )
    return (
        f'def Material "{name}"\n{{\n'
        f"    token outputs:surface.connect = </{name}/S.outputs:surface>\n"
        '    def Shader "S"\n    {\n        uniform token info:id = "UsdPreviewSurface"\n'
        + inputs
        + conn
        + "        token outputs:surface\n    }\n"
        + nodes
        + "}\n"
    )


def uv_texture(
    node: str,
    file: str,
    st_source: str | None = "P.outputs:result",
    material: str = "M",
    color_space: str = "auto",
    extra: str = "",
) -> str:
    """A UsdUVTexture shader ``node`` reading ``file`` (all outputs declared)."""
    st = f"        float2 inputs:st.connect = </{material}/{st_source}>\n" if st_source else ""
    return (
        f'    def Shader "{node}"\n    {{\n        uniform token info:id = "UsdUVTexture"\n'
        f"        asset inputs:file = @{file}@\n"
        + st
        + f'        token inputs:sourceColorSpace = "{color_space}"\n'
        + extra
        + "        float3 outputs:rgb\n        float outputs:r\n        float outputs:g\n"
        "        float outputs:b\n        float outputs:a\n    }\n"
    )


def primvar_reader(node: str = "P", varname: str = "st", kind: str = "float2") -> str:
    return (
        f'    def Shader "{node}"\n    {{\n'
        f'        uniform token info:id = "UsdPrimvarReader_{kind}"\n'
        f'        string inputs:varname = "{varname}"\n'
        f"        {kind} outputs:result\n    }}\n"
    )


def write_stage(folder: Path, body: str, name: str = "scene.usda") -> Path:
    p = folder / name
    p.write_text(HEADER + body)
    return p


def expected_st(width: int, height: int, scale: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """(s, t) at each pixel centre of the standard set-up, (height, width) each."""
    c = (np.arange(width) + 0.5) / width
    r = 1.0 - (np.arange(height) + 0.5) / height
    s, t = np.meshgrid(c * scale, r * scale)
    return s, t


def lookup_cells(img: np.ndarray, s: np.ndarray, t: np.ndarray) -> np.ndarray:
    """The texel of ``img`` (top row first) containing (s, t) in [0, 1) (t = 0 at the
    bottom row, as USD's st)."""
    h, w = img.shape[:2]
    col = np.clip(np.floor(s * w).astype(int), 0, w - 1)
    row = np.clip(h - 1 - np.floor(t * h).astype(int), 0, h - 1)
    return img[row, col]


def interior(s: np.ndarray, t: np.ndarray, n_cells: int, margin: float = 0.25) -> np.ndarray:
    """Pixels at least ``margin`` of a cell away from every cell edge of an n x n grid."""
    fs = (s * n_cells) % 1.0
    ft = (t * n_cells) % 1.0
    return (fs > margin) & (fs < 1 - margin) & (ft > margin) & (ft < 1 - margin)
