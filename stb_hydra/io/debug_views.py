"""Debug-view images: the colours of the debug AOVs and writing them to files.

CPU side of ``renderer/tasks/aov_output.py`` (which only reads the views back):
light-index hash colours (twin of ``light_color()`` in ``shaders/debug_*.frag``),
the light-count heat map (log2 scale of matplotlib's ``turbo``), its legend, and
``write_debug_aov`` (PNG, plus an EXR of raw counts for ``lightcount``).
"""

from __future__ import annotations

import functools
import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

#: Light count at the top of the heat map's log2 scale (brighter counts saturate).
LIGHTCOUNT_SCALE_MAX = 256


def hash_colors(index: np.ndarray) -> np.ndarray:
    """(..., 3) float32 colours of light indices: CPU twin of ``light_color()`` in
    ``shaders/debug_bigtile.frag`` / ``debug_smalltile.frag``."""
    with np.errstate(over="ignore"):
        h = np.asarray(index, dtype=np.uint32) * np.uint32(747796405) + np.uint32(2891336453)
        h = ((h >> ((h >> np.uint32(28)) + np.uint32(4))) ^ h) * np.uint32(277803737)
        h = (h >> np.uint32(22)) ^ h
    hue = (h & np.uint32(1023)).astype(np.float32) / np.float32(1024.0)
    off = np.array([0.0, 2.0 / 3.0, 1.0 / 3.0], dtype=np.float32)
    c = np.clip(np.abs(np.modf(hue[..., None] + off)[0] * 6.0 - 3.0) - 1.0, 0.0, 1.0)
    v = 0.55 + 0.45 * ((h >> np.uint32(10)) & np.uint32(255)).astype(np.float32) / 255.0
    return ((1.0 - 0.85) + 0.85 * c) * v[..., None]


@functools.cache
def _turbo_lut() -> np.ndarray:
    import matplotlib

    return np.asarray(matplotlib.colormaps["turbo"](np.linspace(0.0, 1.0, 256))[:, :3], np.float32)


def lightcount_scale(counts: np.ndarray) -> np.ndarray:
    """Counts -> position on the heat map's colour scale [0, 1] (log2, 1 -> 0)."""
    c = np.maximum(np.asarray(counts, dtype=np.float64), 1.0)
    return np.clip(np.log2(c) / np.log2(LIGHTCOUNT_SCALE_MAX), 0.0, 1.0)


def lightcount_heatmap(counts: np.ndarray) -> np.ndarray:
    """(h, w) light counts -> (h, w, 3) display-referred heat map (0 = black)."""
    counts = np.asarray(counts)
    idx = np.rint(lightcount_scale(counts) * 255.0).astype(np.intp)
    rgb = _turbo_lut()[idx]
    rgb[counts < 0.5] = 0.0
    return rgb


def write_lightcount_legend(path: str | os.PathLike[str]) -> Path:
    """Write the light-count heat map's colour bar (PNG, for the docs)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ticks = [0, *(2**k for k in range(int(np.log2(LIGHTCOUNT_SCALE_MAX)) + 1))]
    counts = np.concatenate([[0.0], np.exp2(np.linspace(0, np.log2(LIGHTCOUNT_SCALE_MAX), 511))])
    bar = lightcount_heatmap(counts[None, :])
    fig, ax = plt.subplots(figsize=(7.0, 1.1))
    ax.imshow(np.repeat(bar, 24, axis=0), aspect="auto", extent=(-1.0 / 511, 1.0, 0, 1))
    ax.set_xticks([float(lightcount_scale(np.array(t))) if t else -0.5 / 511 for t in ticks])
    ax.set_xticklabels([str(t) if t < LIGHTCOUNT_SCALE_MAX else f">={t}" for t in ticks])
    ax.set_yticks([])
    ax.set_title("lightcount AOV: FoV lights whose range covers the pixel (0 = black)", fontsize=9)
    fig.tight_layout()
    out = Path(os.fspath(path))
    fig.savefig(out, dpi=120)
    plt.close(fig)
    return out


def debug_aov_image(name: str, pixels: np.ndarray) -> np.ndarray:
    """A debug AOV as a display-referred (h, w, 3) image in [0, 1]."""
    if name == "lightcount":
        return lightcount_heatmap(pixels)
    return np.clip(np.asarray(pixels, dtype=np.float32), 0.0, 1.0)


def write_debug_aov(
    path: str | os.PathLike[str],
    name: str,
    pixels: np.ndarray,
    *,
    metadata: Mapping[str, Any] | None = None,
) -> list[Path]:
    """Write debug AOV ``name`` next to colour image ``path``: ``<stem>.<name>.png``
    (8-bit, display-referred) and for ``lightcount`` also ``<stem>.lightcount.exr``
    (float counts, channel Y). Returns the written paths."""
    from .images import aov_path, write_image

    meta = {"stb:aov": name, **(metadata or {})}
    exr = aov_path(path, name)
    png = exr.with_suffix(".png")
    if name == "lightcount":
        meta["stb:lightcountScaleMax"] = LIGHTCOUNT_SCALE_MAX
    out = [write_image(png, debug_aov_image(name, pixels), metadata=meta, display_referred=True)]
    if name == "lightcount":
        counts = np.asarray(pixels, dtype=np.float32)
        out.append(
            write_image(
                exr, counts, metadata=meta, pixel_type="float", channel_names=("Y",),
                colorspace="data",
            )
        )
    return out
