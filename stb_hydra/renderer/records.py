"""Typed per-frame records passed between passes on the frame context.

Each record has one producing pass (see ``graph.py``); passes read them with
``frame.get(RecordClass)`` and write them with ``frame.put(record)``, both checked
against the pass's declarations. They live for one frame; GPU objects they point
to are owned by the delegate or by the producing pass.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import moderngl
import numpy as np

from ..scene.prims import LightPrim
from .frame_data import SunSetup


@dataclass
class DistantLights:
    """The shadowed sun (brightest DistantLight), up to 3 more distant lights
    (direction to the light, illuminance lux RGB, diffuse, specular) and the
    ambient radiance (nits, dome lights + settings.ambient). World space."""

    sun: SunSetup = field(default_factory=SunSetup)
    extra: list = field(default_factory=list)
    ambient: np.ndarray = field(default_factory=lambda: np.zeros(3))
    #: Light-table rows: the sun then the extra distant lights (their order above),
    #: and the enabled dome lights (light linking reads their masks).
    rows: tuple[int, ...] = ()
    dome_rows: tuple[int, ...] = ()
    #: The textured dome this frame lights with (``renderer/dome_env.py``; its mean is
    #: then not in ``ambient``), else None.
    dome: LightPrim | None = None
    #: ``sun`` is the dome's own sun (``DomeMap.sun_direction``): the real-time methods
    #: light the rest of the map from ``DomeMap.rest``; the reference skips ``sun``.
    dome_sun: bool = False


@dataclass
class InViewLights:
    """Lights whose influence sphere meets the view frustum, in light-buffer order.

    ``rows``: light-table rows (SSBO index i = rows[i]); the feature flags say
    whether any of them has a cone / an IES profile (shader variants);
    ``point_count``: the first ``point_count`` lights have no extent (the exact
    methods' point-only loop, ``u_point_lights``), 0 when the order is not split;
    ``sphere_count``: the next ``sphere_count`` are sphere lights narrow against every
    lobe (their loop ends at ``u_sphere_end`` = point_count + sphere_count), then
    ``wide_sphere_count`` other sphere lights (up to ``u_wide_sphere_end``)."""

    rows: np.ndarray
    has_cones: bool = False
    has_ies: bool = False
    #: Some of them has a focus > 0 (a focusTint blend; light buffer ``cone.w``). True
    #: unless the producer checked: without it, methods compile ``NO_FOCUS`` (the
    #: focus ``pow`` left out of ``light_tint_rgb``: on llvmpipe an ``if`` body runs for
    #: every light, issue 34).
    has_focus: bool = True
    #: Some of them is a CylinderLight shaded as one (area kind ``AREA_CYLINDER``). True
    #: unless the producer checked: without it, methods compile ``NO_CYLINDER_LIGHTS``
    #: (the cylinder's vertices and their per-vertex ``cos`` / ``sin`` left out of the
    #: exact methods' streamed polygon, common/area.glsl).
    has_cylinders: bool = True
    #: Some of them is a textured RectLight (``RECT_TEXTURES``).
    has_rect_textures: bool = False
    point_count: int = 0
    sphere_count: int = 0
    wide_sphere_count: int = 0
    #: The first ``sphere_unshadowed`` narrow spheres, and the first ``tail_unshadowed``
    #: lights after them (wide spheres and the rest), have no shadows
    #: (``light_buffer.unshadowed_first``; 0 when the order is not split).
    sphere_unshadowed: int = 0
    tail_unshadowed: int = 0

    @property
    def count(self) -> int:
        return len(self.rows)


@dataclass
class ShadowSlots:
    """Shadow-map record slot per in-view light (-1: unshadowed this frame) and the
    atlas objects to bind: the 16-bit atlas texture and the record SSBO (binding 1).
    ``maps`` None: local shadows are off for this frame."""

    maps: np.ndarray | None = None
    atlas: moderngl.Texture | None = None
    records: moderngl.Buffer | None = None

    @property
    def any(self) -> bool:
        return self.maps is not None and bool(np.any(self.maps >= 0))


@dataclass
class SunShadowMap:
    """The sun's shadow depth texture (None: no sun shadow this frame)."""

    texture: moderngl.Texture | None = None


@dataclass
class LightBuffer:
    """The uploaded in-view light SSBO (binding 0) and what the upload did; with light
    linking (``links``) also the link SSBO (``SSBO_LIGHT_LINKS``: masks of the in-view
    lights in the same order, of the distant lights, ambient per link group)."""

    ssbo: moderngl.Buffer | None
    count: int
    has_shadows: bool = False
    uploaded: bool = False
    links: bool = False
    link_ssbo: moderngl.Buffer | None = None


@dataclass
class SceneColor:
    """Name of the render buffer holding the frame's scene-linear colour
    (``lighting``, or the accumulation buffer once averaged)."""

    buffer: str = "lighting"


@dataclass
class FrameBlock:
    """The per-frame uniform block has been written and bound (binding 0)."""

    big_tiles: tuple[int, int] = (0, 0)
