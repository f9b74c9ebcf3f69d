"""Shadow-map sides from the screen footprint (issue 33 item 5): a compute pass over
the G-buffer (``shadow_footprint.comp``) measures, per shadowed in-view light, the map
side its receivers need on screen -- side = H w l / (2 D tan(fov_y / 2)) x
min(cos(view) / cos(light), SHADOW_FOOTPRINT_SLOPE_MAX) at 1 texel per pixel for a
receiver at view depth D (m), distance l (m) from the light, w the map's angular span
per side -- weighted by the light's share of the receiver's
illuminance and skipped where the light's display-relative radiance is negligible
(``limits.SHADOW_FOOTPRINT_*``). The maximum over every
``SHADOW_FOOTPRINT_STRIDE_PX``-th pixel is read back (one small synchronous read,
only on the frame before the atlas's next policy run) and handed to
``ShadowAtlasTask.set_footprint``; the policy uses it as
``RenderSettings.shadow_resolution`` says (``shadows.policy.combine_targets``).

At most ``SHADOW_FOOTPRINT_LIGHTS_MAX`` lights are measured (the atlas's highest
priorities); the others keep the flux rule. IES profiles and light linking are not
applied to the weights (their cones are)."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import moderngl
import numpy as np

from ... import limits
from ..frame import FrameContext
from ..gl import set_uniform, shader_library
from ..graph import Imported, Rec, Tex
from ..records import FrameBlock, InViewLights, LightBuffer
from ..shader_constants import SSBO_FOOTPRINT_LIGHTS, SSBO_FOOTPRINT_OUT, SSBO_LIGHTS
from .base import Pass

if TYPE_CHECKING:
    from ..gl_delegate import GLRenderDelegate
    from .shadow_atlas import ShadowAtlasTask


def percentile_need(maxima: np.ndarray, hist: np.ndarray, fraction: float) -> np.ndarray:
    """Per light, the side (texels at 1 texel/px) that meets ``fraction`` of its
    receivers: the maximum for fraction >= 1, else the upper edge 2^((b + 1) / 2) of
    the half-octave bin b where the cumulative count reaches it (never above the
    maximum). ``hist``: (lights, bins) receiver counts; ``maxima``: (lights,)."""
    mx = np.asarray(maxima, dtype=np.float64)
    if fraction >= 1.0 or not len(mx):
        return mx
    h = np.asarray(hist, dtype=np.float64)
    cum = np.cumsum(h, axis=1)
    total = cum[:, -1:]
    b = np.argmax(cum >= fraction * np.maximum(total, 1e-30), axis=1)
    edge = 2.0 ** ((b + 1) / 2.0)
    return np.where(total[:, 0] > 0, np.minimum(edge, mx), mx)


class ShadowFootprintTask(Pass):
    name = "shadow_footprint"
    reads = (
        Tex("g_depth", "r32f"),
        Tex("g_normal", "rg16f"),
        Rec(LightBuffer),
        Rec(InViewLights),
        Rec(FrameBlock),
        Imported("light_table"),
    )
    writes = ()
    side_effect = True

    def __init__(self, delegate: GLRenderDelegate, atlas: ShadowAtlasTask) -> None:
        super().__init__(delegate)
        self.atlas = atlas
        self._in: moderngl.Buffer | None = None
        self._out: moderngl.Buffer | None = None
        #: Lights measured by the last run (tests, tools).
        self.last_count = 0

    def execute(self, frame: FrameContext) -> None:
        atlas = self.atlas
        if not atlas.wants_footprint(frame.frame_index):
            return
        lights = frame.get(InViewLights)
        ssbo = frame.get(LightBuffer).ssbo
        keys, idx, span = atlas.footprint_candidates(lights.rows)
        if not keys or ssbo is None:
            atlas.set_footprint([], np.zeros(0), frame.frame_index)
            return
        n = len(keys)
        with frame.timings_scope("shadow_footprint"):
            ctx = frame.ctx
            data = np.zeros((limits.SHADOW_FOOTPRINT_LIGHTS_MAX, 4), dtype=np.float32)
            data[:n, 0] = idx
            data[:n, 1] = span
            m, bins = limits.SHADOW_FOOTPRINT_LIGHTS_MAX, limits.SHADOW_FOOTPRINT_BINS
            words = m * (1 + bins)
            if self._in is None:
                self._in = ctx.buffer(reserve=data.nbytes)
                self._out = ctx.buffer(reserve=4 * words)
            assert self._out is not None
            self._in.write(data.tobytes())
            self._out.write(np.zeros(words, np.uint32).tobytes())
            defines: dict[str, object] = {"HAS_CONES": True} if lights.has_cones else {}
            cs = shader_library(ctx).compute("shadow_footprint.comp", defines)
            bufs = frame.buffers
            bufs.textures["g_depth"].use(0)
            bufs.textures["g_normal"].use(1)
            set_uniform(cs, "g_depth", 0)
            set_uniform(cs, "g_normal", 1)
            set_uniform(cs, "u_count", n)
            stride = limits.SHADOW_FOOTPRINT_STRIDE_PX
            set_uniform(cs, "u_stride", stride)
            set_uniform(cs, "u_share_full", float(limits.SHADOW_FOOTPRINT_SHARE_FULL))
            set_uniform(cs, "u_display_min", float(limits.SHADOW_FOOTPRINT_DISPLAY_MIN))
            set_uniform(cs, "u_slope_max", float(limits.SHADOW_FOOTPRINT_SLOPE_MAX))
            ssbo.bind_to_storage_buffer(SSBO_LIGHTS)
            self._in.bind_to_storage_buffer(SSBO_FOOTPRINT_LIGHTS)
            self._out.bind_to_storage_buffer(SSBO_FOOTPRINT_OUT)
            w, h = bufs.size
            cs.run(math.ceil(w / stride / 8), math.ceil(h / stride / 8), 1)
            ctx.memory_barrier()
            raw = np.frombuffer(self._out.read(size=4 * (m + n * bins)), dtype=np.uint32)
            need = percentile_need(
                raw[:n].view(np.float32).astype(np.float64),
                raw[m:].reshape(n, bins),
                limits.SHADOW_FOOTPRINT_PERCENTILE,
            )
        self.last_count = n
        atlas.set_footprint(keys, need, frame.frame_index)
        frame.stats["shadow_footprint_lights"] = n

    def release(self) -> None:
        for b in (self._in, self._out):
            if b is not None:
                b.release()
        self._in = self._out = None
