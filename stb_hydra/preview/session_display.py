"""What a :class:`~stb_hydra.preview.session.PreviewSession` shows
(:class:`DisplayControls`): the views on offer (colour, every AOV, the method's debug
views, the shadow atlas; :data:`VIEWS`), the display texture and a view as an 8-bit
image (:func:`view_to_rgb8`, with the debug views' legend), display exposure and the
OCIO display and view.
"""

from __future__ import annotations

import math

import moderngl
import numpy as np

from ..color.ocio import ColorPipeline
from ..io.debug_views import LEGEND_ROWS, legend_strip
from ..renderer.tasks.aov_output import AOVS, DEBUG_AOVS
from .atlas_view import AtlasView
from .session_state import SessionState, _one_line

#: Views the viewport can show: the display image, then every AOV (the debug views
#: of a method only while that method is active).
VIEWS = (*(a for a in AOVS if a != "display"), "shadow_atlas")


class DisplayControls(SessionState):
    """The views, exposure and OCIO part of the session."""

    _atlas_view: AtlasView | None
    _legends: dict[tuple[str, int], np.ndarray]

    # -- display --
    def views(self) -> list[str]:
        """The views the current method offers (colour, AOVs, its debug views)."""
        assert self.engine is not None
        offered = set(getattr(self.engine.method, "debug_aovs", ()))
        return [v for v in VIEWS if v not in DEBUG_AOVS or v == "lightcount" or v in offered]

    def display_texture(self) -> moderngl.Texture | None:
        """The engine's OCIO display image (rgba8, GL rows bottom-up)."""
        if not self.ok:
            return None
        assert self.engine is not None
        return self.engine.buffers.textures.get("display")

    def view_image(self) -> np.ndarray | None:
        """The current non-colour view as (h, w, 3) uint8, top row first (None for
        ``color``: the display texture is shown as it is)."""
        if self.view == "color" or not self.ok:
            return None
        assert self.engine is not None
        if self.view == "shadow_atlas":
            if self._atlas_view is None:
                self._atlas_view = AtlasView(self.engine.ctx)
            return self._atlas_view.image(self.engine, *self.size)
        a = self.engine.aovs.get(self.view)
        if a is None:
            return None
        img = view_to_rgb8(self.view, a)
        if self.view in DEBUG_AOVS and img.shape[0] >= 2 * LEGEND_ROWS:
            # the debug view's colour scale over its bottom rows
            key = (self.view, img.shape[1])
            if key not in self._legends:
                strip = legend_strip(self.view, img.shape[1])
                self._legends[key] = (np.clip(strip, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
            img[-LEGEND_ROWS:] = self._legends[key]
        return img

    def set_view(self, name: str) -> bool:
        """Show colour, an AOV or a debug view (read back each frame)."""
        if not self.ok:
            return False
        assert self.engine is not None
        if name not in self.views():
            self.message = (
                f"view '{name}' not offered by '{self.method}' (views: {', '.join(self.views())})"
            )
            return False
        self.engine.request_aovs(set() if name in ("color", "shadow_atlas") else {name})
        self.view = name
        self._force = True
        return True

    @property
    def exposure(self) -> float:
        assert self.engine is not None
        return self.engine.color.exposure

    def set_exposure(self, stops: float) -> bool:
        """Display exposure (stops, OCIO): the image is re-displayed, samples kept."""
        if not self.ok:
            return False
        assert self.engine is not None
        if not math.isfinite(stops):
            self.message = f"exposure must be finite, got {stops}"
            return False
        self.engine.color.exposure = float(stops)
        self._force = True
        return True

    def set_ocio_display(self, display: str) -> bool:
        """Switch the OCIO display (its default view; same config and exposure)."""
        return self.set_ocio_view(None, display)

    def set_ocio_view(self, view: str | None, display: str | None = None) -> bool:
        """Switch the OCIO view (same config; ``display``: another display too)."""
        if not self.ok:
            return False
        e = self.engine
        assert e is not None
        old = e.color
        try:
            new = ColorPipeline(old.config_source, display or old.display, view, old.exposure)
        except ValueError as exc:
            self.message = _one_line(exc)
            return False
        e.color = new
        e.set_lighting(e.settings.lighting, **e.settings.method_options)
        self._force = True
        return True


def view_to_rgb8(name: str, a: np.ndarray) -> np.ndarray:
    """An AOV as an 8-bit image (top row first): depth as a grey ramp near = white,
    normals as n/2 + 1/2, albedo clipped, debug views by their own colour scale,
    colour (scene-linear) clipped."""
    from ..io.debug_views import debug_aov_image

    a = np.nan_to_num(np.asarray(a, dtype=np.float32), nan=0.0, posinf=0.0, neginf=0.0)
    if name == "depth":
        fg = a > 0
        out = np.zeros(a.shape, np.float32)
        if fg.any():
            lo, hi = float(a[fg].min()), float(a[fg].max())
            out[fg] = 1.0 - 0.8 * (a[fg] - lo) / max(hi - lo, 1e-9)
        rgb = np.repeat(out[..., None], 3, axis=-1)
    elif name == "normal":
        rgb = np.where(np.any(a != 0, axis=-1, keepdims=True), 0.5 * a + 0.5, 0.0)
    elif name in DEBUG_AOVS:
        rgb = debug_aov_image(name, a)
    else:
        rgb = a[..., :3] if a.ndim == 3 else np.repeat(a[..., None], 3, axis=-1)
    return (np.clip(rgb, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)
