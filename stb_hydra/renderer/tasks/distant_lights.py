"""Distant lights and ambient: the brightest DistantLight becomes the (shadowed)
sun, up to ``MAX_EXTRA_DISTANT`` more are unshadowed, dome lights add to the
ambient radiance -> the frame's ``DistantLights`` record."""

from __future__ import annotations

import numpy as np

from ...color import LUMINANCE_REC709
from ...scene import prims
from ...scene.prims import LightPrim
from ..frame import FrameContext
from ..frame_data import MAX_EXTRA_DISTANT, SunSetup
from ..graph import Imported, Rec
from ..records import DistantLights
from .base import Pass


class DistantLightsTask(Pass):
    name = "distant_lights"
    reads = (Imported("light_table"),)
    writes = (Rec(DistantLights),)

    def prepare(self, frame: FrameContext) -> None:
        t = self.delegate.light_table
        rec = DistantLights()
        rows = t.rows_of_type(prims.DISTANT_LIGHT)
        rows = rows[t.enabled[rows]]
        if len(rows):
            lum = t.intensity[rows] @ LUMINANCE_REC709
            order = rows[np.argsort(-lum, kind="stable")]
            rec.sun = self._sun(int(order[0]))
            rec.extra = [
                (
                    -t.direction[r].astype(np.float64),
                    t.intensity[r].astype(np.float64),
                    float(t.diffuse[r]),
                    float(t.specular[r]),
                )
                for r in order[1 : 1 + MAX_EXTRA_DISTANT]
            ]
            rec.rows = tuple(int(r) for r in order[: 1 + MAX_EXTRA_DISTANT])
            if len(order) > 1 + MAX_EXTRA_DISTANT:
                frame.warn(
                    f"{len(order)} distant lights: only the {1 + MAX_EXTRA_DISTANT} brightest"
                    " are used"
                )
        domes = t.rows_of_type(prims.DOME_LIGHT)
        domes = domes[t.enabled[domes]]
        rec.dome_rows = tuple(int(r) for r in domes)
        rec.dome = self._textured_dome(domes, frame)
        if rec.dome is not None:  # lit by its map (renderer/dome_env.py), not its mean
            domes = domes[domes != t.rows[rec.dome.path]]
        amb = t.intensity[domes].sum(axis=0).astype(np.float64) if len(domes) else np.zeros(3)
        rec.ambient = amb + frame.settings.ambient
        dm = rec.dome.dome_map if rec.dome is not None else None
        if (
            rec.dome is not None
            and dm is not None
            and dm.sun_direction is not None
            and not rec.sun.enabled
            and not t.has_light_links()
        ):
            rec.sun = self._dome_sun(rec.dome)
            rec.rows = (int(t.rows[rec.dome.path]),)
            rec.dome_sun = True
        self.delegate.dome_env.update(rec.dome, rec.dome_sun)
        frame.put(rec)

    @staticmethod
    def _dome_sun(lp: LightPrim) -> SunSetup:
        """The sun split off a dome's map as the shadowed sun (its light's multipliers
        and shadow inputs)."""
        dm = lp.dome_map
        assert dm is not None and dm.sun_direction is not None
        assert dm.sun_illuminance is not None
        sun = SunSetup()
        sun.direction_to_sun = np.asarray(dm.sun_direction, dtype=np.float64)
        sun.illuminance = dm.sun_illuminance * np.asarray(lp.dome_scale, dtype=np.float64)
        sun.enabled = True
        sun.shadow = bool(lp.shadow_enable)
        sun.diffuse, sun.specular = float(lp.diffuse), float(lp.specular)
        sun.shadow_color = np.asarray(lp.shadow_color, dtype=np.float64)
        return sun

    def _textured_dome(self, rows: np.ndarray, frame: FrameContext) -> LightPrim | None:
        """The brightest enabled dome with a texture map (the others with one light as
        their solid-angle mean, with one warning)."""
        t = self.delegate.light_table
        found: list[LightPrim] = []
        for r in rows:  # a handful of domes at most
            sprim = self.delegate.lights.get(t.paths[int(r)] or "")
            lp = sprim.light if sprim is not None else None
            if lp is not None and lp.dome_map is not None:
                found.append(lp)
        if not found:
            return None
        found.sort(key=lambda lp: -float(np.asarray(lp.intensity) @ LUMINANCE_REC709))
        if len(found) > 1:
            frame.warn(
                f"{len(found)} textured dome lights: only <{found[0].path}> lights with its"
                " texture, the others with their mean"
            )
        return found[0]

    def _sun(self, r: int) -> SunSetup:
        t = self.delegate.light_table
        sun = SunSetup()
        sun.direction_to_sun = -t.direction[r].astype(np.float64)
        sun.illuminance = t.intensity[r].astype(np.float64)
        sun.enabled = True
        sun.shadow = bool(t.shadow_enable[r])
        sun.diffuse, sun.specular = float(t.diffuse[r]), float(t.specular[r])
        sun.shadow_color = t.shadow_color[r].astype(np.float64)
        return sun
