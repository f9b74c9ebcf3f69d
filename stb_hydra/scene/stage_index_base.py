"""The state and read side of :class:`~stb_hydra.scene.stage_scene_index.StageSceneIndex`
(:class:`StageIndexBase`): the prim table, the time and caches, the render frame, and the
world-state reads its data sources make (world matrices, visibility, instancing, mesh
geometry and the primvars a material asks for).

The render frame is Y-up metres: ``render_from_stage`` folds ``upAxis`` and
``metersPerUnit`` into every world matrix handed out (row-vector 4x4).
"""

from __future__ import annotations

import bisect
import math
from collections import defaultdict
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from pxr import Sdf, Tf, Usd, UsdGeom

from . import locators as loc
from . import materialx as mtlx
from . import prims
from .geometry import DEFAULT_PRIMVARS, MeshGeometry, PrimvarRequest, read_mesh_geometry
from .instancing import InstancerExpansion
from .lights import LightReadContext
from .links import LinkResolver
from .materials import bound_material_path
from .scene_index import SceneIndex
from .stage_data_sources import StageEntry

#: ``(light type, the prim's authored property names) -> add it?``: which light prims
#: population adds (a render delegate's supported sprim types, Hydra's
#: ``HdRenderDelegate::GetSupportedSprimTypes``, refined by what a light needs: see
#: ``renderer.engine``). Prims that are meshes too (MeshLightAPI) keep their mesh.
LightFilter = Callable[[str, frozenset[str]], bool]

_Z_TO_Y = np.array(
    [[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, -1.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]]
)


def render_from_stage_matrix(stage: Usd.Stage) -> np.ndarray:
    """Stage units/up-axis -> render frame (Y-up metres), row-vector 4x4."""
    mpu = float(UsdGeom.GetStageMetersPerUnit(stage)) or 0.01
    if not math.isfinite(mpu) or mpu <= 0:
        mpu = 0.01
    m = np.diag([mpu, mpu, mpu, 1.0])
    if UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z:
        m = m @ _Z_TO_Y
    return m


def _gf_to_np(m) -> np.ndarray:
    return np.array(m, dtype=np.float64).reshape(4, 4)


#: Material inputs a float3 primvar may drive (the others take a float).
_COLOR_INPUTS = frozenset({"diffuseColor", "emissiveColor", "specularColor"})


@dataclass
class PendingNotices:
    """USD notices queued until ``apply_pending_updates``."""

    resynced: list[Sdf.Path] = field(default_factory=list)
    changed: list[Sdf.Path] = field(default_factory=list)


class StageIndexBase(SceneIndex):
    """A scene index's state over a ``Usd.Stage`` and the reads of its data sources."""

    def __init__(self, stage: Usd.Stage, time: float | Usd.TimeCode | None = None) -> None:
        super().__init__()
        self.stage = stage
        self.time = self._resolve_time(time)
        self.warnings: list[str] = []
        self._warned_once: set[str] = set()
        self.xform_cache = UsdGeom.XformCache(self.time)
        self._entries: dict[str, StageEntry] = {}
        self._sorted: list[str] = []
        self._sorted_valid = False
        #: path -> locators that vary in time
        self._time_varying: dict[str, set[str]] = {}
        #: USD prim path (str) -> scene paths derived from it (instancer lights, ...)
        self._derived: dict[str, list[str]] = defaultdict(list)
        self._instancers: dict[str, InstancerExpansion] = {}
        #: prototype root path -> instancer paths that use it
        self._proto_users: dict[str, set[str]] = defaultdict(set)
        self._geom_cache: dict[tuple[str, PrimvarRequest], MeshGeometry | None] = {}
        #: Scene path -> MaterialPrim read for primvar requests (see material_record).
        self._material_cache: dict[str, prims.MaterialPrim | None] = {}
        #: Parsed .mtlx documents (per resolved file) and the prims referencing one.
        self._mtlx_docs = mtlx.MtlxDocumentCache()
        self._mtlx_prims: set[str] = set()
        self._pending = PendingNotices()
        #: Light/shadow linking: link groups of meshes, masks of lights.
        self.links = LinkResolver(stage, self.warn_once)
        self._update_frame()
        self._listener: Tf.Listener | None = None
        #: Which light prims population adds (None: all); see ``LightFilter``.
        self._light_filter: LightFilter | None = None
        #: USD prim paths of the lights ``_light_filter`` left out (a property edit on
        #: one re-traverses it: the edit may make the filter keep it).
        self._skipped_lights: dict[str, int] = {}

    # -- configuration --
    def _resolve_time(self, time) -> Usd.TimeCode:
        if isinstance(time, Usd.TimeCode):
            return time
        if time is not None:
            return Usd.TimeCode(float(time))
        if self.stage.HasAuthoredTimeCodeRange():
            return Usd.TimeCode(self.stage.GetStartTimeCode())
        return Usd.TimeCode.EarliestTime()

    def _update_frame(self) -> None:
        self.render_from_stage = render_from_stage_matrix(self.stage)
        #: Y-up metre stages need no conversion (skip a 4x4 product per read).
        self._frame_is_identity = bool(np.array_equal(self.render_from_stage, np.eye(4)))
        self.mpu = float(np.linalg.norm(self.render_from_stage[0, :3]))
        self.light_ctx = LightReadContext(
            self.stage, self.render_from_stage, self._warn, self.warn_once
        )

    def _warn(self, msg: str) -> None:
        self.warnings.append(msg)

    def warn_once(self, key: str, msg: str) -> None:
        """Add ``msg`` to :attr:`warnings` the first time ``key`` warns."""
        if key not in self._warned_once:
            self._warned_once.add(key)
            self.warnings.append(msg)

    # -- world state helpers used by data sources --
    def world_matrix(self, e: StageEntry) -> np.ndarray:
        if e.instancer is not None and e.prim_type in prims.LIGHT_TYPES:
            exp = self._instancers.get(e.instancer)
            ip = self.stage.GetPrimAtPath(e.instancer)
            inst_world = _gf_to_np(self.xform_cache.GetLocalToWorldTransform(ip))
            row = int(np.nonzero(exp.instance_ids == e.instance_id)[0][0]) if exp else 0
            m = e.part.local @ exp.instance_xforms[row] @ inst_world
            return m @ self.render_from_stage
        m = _gf_to_np(self.xform_cache.GetLocalToWorldTransform(e.prim))
        return m if self._frame_is_identity else m @ self.render_from_stage

    def is_visible(self, e: StageEntry) -> bool:
        prim = e.prim
        if e.instancer is not None:
            prim = self.stage.GetPrimAtPath(e.instancer)
        img = UsdGeom.Imageable(prim)
        if not img:
            return True
        return img.ComputeVisibility(self.time) != UsdGeom.Tokens.invisible

    def instance_transforms(self, e: StageEntry) -> np.ndarray | None:
        if e.instancer is None:
            return None
        exp = self._instancers[e.instancer]
        ip = self.stage.GetPrimAtPath(e.instancer)
        inst_world = _gf_to_np(self.xform_cache.GetLocalToWorldTransform(ip))
        rows = exp.proto_of_instance == e.part.proto_index
        m = exp.instance_xforms[rows]
        return e.part.local[None] @ m @ (inst_world @ self.render_from_stage)[None]

    def instance_ids(self, e: StageEntry) -> np.ndarray | None:
        if e.instancer is None:
            return None
        exp = self._instancers[e.instancer]
        return exp.instance_ids[exp.proto_of_instance == e.part.proto_index].copy()

    def is_dynamic(self, e: StageEntry) -> bool:
        """``stb:dynamic`` on the prim or an ancestor, else time-varying transform/points."""
        p = e.prim
        while p and p.GetPath() != Sdf.Path.absoluteRootPath:
            a = p.GetAttribute("stb:dynamic")
            if a and a.HasAuthoredValue():
                return bool(a.Get())
            p = p.GetParent()
        tv = self._time_varying.get(e.path, ())
        return loc.XFORM in tv or loc.POINTS in tv or loc.INSTANCER in tv

    def material_record(self, path: str | None) -> prims.MaterialPrim | None:
        """The material at scene path ``path`` as its data source reads it (cached
        until the next edit or time change), or None."""
        if path is None:
            return None
        if path in self._material_cache:
            return self._material_cache[path]
        e = self._entries.get(path)
        mp = None
        if e is not None and e.prim_type == prims.MATERIAL:
            try:
                mp = e.ds.material()  # type: ignore[attr-defined]
            except Exception:  # noqa: BLE001 - the material sprim reports it
                mp = None
        self._material_cache[path] = mp
        return mp

    def primvar_request(self, e: StageEntry) -> PrimvarRequest:
        """The primvars mesh ``e``'s bound material reads (texture coordinates first,
        then ``st``; one float3 and one float ``UsdPrimvarReader`` primvar)."""
        mpath = bound_material_path(e.prim) if e.prim is not None else None
        mp = self.material_record(mpath)
        if mp is None or (not mp.textures and not mp.primvars):
            return DEFAULT_PRIMVARS
        uv = tuple(dict.fromkeys((*mp.st_primvars, "st")))
        vec3 = scalar = None
        for name, ref in sorted(mp.primvars.items()):
            if ref.name == "displayColor":
                continue  # the vertex colour
            if name in _COLOR_INPUTS:
                vec3 = vec3 or ref.name
            else:
                scalar = scalar or ref.name
        return PrimvarRequest(uv, vec3, scalar)

    def mesh_geometry(self, e: StageEntry) -> MeshGeometry | None:
        prim = e.prim
        proto = str(prim.GetPrimInPrototype().GetPath()) if prim.IsInstanceProxy() else e.path
        request = self.primvar_request(e)
        key = (proto, request)
        if key in self._geom_cache and not self._is_tv_geometry(e):
            return self._geom_cache[key]
        try:
            g = read_mesh_geometry(prim, self.time, request)
        except Exception as exc:  # noqa: BLE001 - bad geometry must not crash
            self._warn(f"mesh <{e.path}>: could not be read ({exc}); skipped")
            g = None
        if g is not None:
            for w in g.warnings:
                self._warn(w)
        self._geom_cache[key] = g
        return g

    def geometry_key(self, e: StageEntry) -> str:
        prim = e.prim
        return str(prim.GetPrimInPrototype().GetPath()) if prim.IsInstanceProxy() else e.path

    def _is_tv_geometry(self, e: StageEntry) -> bool:
        tv = self._time_varying.get(e.path)
        return bool(tv and (loc.POINTS in tv or loc.TOPOLOGY in tv or loc.NORMALS in tv))

    # -- path queries --
    def _sorted_paths(self) -> list[str]:
        if not self._sorted_valid:
            self._sorted = sorted(self._entries)
            self._sorted_valid = True
        return self._sorted

    def subtree(self, path: str) -> list[str]:
        """Scene paths equal to ``path`` or below it."""
        s = self._sorted_paths()
        out = []
        if path in self._entries:
            out.append(path)
        if path == "/":
            return list(s)
        lo = bisect.bisect_left(s, path + "/")
        hi = bisect.bisect_left(s, path + "0")  # '0' follows '/' in ASCII
        out.extend(s[lo:hi])
        return out
