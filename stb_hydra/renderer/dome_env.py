"""The textured dome on the GPU (issue 37): the render-frame lat-long map of
``scene/dome.py`` as a mipmapped float texture plus the uniforms of
``shaders/common/dome.glsl`` (SH9 irradiance, radiance scale, multipliers).

Owned by the delegate; re-uploaded only when the dome's map changes (a new file,
format or orientation), while its scale and multipliers are plain uniforms.
"""

from __future__ import annotations

from typing import cast

import moderngl
import numpy as np

from ..scene.prims import DomeMap, LightPrim
from .gl import set_uniform


class DomeEnvironment:
    """GPU copy of the one textured dome a frame uses (the brightest enabled one)."""

    def __init__(self, ctx: moderngl.Context) -> None:
        self.ctx = ctx
        #: The whole map (seen by the camera; lighting without a split sun).
        self.texture: moderngl.Texture | None = None
        #: The map without its sun (``DomeMap.rest``), when it has one.
        self.rest: moderngl.Texture | None = None
        self.map: DomeMap | None = None
        self.light: LightPrim | None = None
        #: This frame lights the dome's sun as the shadowed sun (use ``rest``).
        self.split = False
        self.levels = 0

    def update(self, lp: LightPrim | None, split: bool = False) -> None:
        """Use dome light ``lp`` (None: none this frame), its sun split off when
        ``split``; uploads its map if new."""
        self.light = lp
        self.split = split
        dm = lp.dome_map if lp is not None else None
        if dm is None or dm is self.map:
            return
        self._release_texture()
        self.texture = self._upload(dm.latlong)
        self.rest = self._upload(dm.rest) if dm.rest is not None else None
        self.map = dm
        h, w = dm.latlong.shape[:2]
        self.levels = int(np.floor(np.log2(max(w, h))))

    def _upload(self, img: np.ndarray) -> moderngl.Texture:
        h, w = img.shape[:2]
        rgba = np.concatenate([img, np.ones((h, w, 1), np.float32)], axis=2)
        data = np.ascontiguousarray(rgba, np.float32).tobytes()
        tex = self.ctx.texture((w, h), 4, data, dtype="f4")
        tex.repeat_x = True
        tex.repeat_y = False
        tex.build_mipmaps()
        tex.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
        return tex

    @property
    def active(self) -> bool:
        return self.light is not None and self.texture is not None

    def bind(self, prog: moderngl.Program, unit: int) -> int:
        """Bind the map and set the dome uniforms on ``prog`` (when it has them);
        returns the next free texture unit."""
        lp, tex, dm = self.light, self.texture, self.map
        if lp is None or tex is None or dm is None or "u_dome_mult" not in prog:
            return unit
        split = self.split and self.rest is not None and dm.rest_sh9 is not None
        if "u_dome_map" in prog:
            (self.rest if split and self.rest is not None else tex).use(unit)
            cast(moderngl.Uniform, prog["u_dome_map"]).value = unit
        if "u_dome_sky" in prog:
            tex.use(unit + 1)
            cast(moderngl.Uniform, prog["u_dome_sky"]).value = unit + 1
        scale = np.asarray(lp.dome_scale, dtype=np.float64)
        sh9 = dm.rest_sh9 if split and dm.rest_sh9 is not None else dm.sh9
        sh = (sh9 * scale[None, :]).astype(np.float32)
        if "u_dome_sh" in prog:
            cast(moderngl.Uniform, prog["u_dome_sh"]).write(
                np.ascontiguousarray(sh, np.float32).tobytes()
            )
        set_uniform(prog, "u_dome_scale", (*scale.tolist(), float(self.levels)))
        w = float(dm.latlong.shape[1])
        set_uniform(
            prog,
            "u_dome_mult",
            (float(lp.diffuse), float(lp.specular), 1.0 if lp.camera_visible else 0.0, w),
        )
        return unit + 2

    def _release_texture(self) -> None:
        for t in (self.texture, self.rest):
            if t is not None:
                t.release()
        self.texture = self.rest = None
        self.map = None

    def release(self) -> None:
        self._release_texture()
        self.light = None
