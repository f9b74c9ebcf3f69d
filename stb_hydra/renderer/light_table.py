"""Structure-of-arrays store of every light, one row per light render prim.

Light sprims write their row on sync; culling, shadow scheduling and the GPU
packing read whole columns with numpy (no per-light Python loop in the frame
path). Rows are recycled through a free list; ``version`` increases on every
write so consumers can upload only what changed.

Units: metres, candela (local lights), lux (distant), nits (dome), radians.
"""

from __future__ import annotations

import math

import numpy as np

from ..scene import prims
from ..scene.lights import influence_range
from ..scene.links import ALL_GROUPS, LinkMasks
from ..scene.prims import NO_CONE_CUTOFF_RAD, LightPrim
from . import shader_constants as sc

TYPE_CODES = {t: i for i, t in enumerate(prims.LIGHT_TYPES)}
LOCAL_TYPE_CODES = np.array([TYPE_CODES[t] for t in prims.LOCAL_LIGHT_TYPES], dtype=np.int8)

_COLUMNS: dict[str, tuple[tuple[int, ...], type, object]] = {
    "position": ((3,), np.float64, 0.0),
    "direction": ((3,), np.float32, 0.0),
    "tangent": ((3,), np.float32, 0.0),
    "intensity": ((3,), np.float32, 0.0),
    "range": ((), np.float32, 0.0),
    "range_authored": ((), np.bool_, False),
    "peak_intensity": ((), np.float32, 0.0),  # cd, luminance-weighted
    "flux": ((), np.float32, 0.0),
    "type": ((), np.int8, -1),
    "emission": ((), np.int8, 0),
    "enabled": ((), np.bool_, False),
    "live": ((), np.bool_, False),
    "cone_cutoff": ((), np.float32, NO_CONE_CUTOFF_RAD),  # radians
    "cone_start": ((), np.float32, NO_CONE_CUTOFF_RAD),  # radians, smoothstep start
    "focus": ((), np.float32, 0.0),
    "focus_tint": ((3,), np.float32, 0.0),
    "ies_layer": ((), np.int32, -1),
    "ies_scale": ((), np.float32, 1.0),
    "ies_angle_scale": ((), np.float32, 0.0),
    # RectLight texture (issue 37): layer of the delegate's rect texture array (-1:
    # none; the light emits its mean, ``intensity``), and whether the camera sees it.
    "texture_layer": ((), np.int32, -1),
    "camera_visible": ((), np.bool_, True),
    "diffuse": ((), np.float32, 1.0),
    "specular": ((), np.float32, 1.0),
    "shadow_enable": ((), np.bool_, False),
    "shadow_dynamic": ((), np.bool_, False),
    "static": ((), np.bool_, False),  # stb:mobility = static
    "baked": ((), np.bool_, False),  # stb:baked: lit by the lightmaps, not per frame
    "shadow_color": ((3,), np.float32, 0.0),
    "shadow_distance": ((), np.float32, -1.0),
    "shadow_falloff": ((), np.float32, -1.0),
    "shadow_falloff_gamma": ((), np.float32, 1.0),
    "radius": ((), np.float32, 0.0),
    "angle": ((), np.float32, 0.0),  # distant light angular diameter, degrees
    # Area lights (common/area.glsl): half sizes (m: rect w/2, h/2; disk, sphere r, 0;
    # cylinder length/2, r), shape code (shader_constants.AREA_*), radiance per cd of
    # ``intensity`` (1 / projected area along the axis, m^-2).
    "area_size": ((2,), np.float32, 0.0),
    "area_kind": ((), np.int8, 0),
    "area_radiance": ((), np.float32, 0.0),
    # Light / shadow linking (scene/links.py): masks over the link and shadow groups
    # (every bit set: the light lights / is shadowed by everything).
    "light_link_mask": ((), np.uint32, ALL_GROUPS),
    "shadow_link_mask": ((), np.uint32, ALL_GROUPS),
    "version": ((), np.int64, 0),
}


_AREA_KINDS = {
    prims.RECT_LIGHT: sc.AREA_RECT,
    prims.DISK_LIGHT: sc.AREA_DISK,
    prims.SPHERE_LIGHT: sc.AREA_SPHERE,
    prims.CYLINDER_LIGHT: sc.AREA_CYLINDER,
}


def area_shape(lp: LightPrim) -> tuple[int, tuple[float, float], float]:
    """(shape code, half sizes (m), radiance per cd along the axis (m^-2)) of a light.

    Code ``AREA_POINT`` (point model) for ``treatAsPoint``, mesh lights and a zero
    projected area; otherwise the light is integrated over its area."""
    kind = _AREA_KINDS.get(lp.type, sc.AREA_POINT)
    if lp.treat_as_point or kind == sc.AREA_POINT:
        return sc.AREA_POINT, (0.0, 0.0), 0.0
    if kind == sc.AREA_RECT:
        size, proj = (0.5 * lp.width, 0.5 * lp.height), lp.width * lp.height
    elif kind == sc.AREA_CYLINDER:
        size, proj = (0.5 * lp.length, lp.radius), 2.0 * lp.radius * lp.length
    else:
        size, proj = (lp.radius, lp.radius), math.pi * lp.radius**2
    if not (proj > 0.0 and math.isfinite(proj)):
        return sc.AREA_POINT, (0.0, 0.0), 0.0
    return kind, size, 1.0 / proj


class LightTable:
    def __init__(self, capacity: int = 64) -> None:
        #: Camera exposure scale the automatic ranges are computed for.
        self.exposure_scale = 1.0
        self.capacity = 0
        self.cols: dict[str, np.ndarray] = {}
        self._free: list[int] = []
        self._n_rows = 0  # high-water mark
        self.rows: dict[str, int] = {}
        self.paths: list[str | None] = []
        self.version = 0  # bumped on any write/free
        self._links_key = -1
        self._links = False
        self._grow(max(capacity, 1))

    def __len__(self) -> int:
        return len(self.rows)

    @property
    def n_rows(self) -> int:
        """Rows in use or freed (columns are valid up to this index)."""
        return self._n_rows

    def _grow(self, cap: int) -> None:
        for name, (shape, dtype, fill) in _COLUMNS.items():
            new: np.ndarray = np.full((cap, *shape), fill, dtype=dtype)
            old = self.cols.get(name)
            if old is not None:
                new[: len(old)] = old
            self.cols[name] = new
        self.paths.extend([None] * (cap - self.capacity))
        self.capacity = cap

    def __getattr__(self, name: str) -> np.ndarray:
        cols = self.__dict__.get("cols")
        if cols is not None and name in cols:
            return cols[name][: self._n_rows]
        raise AttributeError(name)

    def alloc(self, path: str) -> int:
        if path in self.rows:
            return self.rows[path]
        if self._free:
            row = self._free.pop()
        else:
            if self._n_rows >= self.capacity:
                self._grow(self.capacity * 2)
            row = self._n_rows
            self._n_rows += 1
        self.rows[path] = row
        self.paths[row] = path
        self.cols["live"][row] = True
        return row

    def free(self, path: str) -> None:
        row = self.rows.pop(path, None)
        if row is None:
            return
        for name, (_shape, _dtype, fill) in _COLUMNS.items():
            if name != "version":
                self.cols[name][row] = fill
        self.paths[row] = None
        self._free.append(row)
        self.version += 1
        self.cols["version"][row] = self.version

    def set_exposure(self, exposure_scale: float) -> int:
        """Rescale the automatic influence ranges to a camera exposure (a brighter
        exposure sees dimmer light, so ranges grow as sqrt(exposure)). Authored
        ``stb:range`` values stay. Returns the number of rows changed (their version
        moves, so the light buffer and the shadow maps follow)."""
        s = float(exposure_scale)
        if not (math.isfinite(s) and s > 0.0) or s == self.exposure_scale:
            return 0
        self.exposure_scale = s
        c = self.cols
        n = self._n_rows
        local = c["live"][:n] & np.isin(c["type"][:n], LOCAL_TYPE_CODES)
        rows = np.nonzero(local & ~c["range_authored"][:n])[0]
        if len(rows):
            c["range"][rows] = influence_range(c["peak_intensity"][rows], s)
            self.version += 1
            c["version"][rows] = self.version
        return len(rows)

    def write(self, row: int, lp: LightPrim, ies_layer: int = -1, texture_layer: int = -1) -> None:
        """Copy a light record into its row (``texture_layer``: its RectLight texture's
        layer, -1 none)."""
        c = self.cols
        c["position"][row] = lp.position
        c["direction"][row] = lp.direction
        c["tangent"][row] = lp.tangent
        c["intensity"][row] = lp.intensity
        c["range_authored"][row] = lp.range_authored
        c["peak_intensity"][row] = lp.peak_intensity
        if not math.isfinite(lp.range):
            c["range"][row] = np.float32(3.0e38)
        elif lp.range_authored or lp.type not in prims.LOCAL_LIGHT_TYPES:
            c["range"][row] = lp.range
        else:
            c["range"][row] = influence_range(lp.peak_intensity, self.exposure_scale)
        c["flux"][row] = lp.flux
        c["type"][row] = TYPE_CODES[lp.type]
        c["emission"][row] = lp.emission
        c["enabled"][row] = lp.enabled
        if lp.has_cone:
            cut = math.radians(lp.cone_angle)
            c["cone_cutoff"][row] = cut
            c["cone_start"][row] = cut * (1.0 - lp.cone_softness)
        else:
            c["cone_cutoff"][row] = c["cone_start"][row] = NO_CONE_CUTOFF_RAD
        c["focus"][row] = lp.focus
        c["focus_tint"][row] = lp.focus_tint
        c["ies_layer"][row] = ies_layer
        c["ies_scale"][row] = lp.ies_scale if ies_layer >= 0 else 1.0
        c["ies_angle_scale"][row] = lp.ies_angle_scale
        c["texture_layer"][row] = texture_layer
        c["camera_visible"][row] = lp.camera_visible
        c["diffuse"][row] = lp.diffuse
        c["specular"][row] = lp.specular
        c["shadow_enable"][row] = lp.shadow_enable
        c["shadow_dynamic"][row] = lp.shadow_update == prims.SHADOW_DYNAMIC
        c["static"][row] = lp.mobility == prims.MOBILITY_STATIC
        c["baked"][row] = lp.baked
        c["shadow_color"][row] = lp.shadow_color
        c["shadow_distance"][row] = lp.shadow_distance
        c["shadow_falloff"][row] = lp.shadow_falloff
        c["shadow_falloff_gamma"][row] = lp.shadow_falloff_gamma
        c["radius"][row] = lp.radius
        c["angle"][row] = lp.angle
        kind, size, rad = area_shape(lp)
        c["area_kind"][row] = kind
        c["area_size"][row] = size
        c["area_radiance"][row] = rad
        c["light_link_mask"][row] = lp.light_link_mask
        c["shadow_link_mask"][row] = lp.shadow_link_mask
        self.version += 1
        c["version"][row] = self.version

    def write_many(
        self,
        rows: np.ndarray,
        lps: list[LightPrim],
        ies_layers: np.ndarray,
        texture_layers: np.ndarray | None = None,
    ) -> None:
        """``write(rows[i], lps[i], ies_layers[i], texture_layers[i])`` for every i,
        column by column (the first sync of many lights: no per-light numpy calls).
        One version for all."""
        n = len(lps)
        if n == 0:
            return
        rows = np.asarray(rows, dtype=np.int64)
        c = self.cols

        def col(name: str) -> list:
            return [getattr(lp, name) for lp in lps]

        for name in ("position", "direction", "tangent", "intensity", "focus_tint"):
            c[name][rows] = np.array(col(name), dtype=np.float64).reshape(n, 3)
        c["shadow_color"][rows] = np.array(col("shadow_color"), dtype=np.float64).reshape(n, 3)
        local = np.array([lp.type in prims.LOCAL_LIGHT_TYPES for lp in lps], dtype=bool)
        authored = np.array(col("range_authored"), dtype=bool)
        peak = np.array(col("peak_intensity"), dtype=np.float64)
        rng = np.array(col("range"), dtype=np.float64)
        auto = local & ~authored
        if auto.any():
            rng[auto] = influence_range(peak[auto], self.exposure_scale)
        rng[~np.isfinite(rng)] = 3.0e38
        c["range"][rows] = rng
        c["range_authored"][rows] = authored
        c["peak_intensity"][rows] = peak
        c["flux"][rows] = col("flux")
        c["type"][rows] = [TYPE_CODES[t] for t in col("type")]
        c["emission"][rows] = col("emission")
        c["enabled"][rows] = col("enabled")
        has_cone = np.array(col("has_cone"), dtype=bool)
        cut = np.radians(np.array(col("cone_angle"), dtype=np.float64))
        start = cut * (1.0 - np.array(col("cone_softness"), dtype=np.float64))
        c["cone_cutoff"][rows] = np.where(has_cone, cut, NO_CONE_CUTOFF_RAD)
        c["cone_start"][rows] = np.where(has_cone, start, NO_CONE_CUTOFF_RAD)
        c["focus"][rows] = col("focus")
        layers = np.asarray(ies_layers, dtype=np.int32)
        c["ies_layer"][rows] = layers
        c["ies_scale"][rows] = np.where(layers >= 0, np.array(col("ies_scale")), 1.0)
        c["ies_angle_scale"][rows] = col("ies_angle_scale")
        c["texture_layer"][rows] = -1 if texture_layers is None else texture_layers
        c["camera_visible"][rows] = col("camera_visible")
        c["diffuse"][rows] = col("diffuse")
        c["specular"][rows] = col("specular")
        c["shadow_enable"][rows] = col("shadow_enable")
        c["shadow_dynamic"][rows] = [u == prims.SHADOW_DYNAMIC for u in col("shadow_update")]
        c["static"][rows] = [m == prims.MOBILITY_STATIC for m in col("mobility")]
        c["baked"][rows] = col("baked")
        for name in ("shadow_distance", "shadow_falloff", "shadow_falloff_gamma", "radius"):
            c[name][rows] = col(name)
        c["angle"][rows] = col("angle")
        shapes = [area_shape(lp) for lp in lps]
        c["area_kind"][rows] = [k for k, _, _ in shapes]
        c["area_size"][rows] = np.array([sz for _, sz, _ in shapes], dtype=np.float64)
        c["area_radiance"][rows] = [r for _, _, r in shapes]
        c["light_link_mask"][rows] = col("light_link_mask")
        c["shadow_link_mask"][rows] = col("shadow_link_mask")
        self.version += 1
        c["version"][rows] = self.version

    def set_link_masks(self, row: int, masks: LinkMasks) -> None:
        """A light's link masks changed (its collection, or the groups moved)."""
        c = self.cols
        c["light_link_mask"][row] = masks.light
        c["shadow_link_mask"][row] = masks.shadow
        self.version += 1
        c["version"][row] = self.version

    def has_light_links(self) -> bool:
        """Some light lights less than everything: the G-buffer carries link groups and
        the lighting shaders test masks (cached per table version)."""
        if self._links_key != self.version:
            n = self._n_rows
            c = self.cols
            self._links = bool(np.any(c["live"][:n] & (c["light_link_mask"][:n] != ALL_GROUPS)))
            self._links_key = self.version
        return self._links

    def write_transform(self, row: int, lp: LightPrim) -> None:
        c = self.cols
        c["position"][row] = lp.position
        c["direction"][row] = lp.direction
        c["tangent"][row] = lp.tangent
        self.version += 1
        c["version"][row] = self.version

    def set_enabled(self, row: int, enabled: bool) -> None:
        self.cols["enabled"][row] = enabled
        self.version += 1
        self.cols["version"][row] = self.version

    def local_mask(self) -> np.ndarray:
        """Rows holding enabled local (point-like) lights."""
        n = self._n_rows
        return (
            self.cols["live"][:n]
            & self.cols["enabled"][:n]
            & np.isin(self.cols["type"][:n], LOCAL_TYPE_CODES)
        )

    def rows_of_type(self, light_type: str) -> np.ndarray:
        n = self._n_rows
        m = self.cols["live"][:n] & (self.cols["type"][:n] == TYPE_CODES[light_type])
        return np.nonzero(m)[0]
