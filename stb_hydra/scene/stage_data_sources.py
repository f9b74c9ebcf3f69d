"""The per-prim data sources of :class:`~stb_hydra.scene.stage_scene_index.StageSceneIndex`
(Hydra 2.0's data sources): a :class:`StageEntry` per scene prim, and the light, mesh,
camera and material data sources that read it on demand at the index's time. World
matrices are render-frame (Y-up metres), row-vector 4x4.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from pxr import Usd

from . import prims
from .cameras import exposure_scale, read_camera
from .geometry import MeshGeometry
from .lights import LightReadContext, read_light, set_transform
from .lights_bulk import LightItem, read_lights
from .links import LinkMasks, LinkResolver
from .materials import bound_material_path, read_material


class StageReads(Protocol):
    """What a data source reads of its scene index (``stage_index_base.StageIndexBase``)."""

    time: Usd.TimeCode
    mpu: float
    light_ctx: LightReadContext
    links: LinkResolver

    def world_matrix(self, e: StageEntry) -> np.ndarray: ...
    def is_visible(self, e: StageEntry) -> bool: ...
    def instance_transforms(self, e: StageEntry) -> np.ndarray | None: ...
    def instance_ids(self, e: StageEntry) -> np.ndarray | None: ...
    def is_dynamic(self, e: StageEntry) -> bool: ...
    def mesh_geometry(self, e: StageEntry) -> MeshGeometry | None: ...
    def geometry_key(self, e: StageEntry) -> str: ...
    def mtlx_material(self, e: StageEntry) -> prims.MaterialPrim: ...
    def warn_once(self, key: str, msg: str) -> None: ...


@dataclass(slots=True, eq=False)
class StageEntry:
    """One scene prim of the index: its scene path, prim type, USD prim and data source."""

    path: str
    prim_type: str
    prim: Usd.Prim | None  # the USD prim (or instance proxy); None for synthesised prims
    #: PointInstancer expansion this prim belongs to, with the part index.
    instancer: str | None = None
    instance_id: int = -1
    part: object = None
    ds: object = None
    #: Visibility computed during population (consumed by the first read).
    vis_hint: bool | None = None
    #: Authored property names read during population (consumed by the first
    #: light read; dropped when a notice touches the prim).
    names_hint: frozenset[str] | None = None
    #: A material read from a MaterialX document: (resolved .mtlx file, material name).
    mtlx: tuple[str, str] | None = None


class _DataSource:
    """Base of the per-prim data sources: reads on demand at the index's time."""

    __slots__ = ("entry", "index")

    def __init__(self, index: StageReads, entry: StageEntry) -> None:
        self.index = index
        self.entry = entry

    @property
    def path(self) -> str:
        return self.entry.path

    def world_matrix(self) -> np.ndarray:
        return self.index.world_matrix(self.entry)

    def visible(self) -> bool:
        """Whether the prim is shown at the index's time. The population's hint (its
        walk already knew) answers the first read only: after it, an edit or a time
        change must be read from the stage."""
        e = self.entry
        hint, e.vis_hint = e.vis_hint, None
        if hint is not None:
            return hint
        return self.index.is_visible(e)


class LightDataSource(_DataSource):
    __slots__ = ()

    def light(self) -> prims.LightPrim:
        """The full light record (params, shadow, resource, transform)."""
        e, idx = self.entry, self.index
        lp = read_light(
            e.prim,
            idx.light_ctx,
            idx.time,
            idx.world_matrix(e),
            visible=self.visible(),
            path=e.path,
            names=e.names_hint,
        )
        self._finish(lp)
        return lp

    def _finish(self, lp: prims.LightPrim) -> None:
        """What the scene index adds to a read light: its instance id and link masks
        (the entry's read hints are spent)."""
        e, idx = self.entry, self.index
        e.vis_hint = None
        e.names_hint = None
        lp.instance_id = e.instance_id
        m = idx.links.light_masks(e.path)
        lp.light_link_mask, lp.shadow_link_mask = m.light, m.shadow
        lp.default_linking = not idx.links.is_linked(e.path)

    @staticmethod
    def lights(sources: Sequence[LightDataSource]) -> list[prims.LightPrim]:
        """``[ds.light() for ds in sources]`` (same records), read in bulk
        (``scene/lights_bulk.py``): the first sync of many lights. The sources share
        one scene index."""
        if not sources:
            return []
        idx = sources[0].index
        items = [
            LightItem(
                ds.entry.prim,
                ds.entry.path,
                idx.world_matrix(ds.entry),
                ds.visible(),
                ds.entry.names_hint,
            )
            for ds in sources
        ]
        out = read_lights(items, idx.light_ctx, idx.time)
        for ds, lp in zip(sources, out, strict=True):
            ds._finish(lp)
        return out

    def link_masks(self) -> LinkMasks:
        """The light's masks over the link and shadow groups (``scene/links.py``)."""
        return self.index.links.light_masks(self.entry.path)

    def update_transform(self, lp: prims.LightPrim) -> bool:
        """Re-read only the transform into ``lp``; returns False when the world
        scale changed (shape-dependent intensity needs a full re-read)."""
        old = lp.world_scale
        set_transform(lp, self.world_matrix())
        if lp.type == prims.MESH_LIGHT or lp.dome_map is not None:
            return False  # a textured dome's map is resampled in its new orientation
        return abs(lp.world_scale - old) <= 1e-9 * max(1.0, old)


class MeshDataSource(_DataSource):
    __slots__ = ()

    def geometry(self) -> MeshGeometry | None:
        return self.index.mesh_geometry(self.entry)

    def material(self) -> str | None:
        e = self.entry
        return bound_material_path(e.prim) if e.prim is not None else None

    def instance_transforms(self) -> np.ndarray | None:
        return self.index.instance_transforms(self.entry)

    def instance_ids(self) -> np.ndarray | None:
        """PointInstancer instance id of each row of ``instance_transforms``."""
        return self.index.instance_ids(self.entry)

    def instance_rel_path(self) -> str:
        """The prototype mesh's path below its prototype root's parent ("" if none)."""
        part = self.entry.part
        return str(getattr(part, "rel_path", "")) if self.entry.instancer else ""

    def dynamic(self) -> bool:
        return self.index.is_dynamic(self.entry)

    def geometry_key(self) -> str:
        return self.index.geometry_key(self.entry)

    def link_groups(self) -> tuple[int, int]:
        """(light-link group, shadow-link group) of the mesh (``scene/links.py``)."""
        return self.index.links.mesh_groups(self.entry.path)


class CameraDataSource(_DataSource):
    __slots__ = ()

    def camera(self) -> prims.CameraPrim:
        idx = self.index
        return read_camera(
            self.entry.prim,
            idx.time,
            idx.world_matrix(self.entry),
            idx.mpu,
            lambda msg: idx.warn_once(msg, msg),
        )

    def exposure_scale(self) -> float:
        idx, path = self.index, self.entry.path
        return exposure_scale(
            self.entry.prim, idx.time, lambda msg: idx.warn_once("exposure:" + path, msg)
        )


class MaterialDataSource(_DataSource):
    __slots__ = ()

    def material(self) -> prims.MaterialPrim:
        e = self.entry
        if e.mtlx is not None:
            return self.index.mtlx_material(e)
        return read_material(e.prim, self.index.time)


_DS_FOR_TYPE = {prims.MESH: MeshDataSource, prims.CAMERA: CameraDataSource}


def data_source_class(prim_type: str):
    """The data source class that reads prims of ``prim_type``."""
    if prim_type in prims.LIGHT_TYPES:
        return LightDataSource
    if prim_type == prims.MATERIAL:
        return MaterialDataSource
    return _DS_FOR_TYPE[prim_type]
