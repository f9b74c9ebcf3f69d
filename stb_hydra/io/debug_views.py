"""Debug-view images: the colours of the debug AOVs and writing them to files.

CPU side of ``renderer/tasks/aov_output.py`` (which only reads the views back):
light-index hash colours (twin of ``light_color()`` in ``shaders/debug_*.frag``),
the light-count heat map (log2 scale of matplotlib's ``turbo``), its legend, and
``write_debug_aov`` (PNG, plus an EXR of raw counts for ``lightcount``).

Every debug PNG carries its colour scale: a strip of :data:`LEGEND_ROWS` rows below
the view (:func:`legend_strip`) with the scale's colours and its min/max labelled
(the view itself keeps its size and pixels; ``stb:legendRows`` in the metadata).
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


#: Colour stops of the debug views' heat ramp (twin of ``heat_ramp()`` in
#: ``shaders/common/debug_colors.glsl``): blue, cyan, green, yellow, red.
_HEAT_STOPS = np.array(
    [[0.1, 0.2, 1.0], [0.0, 0.85, 1.0], [0.1, 0.9, 0.2], [1.0, 0.9, 0.0], [1.0, 0.15, 0.1]],
    dtype=np.float32,
)
#: Colours of the ``reuse_reject`` view: history combined, rejected, none this frame.
REUSE_REJECT_COLORS = {
    "taken": (0.1, 0.85, 0.2),
    "rejected": (1.0, 0.1, 0.1),
    "none": (0.15, 0.3, 1.0),
}


def heat_ramp(t: np.ndarray) -> np.ndarray:
    """(...,) positions in [0, 1] -> (..., 3) colours of the heat ramp."""
    x = np.clip(np.asarray(t, dtype=np.float32), 0.0, 1.0) * 4.0
    i = np.minimum(x.astype(np.intp), 3)
    f = (x - i)[..., None]
    return _HEAT_STOPS[i] * (1.0 - f) + _HEAT_STOPS[i + 1] * f


def reuse_m_colors(m: np.ndarray) -> np.ndarray:
    """(...,) reservoir confidences M -> (..., 3) colours of the ``reuse_m`` view (log2
    scale from 1 to ``limits.STB_REUSE_DEBUG_M_MAX``; black where M = 0)."""
    from .. import limits

    m = np.asarray(m, dtype=np.float64)
    t = np.log2(np.maximum(m, 1.0)) / np.log2(limits.STB_REUSE_DEBUG_M_MAX)
    return np.where((m > 0.0)[..., None], heat_ramp(t), 0.0).astype(np.float32)


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


#: Rows of the colour-scale strip appended below each debug view's PNG.
LEGEND_ROWS = 28


def _legend_spec(name: str) -> tuple[np.ndarray, str, str, str]:
    """(colours of the scale, left to right; min label; max label; caption)."""
    if name == "lightcount":
        top = np.log2(LIGHTCOUNT_SCALE_MAX)
        counts = np.concatenate([np.zeros(16), np.exp2(np.linspace(0.0, top, 240))])
        return (
            lightcount_heatmap(counts[None, :])[0],
            "0",
            f">={LIGHTCOUNT_SCALE_MAX}",
            "lights in range, log2 (black = 0)",
        )
    if name == "shadowterms":
        g = np.linspace(0.0, 1.0, 256, dtype=np.float32)
        return np.repeat(g[:, None], 3, 1), "0", "1", "shadow x cone x IES term (0 = dark)"
    if name == "bigtile":
        # dark grey = empty slot, then brightness 0.25..1 = weight within the tile
        g = np.concatenate([[0.06] * 16, np.linspace(0.25, 1.0, 240)]).astype(np.float32)
        return (
            np.repeat(g[:, None], 3, 1),
            "min",
            "max",
            "slot weight in its tile, log2 (dark = empty; hue = light)",
        )
    if name in ("smalltile", "reuse_light"):  # black = empty, then hash colours
        c = np.concatenate(
            [np.zeros((16, 3), np.float32), np.repeat(hash_colors(np.arange(15)), 16, axis=0)]
        )
        what = "the light index" if name == "smalltile" else "the reservoir's light"
        return c, "empty", "light hash", f"colour = hash of {what}"
    if name == "reuse_m":
        from .. import limits

        m = np.concatenate([[0.0] * 16, np.exp2(np.linspace(0.0, 7.0, 240))])
        top = int(limits.STB_REUSE_DEBUG_M_MAX)
        return reuse_m_colors(m), "0 | 1", f">={top}", "reservoir confidence M, log2"
    if name == "reuse_reject":
        rgb = np.array(list(REUSE_REJECT_COLORS.values()), np.float32)
        c = np.repeat(rgb, 85, axis=0)
        return c, "taken", "none", "green taken / red rejected / blue no history"
    g = np.linspace(0.0, 1.0, 256, dtype=np.float32)
    return np.repeat(g[:, None], 3, 1), "0", "1", name


def legend_strip(name: str, width: int) -> np.ndarray:
    """(LEGEND_ROWS, width, 3) float32 display-referred colour scale of debug view
    ``name``: the scale's colours left to right (min to max) over the labels."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    colors, lo, hi, caption = _legend_spec(name)
    width = max(int(width), 1)
    rows = LEGEND_ROWS
    out = np.zeros((rows, width, 3), np.float32)
    bar_rows = slice(2, 11)
    x = np.rint(np.linspace(0.0, len(colors) - 1.0, width)).astype(np.intp)  # min ... max
    out[bar_rows] = colors[x][None, :, :]
    fig = Figure(figsize=(width / 100.0, rows / 100.0), dpi=100, facecolor="black")
    FigureCanvasAgg(fig)
    kw = {"color": "white", "fontsize": 6.5, "va": "bottom", "family": "DejaVu Sans"}
    y = 1.0 / rows
    fig.text(1.0 / width, y, lo, ha="left", **kw)
    fig.text(1.0 - 1.0 / width, y, hi, ha="right", **kw)
    if width >= 320:
        fig.text(0.5, y, caption, ha="center", **kw)
    fig.canvas.draw()
    text = np.asarray(fig.canvas.buffer_rgba(), dtype=np.float32)[..., :3] / 255.0
    h = min(text.shape[0], rows)
    w = min(text.shape[1], width)
    label_rows = slice(11, rows)
    out[label_rows, :w] = np.maximum(out[label_rows, :w], text[11:h, :w])
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
    (8-bit, display-referred: the view, then :data:`LEGEND_ROWS` rows of its colour
    scale with min/max labelled) and for ``lightcount`` also ``<stem>.lightcount.exr``
    (float counts, channel Y, no legend). Returns the written paths."""
    from .images import aov_path, write_image

    meta = {"stb:aov": name, **(metadata or {}), "stb:legendRows": LEGEND_ROWS}
    exr = aov_path(path, name)
    png = exr.with_suffix(".png")
    if name == "lightcount":
        meta["stb:lightcountScaleMax"] = LIGHTCOUNT_SCALE_MAX
    view = debug_aov_image(name, pixels)
    shown = np.concatenate([view, legend_strip(name, view.shape[1])], axis=0)
    out = [write_image(png, shown, metadata=meta, display_referred=True)]
    if name == "lightcount":
        counts = np.asarray(pixels, dtype=np.float32)
        out.append(
            write_image(
                exr,
                counts,
                metadata=meta,
                pixel_type="float",
                channel_names=("Y",),
                colorspace="data",
            )
        )
    return out
