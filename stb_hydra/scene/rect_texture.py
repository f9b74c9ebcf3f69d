"""RectLight textures (issue 37 item 3) -> one square, box-filtered layer (no GL here).

UsdLux (RectLight): the rect lies in its local XY plane and emits along -Z; "in the
default position, a texture file's min coordinates should be at (+X, +Y) and max
coordinates at (-X, -Y)". The image's first column lies along the rect's +X edge and its
first (top) row along +Y, so a viewer facing the emitting side sees the image upright and
unmirrored. A texel (column i, row j) of an n x n layer covers the local rect
``x in [w/2 - (i + 1) w/n, w/2 - i w/n]``, ``y in [h/2 - (j + 1) h/n, h/2 - j h/n]``.

The file is decoded like a material texture (``scene/dome.py``'s reader: OIIO, the
colour-space rules of ``color.texture_spaces``, linear Rec.709), then box-resampled
(each output texel the exact area average of the source texels it covers) into a
``limits.RECT_TEXTURE_PX`` square layer; GL's mip generation of that power-of-two
layer (2 x 2 box means down to 1 x 1) makes every mip texel the mean of the texture
over its part of the rect. The layer stores the
texture **divided by its mean**, channel by channel (0 where a channel's mean is 0): the
light's ``intensity`` keeps radiance x mean (the single colour validation, STB's
targets and the point model use), and ``intensity`` x this layer is the radiance at
each point of the rect.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from .. import limits


@dataclass(frozen=True)
class RectTexture:
    """A RectLight texture ready for the GPU (see the module docstring)."""

    #: Plain mean RGB of the texture (linear Rec.709; the light's colour factor).
    mean: np.ndarray
    #: (n, n, 3) float32 texture / mean, n = RECT_TEXTURE_PX.
    layer: np.ndarray
    source: str


_cache: dict[tuple[str, float, str], RectTexture] = {}


def box_weights(n_in: int, n_out: int) -> np.ndarray:
    """(n_out, n_in) matrix averaging ``n_in`` unit cells into ``n_out`` equal ones (rows
    sum to 1; each weight the overlap of an output cell with an input cell)."""
    e_in = np.arange(n_in + 1) / n_in
    e_out = np.arange(n_out + 1) / n_out
    lo = np.maximum(e_out[:-1, None], e_in[None, :-1])
    hi = np.minimum(e_out[1:, None], e_in[None, 1:])
    w = np.maximum(hi - lo, 0.0)
    return w / w.sum(axis=1, keepdims=True)


def box_resample(img: np.ndarray, size: int) -> np.ndarray:
    """(size, size, 3) float64 area average of (h, w, 3) ``img`` (exact for a texture
    piecewise constant over its texels: the mean and every cell average are kept)."""
    h, w = img.shape[:2]
    wy = box_weights(h, size)
    wx = box_weights(w, size)
    # Two matrix products (rows, then columns): an unoptimised three-operand einsum
    # loops over every (output texel, input texel) pair -- 20 minutes for a 2k texture.
    rows = (wy @ img.astype(np.float64).reshape(h, -1)).reshape(size, w, -1)
    return np.einsum("xw,ywc->yxc", wx, rows, optimize=True)


def load_rect_texture(path: str, color_space: str = "") -> RectTexture:
    """The GPU-ready layer of RectLight texture ``path`` (``color_space`` "" or "auto":
    the file's own), cached by file, mtime and colour space. Raises
    ``dome.DomeTextureError`` with a one-line reason."""
    from .dome import DomeTextureError, _read_rgb

    try:
        key = (path, os.path.getmtime(path), color_space)
    except OSError:
        raise DomeTextureError("file not found") from None
    hit = _cache.get(key)
    if hit is not None:
        return hit
    n = limits.RECT_TEXTURE_PX
    assert n & (n - 1) == 0 and n % limits.RECT_TEXTURE_GRID == 0
    layer = box_resample(_read_rgb(path, color_space), n)
    mean = layer.mean(axis=(0, 1))
    scale = np.where(mean > 0.0, 1.0 / np.where(mean > 0.0, mean, 1.0), 0.0)
    norm = (layer * scale).astype(np.float32)
    tex = RectTexture(mean=mean, layer=norm, source=path)
    if len(_cache) >= limits.DOME_CACHE_ENTRIES:
        _cache.pop(next(iter(_cache)))
    _cache[key] = tex
    return tex
