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

The STB views are drawn by ``lighting.stb.StbDebugPass`` (shaders ``debug_*.frag``),
the light count by :class:`LightCountTask` (``debug_lightcount.frag`` over the FoV
light buffer); those passes join the graph only when their AOV is requested.
Colouring and file writing live in ``stb_hydra/io/debug_views.py``.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import TYPE_CHECKING, Any, cast

import moderngl
import numpy as np
import numpy.typing as npt

from ..frame import FrameContext
from ..graph import Imported, Rec, Resource, Tex
from ..lighting import METHODS, debug_aov_names
from ..lighting.stb import StbLighting
from ..records import InViewLights, LightBuffer, SceneColor
from ..shader_constants import SSBO_LIGHTS
from .base import Pass
from .color_correction import COLOR_SOURCES

if TYPE_CHECKING:
    from ..gl_delegate import GLRenderDelegate

#: The STB method's debug views.
STB_DEBUG_AOVS = StbLighting.debug_aovs
#: Debug AOVs: every method's declared views, then the light-count heat map (all methods).
DEBUG_AOVS = (*debug_aov_names(), "lightcount")
#: Every AOV name (``stb render --aov``), the one list.
AOVS = ("color", "depth", "normal", "albedo", "display", *DEBUG_AOVS)


def _read(tex: moderngl.Texture, comps: int, dtype: npt.DTypeLike) -> np.ndarray:
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


def check_debug_aovs(names: Iterable[str], lighting: str, method: Any = None) -> None:
    """Raise ``ValueError`` (one line) for unknown AOV names and for a method's debug
    AOVs asked of another method. ``method``: the method instance or class
    (default: looked up from ``lighting``)."""
    names = list(dict.fromkeys(names))
    unknown = [n for n in names if n not in AOVS]
    if unknown:
        raise ValueError(f"unknown AOV(s) {','.join(unknown)} (choose from {', '.join(AOVS)})")
    if method is None:
        from ..lighting import method_class

        method = method_class(lighting)
    offered = set(getattr(method, "debug_aovs", ()))
    missing = [n for n in names if n in debug_aov_names() and n not in offered]
    requires = getattr(method, "debug_aov_requires", {})
    if missing and all(n in requires for n in missing):
        need = ", ".join(dict.fromkeys(requires[n] for n in missing))
        raise ValueError(f"AOV(s) {','.join(missing)} need {need} (--lighting {lighting})")
    if missing:
        owners = [m for m, cls in METHODS.items() if set(missing) <= set(cls.debug_aovs)]
        need = " or ".join(f"--lighting {m}" for m in owners) or "another method"
        raise ValueError(f"AOV(s) {','.join(missing)} need {need} (this render uses '{lighting}')")


# --- the task ----------------------------------------------------------------------------

#: What each non-debug AOV reads.
AOV_READS: dict[str, tuple[Resource, ...]] = {
    "color": (Rec(SceneColor), *COLOR_SOURCES),
    "display": (Tex("display", "rgba8"),),
    "depth": (Tex("g_depth", "r32f"),),
    "normal": (Tex("g_normal", "rg16f"), Tex("g_depth", "r32f")),
    "albedo": (Tex("g_base_rough", "rgba16f"),),
}


class AovOutputTask(Pass):
    """Reads the requested AOVs back to host memory (``results``). Its reads follow
    ``requested``, so the passes drawing debug views join the graph only when one of
    their AOVs is requested (changing ``requested`` rebuilds the graph)."""

    name = "aov_output"
    only_final = True
    side_effect = True

    def __init__(
        self,
        delegate: GLRenderDelegate,
        method: Any = None,
        on_change: Callable[[], None] | None = None,
    ) -> None:
        super().__init__(delegate)
        self.method = method
        self.on_change = on_change
        self._requested: set[str] = {"color"}
        self.results: dict[str, np.ndarray] = {}

    @property
    def requested(self) -> set[str]:
        return self._requested

    @requested.setter
    def requested(self, names: Iterable[str]) -> None:
        names = set(names)
        if self.method is not None:
            check_debug_aovs(names, getattr(self.method, "name", "?"), self.method)
        if names != self._requested:
            self._requested = names
            if self.on_change is not None:
                self.on_change()

    def io(self) -> tuple[tuple[Resource, ...], tuple[Resource, ...]]:
        reads: list[Resource] = []
        for name in sorted(self._requested):
            if name in AOV_READS:
                reads += AOV_READS[name]
            elif name in DEBUG_AOVS:
                reads.append(Tex(f"debug_{name}"))
        return tuple(dict.fromkeys(reads)), ()

    def execute(self, frame: FrameContext) -> None:
        bufs = frame.buffers
        out: dict[str, np.ndarray] = {}
        if "color" in self.requested:
            src = bufs.textures[frame.get(SceneColor).buffer]
            dt = np.float16 if src.dtype == "f2" else np.float32
            out["color"] = _read(src, 4, dt).astype(np.float32)
        if "display" in self.requested:
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
        for name in DEBUG_AOVS:
            if name not in self.requested:
                continue
            tex = bufs.textures[f"debug_{name}"]
            if name == "lightcount":
                out[name] = _read(tex, 1, np.float32)[..., 0].copy()
            else:
                out[name] = _read(tex, 4, np.uint8)[..., :3].astype(np.float32) / np.float32(255.0)
        self.results = out


class LightCountTask(Pass):
    """``debug_lightcount``: per pixel, the in-view lights whose range sphere holds
    its world position (``debug_lightcount.frag``, R32F; 0 on background)."""

    name = "debug_lightcount"
    only_final = True
    reads = (Tex("g_depth", "r32f"), Rec(InViewLights), Rec(LightBuffer), Imported("light_table"))
    writes = (Tex("debug_lightcount", "r32f"),)

    def execute(self, frame: FrameContext) -> None:
        from ..fullscreen import draw_fullscreen
        from ..gl import shader_library

        bufs = frame.buffers
        fbo = bufs.framebuffer("fb_debug_lightcount", ["debug_lightcount"])
        ssbo = frame.get(LightBuffer).ssbo
        if frame.light_count == 0 or ssbo is None:
            fbo.clear(0.0, 0.0, 0.0, 0.0)
            return
        prog = shader_library(frame.ctx).program("fullscreen.vert", "debug_lightcount.frag")
        bufs.textures["g_depth"].use(0)
        if "g_depth" in prog:
            cast(moderngl.Uniform, prog["g_depth"]).value = 0
        ssbo.bind_to_storage_buffer(SSBO_LIGHTS)
        draw_fullscreen(frame.ctx, prog, fbo, bufs.size)
