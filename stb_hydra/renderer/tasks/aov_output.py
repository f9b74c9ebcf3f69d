"""AOV readback: colour (scene-linear float), display (uint8), depth, normal, albedo,
and the debug views.

Debug AOVs (``stb render --aov ...``), each an (h, w[, 3]) float32 array, top row first:

* ``bigtile`` (stb only): each big tile's K reservoir slots as a grid of cells,
  coloured by a hash of the light index, brightness = weight relative to the
  tile's other slots (log2 scale); dark grey = empty slot.
* ``smalltile`` (stb only): each pixel coloured by a hash of its small tile's
  light samples, a 2x2 mosaic per quad (quad pixel k shows sample k mod N).
* ``shadowterms`` (stb only): the 8-bit deferred shadow terms, in screen space
  (same mosaic), as grey.
* ``lightcount`` (every method): number of FoV lights whose range sphere holds
  the pixel's world position (raw counts; 0 on background). Written as a float
  EXR of the counts plus a PNG heat map: 0 = black, 1..LIGHTCOUNT_SCALE_MAX on
  a log2 scale of matplotlib's ``turbo`` (blue = 1 ... dark red >= 256); the
  legend image comes from :func:`write_lightcount_legend`.

The three STB views run ``StbLighting.debug_pass`` (shaders ``debug_*.frag``);
the light count runs ``debug_lightcount.frag`` over the FoV light buffer. The
same light hashes colour ``bigtile`` and ``smalltile`` (:func:`hash_colors` is
the CPU twin of the shaders' ``light_color``).
"""

from __future__ import annotations

import functools
import os
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

import moderngl
import numpy as np

from .base import Task

STB_DEBUG_AOVS = ("bigtile", "smalltile", "shadowterms")
DEBUG_AOVS = (*STB_DEBUG_AOVS, "lightcount")
AOVS = ("color", "depth", "normal", "albedo", "display", *DEBUG_AOVS)
#: Light count at the top of the heat map's log2 scale (brighter counts saturate).
LIGHTCOUNT_SCALE_MAX = 256


def _read(tex, comps: int, dtype) -> np.ndarray:
    w, h = tex.size
    a = np.frombuffer(tex.read(), dtype=dtype).reshape(h, w, comps)
    return np.flipud(a)  # GL rows are bottom-up


def oct_decode(e: np.ndarray) -> np.ndarray:
    n = np.dstack([e[..., 0], e[..., 1], 1.0 - np.abs(e[..., 0]) - np.abs(e[..., 1])])
    t = np.clip(-n[..., 2], 0.0, 1.0)
    n[..., 0] += np.where(n[..., 0] >= 0, -t, t)
    n[..., 1] += np.where(n[..., 1] >= 0, -t, t)
    return n / np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-12)


# --- which AOVs a method supports ---------------------------------------------------------


def supports_stb_debug(method: Any) -> bool:
    """True for a lighting method (instance or class) that draws the STB debug views."""
    return callable(getattr(method, "debug_pass", None))


def check_debug_aovs(names: Iterable[str], lighting: str, method: Any = None) -> None:
    """Raise ``ValueError`` (one line) when STB debug AOVs are asked of another method.

    ``method``: the method instance or class (default: looked up from ``lighting``).
    """
    stb = [n for n in STB_DEBUG_AOVS if n in set(names)]
    if not stb:
        return
    if method is None:
        from ..lighting import method_class

        method = method_class(lighting)
    if not supports_stb_debug(method):
        raise ValueError(
            f"AOV(s) {','.join(stb)} need --lighting stb (this render uses '{lighting}')"
        )


# --- colouring ---------------------------------------------------------------------------


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
    from ...io.images import aov_path, write_image

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


# --- the task ----------------------------------------------------------------------------


class AovOutputTask(Task):
    only_final = True
    name = "aov_output"

    def __init__(self, engine) -> None:
        super().__init__(engine)
        self._requested: set[str] = {"color"}
        self.results: dict[str, np.ndarray] = {}

    @property
    def requested(self) -> set[str]:
        return self._requested

    @requested.setter
    def requested(self, names: Iterable[str]) -> None:
        names = set(names)
        method = getattr(self.engine, "method", None)
        if method is not None:
            check_debug_aovs(names, getattr(method, "name", "?"), method)
        self._requested = names

    def execute(self, frame) -> None:
        bufs = frame.buffers
        out: dict[str, np.ndarray] = {}
        if "color" in self.requested:
            src = bufs.textures[frame.color_buffer]
            dt = np.float16 if src.dtype == "f2" else np.float32
            out["color"] = _read(src, 4, dt).astype(np.float32)
        if "display" in self.requested and "display" in bufs.textures:
            out["display"] = _read(bufs.textures["display"], 4, np.uint8)
        if "depth" in self.requested:
            out["depth"] = _read(bufs.textures["g_depth"], 1, np.float32)[..., 0]
        if "normal" in self.requested:
            e = _read(bufs.textures["g_normal"], 2, np.float16).astype(np.float32)
            n = oct_decode(e)
            bg = _read(bufs.textures["g_depth"], 1, np.float32)[..., 0] <= 0
            n[bg] = 0.0
            out["normal"] = n.astype(np.float32)
        if "albedo" in self.requested:
            out["albedo"] = _read(bufs.textures["g_base_rough"], 4, np.float16)[..., :3].astype(
                np.float32
            )
        for name in STB_DEBUG_AOVS:
            if name in self.requested:
                out[name] = self._stb_debug(frame, name)
        if "lightcount" in self.requested:
            out["lightcount"] = self._lightcount(frame)
        self.results = out

    def _stb_debug(self, frame, name: str) -> np.ndarray:
        w, h = frame.buffers.size
        target = "debug_" + name
        tex = frame.buffers.texture(target, 4, "f1")
        if not self.engine.method.debug_pass(frame, name, target):
            return np.zeros((h, w, 3), np.float32)  # no local lights: no STB passes ran
        return _read(tex, 4, np.uint8)[..., :3].astype(np.float32) / np.float32(255.0)

    def _lightcount(self, frame) -> np.ndarray:
        from ..gl import shader_library

        bufs = frame.buffers
        w, h = bufs.size
        ssbo = self.engine.delegate.light_ssbo
        if frame.light_count == 0 or ssbo is None:
            return np.zeros((h, w), np.float32)
        tex = bufs.texture("debug_lightcount", 1, "f4")
        prog = shader_library(frame.ctx).program("fullscreen.vert", "debug_lightcount.frag")
        bufs.textures["g_depth"].use(0)
        if "g_depth" in prog:
            prog["g_depth"].value = 0
        ssbo.bind_to_storage_buffer(0)
        fbo = bufs.framebuffer("fb_debug_lightcount", ["debug_lightcount"])
        fbo.use()
        frame.ctx.viewport = (0, 0, w, h)
        frame.ctx.disable(moderngl.BLEND | moderngl.DEPTH_TEST)
        self.engine.fullscreen(prog).render(moderngl.TRIANGLES, vertices=3)
        return _read(tex, 1, np.float32)[..., 0].copy()
