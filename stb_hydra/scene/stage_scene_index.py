"""``StageSceneIndex``: a Usd.Stage as a Hydra 2.0-style scene index.

The index is four layers, one file each:

* ``stage_data_sources``: a :class:`StageEntry` per scene prim and the data sources
  (light, mesh, camera, material) that read it on demand at the index's time;
* ``stage_index_base``: the prim table, time, caches and render frame, and the
  world-state reads the data sources make;
* ``stage_population``: population traverses the stage once (instance proxies
  included), classifies prims, expands PointInstancers, and records which prims have
  time-varying data and which locators vary (own or ancestor transforms, visibility,
  attributes);
* ``stage_changes``: ``Usd.Notice.ObjectsChanged`` notices are queued as they arrive and
  applied by :meth:`apply_pending_updates`: resynced subtrees are removed and re-added,
  value edits become ``PrimsDirtied`` with the locators they touch (transform and
  visibility edits reach every descendant); :meth:`set_time` dirties only what varies
  in time.

The render frame is Y-up metres: ``render_from_stage`` folds ``upAxis`` and
``metersPerUnit`` into every world matrix this index hands out.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Iterator

from pxr import Tf, Usd

from . import prims
from .scene_index import SceneIndexPrim
from .stage_changes import StageChanges
from .stage_data_sources import (
    CameraDataSource,
    LightDataSource,
    MaterialDataSource,
    MeshDataSource,
    StageEntry,
)
from .stage_index_base import LightFilter, render_from_stage_matrix

__all__ = [
    "CameraDataSource",
    "LightDataSource",
    "MaterialDataSource",
    "MeshDataSource",
    "StageEntry",
    "StageSceneIndex",
    "render_from_stage_matrix",
]


class StageSceneIndex(StageChanges):
    """Scene index over a ``Usd.Stage``. See the module docstring."""

    def __init__(
        self,
        stage: Usd.Stage,
        time: float | Usd.TimeCode | None = None,
        *,
        light_filter: LightFilter | None = None,
    ) -> None:
        """``light_filter``: which light prims to add (None: every one; see
        ``stage_index_base.LightFilter``)."""
        super().__init__(stage, time)
        self._light_filter = light_filter
        self._listener = Tf.Notice.Register(Usd.Notice.ObjectsChanged, self._on_changed, stage)
        self._populate_all()

    @property
    def skipped_lights(self) -> int:
        """How many lights the light filter left out (a PointInstancer's: one per
        instance; 0: the index holds every light of the stage)."""
        return sum(self._skipped_lights.values())

    def set_light_filter(self, light_filter: LightFilter | None) -> None:
        """Change which light prims the index holds; when lights were left out before,
        the stage is populated again (PrimsRemoved of everything, then PrimsAdded)."""
        had_skipped = bool(self._skipped_lights)
        self._light_filter = light_filter
        if had_skipped or light_filter is not None:
            self._full_rebuild()

    # -- SceneIndex queries --
    def get_prim(self, path: str) -> SceneIndexPrim | None:
        e = self._entries.get(path)
        if e is None:
            return None
        return SceneIndexPrim(e.prim_type, e.ds)

    def prim_paths(self) -> Iterator[str]:
        return iter(list(self._entries))

    def __len__(self) -> int:
        return len(self._entries)

    def counts_by_type(self) -> dict[str, int]:
        out: dict[str, int] = defaultdict(int)
        for e in self._entries.values():
            out[e.prim_type] += 1
        return dict(out)

    def time_varying_paths(self) -> dict[str, frozenset[str]]:
        return {p: frozenset(s) for p, s in self._time_varying.items()}

    # -- convenience --
    def cameras(self) -> list[str]:
        return sorted(p for p, e in self._entries.items() if e.prim_type == prims.CAMERA)

    def light_paths(self) -> list[str]:
        return [p for p, e in self._entries.items() if e.prim_type in prims.LIGHT_TYPES]

    def close(self) -> None:
        if self._listener is not None:
            self._listener.Revoke()
            self._listener = None
