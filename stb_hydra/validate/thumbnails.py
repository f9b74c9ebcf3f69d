"""``--thumbnails``: a small render of the asset lit by its own lights.

Uses the flat render API ``stb_hydra.api.render(stage_or_path, width, height,
lighting="reference", camera=None, ...)`` -> (h, w, 3) float32 scene-linear (a free
camera framing the stage bounds when the stage has no camera), the engine's
reference method (all lights, no stochastic sampling). A neutral ambient of
:data:`AMBIENT_NITS` is passed when the function accepts ``ambient`` so unlit
geometry stays readable. The image is auto-exposed (97th-percentile luminance -> 0.7),
converted to display with the OCIO :class:`~stb_hydra.color.ocio.ColorPipeline` and
written as PNG with OpenImageIO; the PNG is returned base64-encoded for the HTML.
"""

from __future__ import annotations

import base64
import importlib
import inspect
import os
import tempfile

import numpy as np

from ..color import LUMINANCE_REC709

#: Thumbnail size (px).
WIDTH, HEIGHT = 192, 108
#: Uniform ambient radiance (nits) under the asset's own lights.
AMBIENT_NITS = 0.05
_LUMA = np.array(LUMINANCE_REC709, dtype=np.float32)


def render_api():
    """The flat render function, or raise ImportError when stb_hydra.api is missing."""
    return importlib.import_module("stb_hydra.api").render


def auto_expose(rgb: np.ndarray, percentile: float = 97.0, level: float = 0.7) -> np.ndarray:
    """Scale so the ``percentile`` luminance is ``level`` (scene-linear): the brightest
    lit surfaces land just under the view transform's shoulder. Non-finite -> 0."""
    img = np.nan_to_num(np.asarray(rgb, dtype=np.float32), nan=0.0, posinf=0.0, neginf=0.0)
    y = np.maximum(img @ _LUMA, 0.0)
    ref = float(np.percentile(y, percentile)) if y.size else 0.0
    if ref <= 1e-12:
        return img
    return img * np.float32(level / ref)


def png_bytes(u8: np.ndarray) -> bytes:
    """8-bit RGB(A) array -> PNG file bytes (OpenImageIO)."""
    import OpenImageIO as oiio

    h, w, c = u8.shape
    with tempfile.TemporaryDirectory(prefix="stb-thumb-") as tmp:
        path = os.path.join(tmp, "thumb.png")
        out = oiio.ImageOutput.create(path)
        if out is None:
            raise OSError(oiio.geterror())
        spec = oiio.ImageSpec(w, h, c, "uint8")
        if not (out.open(path, spec) and out.write_image(np.ascontiguousarray(u8))):
            err = out.geterror()
            out.close()
            raise OSError(err)
        out.close()
        with open(path, "rb") as f:
            return f.read()


def render_thumbnail(stage_or_path, width: int = WIDTH, height: int = HEIGHT) -> str:
    """Base64 PNG of the asset (see the module docstring). Raises on failure."""
    from ..color.ocio import ColorPipeline

    render = render_api()
    kwargs: dict = {"width": width, "height": height, "lighting": "reference", "camera": None}
    try:
        params = inspect.signature(render).parameters
    except (TypeError, ValueError):
        params = {}
    if "ambient" in params:
        kwargs["ambient"] = AMBIENT_NITS
    rgb = np.asarray(render(stage_or_path, **kwargs), dtype=np.float32)[..., :3]
    u8 = ColorPipeline().to_uint8(auto_expose(rgb))
    return base64.b64encode(png_bytes(np.asarray(u8, dtype=np.uint8))).decode("ascii")
