"""``StageSceneIndex``: a Usd.Stage as a Hydra 2.0-style scene index.

* Population traverses the stage once (instance proxies included), classifies
  prims (lights, meshes and implicit gprims, cameras, materials), expands
  PointInstancers, and records which prims have time-varying data and which
  locators vary (own or ancestor transforms, visibility, attributes).
* ``Usd.Notice.ObjectsChanged`` notices are queued as they arrive and applied
  by :meth:`apply_pending_updates`: resynced subtrees are removed and re-added,
  value edits become ``PrimsDirtied`` with the locators they touch (transform
  and visibility edits reach every descendant).
* :meth:`set_time` dirties only what varies in time.

The render frame is Y-up metres: ``render_from_stage`` folds ``upAxis`` and
``metersPerUnit`` into every world matrix this index hands out.
"""

from __future__ import annotations

import bisect
import math
from collections import defaultdict
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field

import numpy as np
from pxr import Sdf, Tf, Usd, UsdGeom, UsdShade

from . import locators as loc
from . import materialx as mtlx
from . import prims
from .cameras import exposure_scale, read_camera
from .geometry import (
    DEFAULT_PRIMVARS,
    MESH_TYPES,
    MeshGeometry,
    PrimvarRequest,
    read_mesh_geometry,
)
from .instancing import (
    InstancerExpansion,
    expand_point_instancer,
    instance_light_path,
    is_prototype_path,
    proxy_paths_for,
)
from .lights import LightReadContext, light_type_of, read_light, set_transform
from .lights_bulk import LightItem, read_lights
from .links import LinkMasks, LinkResolver
from .materials import bound_material_path, read_material
from .scene_index import AddedPrimEntry, DirtiedPrimEntry, SceneIndex, SceneIndexPrim

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


# --- entries and data sources ------------------------------------------------------------


@dataclass(slots=True, eq=False)
class _Entry:
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

    def __init__(self, index: StageSceneIndex, entry: _Entry) -> None:
        self.index = index
        self.entry = entry

    @property
    def path(self) -> str:
        return self.entry.path

    def world_matrix(self) -> np.ndarray:
        return self.index.world_matrix(self.entry)

    def visible(self) -> bool:
        e = self.entry
        if e.vis_hint is not None:
            return e.vis_hint
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


#: Material inputs a float3 primvar may drive (the others take a float).
_COLOR_INPUTS = frozenset({"diffuseColor", "emissiveColor", "specularColor"})

_DS_FOR_TYPE = {prims.MESH: MeshDataSource, prims.CAMERA: CameraDataSource}


def _ds_class(prim_type: str):
    if prim_type in prims.LIGHT_TYPES:
        return LightDataSource
    if prim_type == prims.MATERIAL:
        return MaterialDataSource
    return _DS_FOR_TYPE[prim_type]


# --- the scene index ---------------------------------------------------------------------


@dataclass
class _Pending:
    resynced: list[Sdf.Path] = field(default_factory=list)
    changed: list[Sdf.Path] = field(default_factory=list)


class StageSceneIndex(SceneIndex):
    """Scene index over a ``Usd.Stage``. See the module docstring."""

    def __init__(self, stage: Usd.Stage, time: float | Usd.TimeCode | None = None) -> None:
        super().__init__()
        self.stage = stage
        self.time = self._resolve_time(time)
        self.warnings: list[str] = []
        self._warned_once: set[str] = set()
        self.xform_cache = UsdGeom.XformCache(self.time)
        self._entries: dict[str, _Entry] = {}
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
        self._pending = _Pending()
        #: Light/shadow linking: link groups of meshes, masks of lights.
        self.links = LinkResolver(stage, self.warn_once)
        self._update_frame()
        self._listener = Tf.Notice.Register(Usd.Notice.ObjectsChanged, self._on_changed, stage)
        self._populate_all()

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

    # -- world state helpers used by data sources --
    def world_matrix(self, e: _Entry) -> np.ndarray:
        if e.instancer is not None and e.prim_type in prims.LIGHT_TYPES:
            exp = self._instancers.get(e.instancer)
            ip = self.stage.GetPrimAtPath(e.instancer)
            inst_world = _gf_to_np(self.xform_cache.GetLocalToWorldTransform(ip))
            row = int(np.nonzero(exp.instance_ids == e.instance_id)[0][0]) if exp else 0
            m = e.part.local @ exp.instance_xforms[row] @ inst_world
            return m @ self.render_from_stage
        m = _gf_to_np(self.xform_cache.GetLocalToWorldTransform(e.prim))
        return m if self._frame_is_identity else m @ self.render_from_stage

    def is_visible(self, e: _Entry) -> bool:
        prim = e.prim
        if e.instancer is not None:
            prim = self.stage.GetPrimAtPath(e.instancer)
        img = UsdGeom.Imageable(prim)
        if not img:
            return True
        return img.ComputeVisibility(self.time) != UsdGeom.Tokens.invisible

    def instance_transforms(self, e: _Entry) -> np.ndarray | None:
        if e.instancer is None:
            return None
        exp = self._instancers[e.instancer]
        ip = self.stage.GetPrimAtPath(e.instancer)
        inst_world = _gf_to_np(self.xform_cache.GetLocalToWorldTransform(ip))
        rows = exp.proto_of_instance == e.part.proto_index
        m = exp.instance_xforms[rows]
        return e.part.local[None] @ m @ (inst_world @ self.render_from_stage)[None]

    def instance_ids(self, e: _Entry) -> np.ndarray | None:
        if e.instancer is None:
            return None
        exp = self._instancers[e.instancer]
        return exp.instance_ids[exp.proto_of_instance == e.part.proto_index].copy()

    def is_dynamic(self, e: _Entry) -> bool:
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

    def primvar_request(self, e: _Entry) -> PrimvarRequest:
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

    def mesh_geometry(self, e: _Entry) -> MeshGeometry | None:
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

    def geometry_key(self, e: _Entry) -> str:
        prim = e.prim
        return str(prim.GetPrimInPrototype().GetPath()) if prim.IsInstanceProxy() else e.path

    def _is_tv_geometry(self, e: _Entry) -> bool:
        tv = self._time_varying.get(e.path)
        return bool(tv and (loc.POINTS in tv or loc.TOPOLOGY in tv or loc.NORMALS in tv))

    # -- population --
    def _classify(self, p: Usd.Prim) -> str | None:
        lt = light_type_of(p)
        if lt is not None:
            return lt
        t = p.GetTypeName()
        if t in MESH_TYPES:
            return prims.MESH
        if t == "Camera":
            return prims.CAMERA
        if t == "Material":
            return prims.MATERIAL
        return None

    def _is_light(self, p: Usd.Prim) -> bool:
        return light_type_of(p) is not None

    def _is_mesh(self, p: Usd.Prim) -> bool:
        return p.GetTypeName() in MESH_TYPES

    def _populate_all(self) -> None:
        added = self._populate(self.stage.GetPseudoRoot(), tv_xform=False, tv_vis=False)
        self.links.resolve()  # before anyone syncs the added prims
        self._send_added(added)

    def _ancestor_state(self, prim: Usd.Prim) -> tuple[bool, bool]:
        """(transform varies, visibility varies) inherited from prim's ancestors."""
        tvx = tvv = False
        p = prim.GetParent()
        while p and p.GetPath() != Sdf.Path.absoluteRootPath:
            x = UsdGeom.Xformable(p)
            if x and x.TransformMightBeTimeVarying():
                tvx = True
            img = UsdGeom.Imageable(p)
            if img and img.GetVisibilityAttr().ValueMightBeTimeVarying():
                tvv = True
            p = p.GetParent()
        return tvx, tvv

    def _populate(self, root: Usd.Prim, tv_xform: bool, tv_vis: bool) -> list[AddedPrimEntry]:
        """Add scene prims for ``root``'s subtree (root included unless pseudo-root)."""
        added: list[AddedPrimEntry] = []
        # Per-path inherited time-variance, filled top-down.
        tvx_of: dict[Sdf.Path, bool] = {root.GetPath().GetParentPath(): tv_xform}
        tvv_of: dict[Sdf.Path, bool] = {root.GetPath().GetParentPath(): tv_vis}
        vis_of: dict[Sdf.Path, bool] = {}
        if root.GetPath() != Sdf.Path.absoluteRootPath:
            parent = root.GetParent()
            img = UsdGeom.Imageable(parent)
            vis_of[root.GetPath().GetParentPath()] = (
                not img or img.ComputeVisibility(self.time) != UsdGeom.Tokens.invisible
            )
        mtlx_candidates: list[Usd.Prim] = []
        pred = Usd.TraverseInstanceProxies(Usd.PrimDefaultPredicate)
        it = iter(Usd.PrimRange(root, pred))
        for p in it:
            path = p.GetPath()
            if path == Sdf.Path.absoluteRootPath:
                tvx_of[path] = tvv_of[path] = False
                vis_of[path] = True
                continue
            parent = path.GetParentPath()
            ptx = tvx_of.get(parent, False)
            ptv = tvv_of.get(parent, False)
            # One call for the authored names; everything unauthored has its
            # (constant) fallback, so most prims need no further USD queries.
            names = frozenset(p.GetAuthoredPropertyNames())
            own_tvx = False
            if "xformOpOrder" in names:
                x = UsdGeom.Xformable(p)
                own_tvx = bool(x) and x.TransformMightBeTimeVarying()
            own_tvv = False
            vis = vis_of.get(parent, True)
            if "visibility" in names or "purpose" in names:
                img = UsdGeom.Imageable(p)
                if img:
                    va = img.GetVisibilityAttr()
                    own_tvv = va.ValueMightBeTimeVarying()
                    if vis and va.Get(self.time) == UsdGeom.Tokens.invisible:
                        vis = False
                    purpose = img.GetPurposeAttr().Get()
                    if purpose == UsdGeom.Tokens.guide:
                        it.PruneChildren()
                        continue
            tvx_of[path] = ptx or own_tvx
            tvv_of[path] = ptv or own_tvv
            vis_of[path] = vis
            if p.IsA(UsdGeom.PointInstancer):
                it.PruneChildren()
                added.extend(self._add_instancer(p, tvx_of[path], tvv_of[path]))
                continue
            if p.HasAuthoredReferences() or p.HasAuthoredPayloads():
                mtlx_candidates.append(p)
            ptype = self._classify(p)
            if ptype is None:
                continue
            spath = str(path)
            tv = self._prim_time_varying(p, ptype, tvx_of[path], tvv_of[path])
            if ptype == prims.MESH_LIGHT and self._is_mesh(p):
                # MeshLightAPI: the mesh is geometry too; the light gets its own path.
                self._add_entry(_Entry(spath, prims.MESH, p), set(tv), added)
                lpath = spath + "/__light"
                self._add_entry(_Entry(lpath, prims.MESH_LIGHT, p), tv, added)
                self._derived[spath].append(lpath)
                continue
            self._add_entry(_Entry(spath, ptype, p, vis_hint=vis, names_hint=names), tv, added)
            if ptype == prims.MATERIAL:
                it.PruneChildren()  # shaders are read through the material
        self._add_mtlx_materials(mtlx_candidates, added)
        return added

    # -- MaterialX documents referenced from the stage --
    def _add_mtlx_materials(self, candidates: list[Usd.Prim], added: list[AddedPrimEntry]) -> None:
        """A MATERIAL prim per material of each ``.mtlx`` document referenced by a
        prim in ``candidates``, at the path usdMtlx would have composed it
        (:func:`stb_hydra.scene.materialx.material_prim_paths`)."""
        for p in candidates:
            refs = mtlx.mtlx_references(p)
            if not refs:
                continue
            self._mtlx_prims.add(str(p.GetPath()))
            for ref in refs:
                self._add_mtlx_reference(ref, added)

    def _add_mtlx_reference(self, ref: mtlx.MtlxReference, added: list[AddedPrimEntry]) -> None:
        key = f"mtlx:{ref.layer}:{ref.asset}"
        where = f"prim <{ref.prim_path}>: MaterialX {ref.arc} @{ref.asset}@"
        if not ref.resolved:
            self.warn_once(key, f"{where} not found; its materials are skipped")
            return
        doc = self._mtlx_docs.get(ref.resolved)
        if doc.error:
            self.warn_once(
                key, f"{where} could not be read ({doc.error}); its materials are skipped"
            )
            return
        paths = mtlx.material_prim_paths(ref.prim_path, ref.target, doc.materials)
        if not paths:
            if paths is None or ref.target.startswith("/MaterialX/Materials/"):
                self.warn_once(
                    f"{key}:{ref.target}",
                    f"{where}: no material at <{ref.target}> (usdMtlx composes materials at "
                    "</MaterialX/Materials/NAME>); skipped",
                )
            return
        derived = self._derived[ref.prim_path]
        for path, name in paths:
            e = self._entries.get(path)
            if e is not None:
                # A Material prim that references one MaterialX material reads it.
                if path == ref.prim_path and e.prim_type == prims.MATERIAL and e.mtlx is None:
                    e.mtlx = (ref.resolved, name)
                continue
            self._add_entry(
                _Entry(path, prims.MATERIAL, None, mtlx=(ref.resolved, name)), set(), added
            )
            if path not in derived:
                derived.append(path)

    def mtlx_material(self, e: _Entry) -> prims.MaterialPrim:
        """The MaterialPrim of a MaterialX-document entry (``e.mtlx``)."""
        assert e.mtlx is not None
        file, name = e.mtlx
        doc = self._mtlx_docs.get(file)
        if doc.error:
            mp = prims.MaterialPrim(e.path, uses_defaults=True, source=mtlx.SOURCE)
            mp.warnings.append(f"material <{e.path}>: {file} could not be read ({doc.error})")
            return mp
        return doc.material(name, e.path)

    def _add_prototype_materials(
        self, exp: InstancerExpansion, ipath: str, added: list[AddedPrimEntry]
    ) -> None:
        """Materials inside a PointInstancer's prototypes (the traversal stops at the
        instancer): UsdShade Materials and MaterialX references. Prototypes outside
        the instancer are traversed on their own."""
        candidates: list[Usd.Prim] = []
        pred = Usd.TraverseInstanceProxies(Usd.PrimDefaultPredicate)
        for r in exp.prototype_roots:
            root = self.stage.GetPrimAtPath(r)
            if not root or not r.startswith(ipath + "/"):
                continue
            it = iter(Usd.PrimRange(root, pred))
            for p in it:
                if p.HasAuthoredReferences() or p.HasAuthoredPayloads():
                    candidates.append(p)
                if p.GetTypeName() == "Material":
                    it.PruneChildren()
                    path = str(p.GetPath())
                    if path not in self._entries:
                        self._add_entry(_Entry(path, prims.MATERIAL, p), set(), added)
        self._add_mtlx_materials(candidates, added)

    def _add_entry(self, e: _Entry, tv: set[str], added: list[AddedPrimEntry]) -> None:
        e.ds = _ds_class(e.prim_type)(self, e)
        self._entries[e.path] = e
        if e.prim is not None:
            if e.prim_type == prims.MESH:
                self.links.add_mesh(e.path, e.path, e.instancer)
            elif e.prim_type in prims.LIGHT_TYPES:
                self.links.add_light(e.path, e.prim, e.names_hint)
        if tv:
            self._time_varying[e.path] = tv
        self._sorted_valid = False
        added.append(AddedPrimEntry(e.path, e.prim_type))

    def _prim_time_varying(self, p: Usd.Prim, ptype: str, tvx: bool, tvv: bool) -> set[str]:
        """Locators of ``p`` that vary in time (``tvx``/``tvv``: its transform /
        visibility varies, own or inherited)."""
        tv: set[str] = set()
        if tvx:
            tv.add(loc.XFORM)
        if tvv:
            tv.add(loc.VISIBILITY)
        # Ask every authored attribute first and its name only when it varies:
        # names cost as much as the question, and almost nothing varies.
        for a in p.GetAuthoredAttributes():
            if not a.ValueMightBeTimeVarying():
                continue
            name = a.GetName()
            if name.startswith("xformOp") or name == "visibility":
                continue
            lc = loc.locator_for_attribute(ptype, name)
            if lc is not None:
                tv.add(lc)
        return tv

    def _add_instancer(self, p: Usd.Prim, tvx: bool, tvv: bool) -> list[AddedPrimEntry]:
        added: list[AddedPrimEntry] = []
        ipath = str(p.GetPath())
        try:
            exp = expand_point_instancer(
                p, self.time, self.xform_cache, self._is_light, self._is_mesh
            )
        except Exception as exc:  # noqa: BLE001
            self._warn(f"point instancer <{ipath}>: could not be expanded ({exc}); skipped")
            return added
        for w in exp.warnings:
            self._warn(w)
        self._instancers[ipath] = exp
        for r in exp.prototype_roots:
            self._proto_users[r].add(ipath)
        inst_tv = exp.time_varying or tvx
        for part in exp.meshes:
            e = _Entry(str(part.prim.GetPath()), prims.MESH, part.prim, ipath, -1, part)
            tv = self._prim_time_varying(part.prim, prims.MESH, False, tvv)
            if inst_tv:
                tv.add(loc.INSTANCER)
            self._add_entry(e, tv, added)
        self._add_prototype_materials(exp, ipath, added)
        for part in exp.lights:
            ptype = light_type_of(part.prim) or prims.SPHERE_LIGHT
            base = self._prim_time_varying(part.prim, ptype, False, tvv)
            if inst_tv:
                base.add(loc.XFORM)
            rows = np.nonzero(exp.proto_of_instance == part.proto_index)[0]
            for r in rows:
                iid = int(exp.instance_ids[r])
                lpath = instance_light_path(ipath, iid, part.rel_path)
                e = _Entry(lpath, ptype, part.prim, ipath, iid, part)
                self._add_entry(e, set(base), added)
                self._derived[str(part.prim.GetPath())].append(lpath)
        return added

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

    # -- time --
    def set_time(self, time: float | Usd.TimeCode) -> int:
        """Move to ``time``; dirties only prims whose data varies. Returns the count."""
        t = time if isinstance(time, Usd.TimeCode) else Usd.TimeCode(float(time))
        if t == self.time:
            return 0
        self.time = t
        self.xform_cache.SetTime(t)
        self._material_cache.clear()
        refreshed = self._refresh_instancers(only_time_varying=True)
        entries = [
            DirtiedPrimEntry(p, frozenset(locs))
            for p, locs in self._time_varying.items()
            if p not in refreshed
        ]
        entries += self._resolve_links(refreshed)  # re-expanded instancers' prototypes
        self._send_dirtied(entries)
        return len(entries)

    def _refresh_instancers(self, only_time_varying: bool, paths=None) -> set[str]:
        """Re-expand instancers; resync those whose instance set changed.
        Returns scene paths that were removed/re-added (no dirty needed)."""
        resynced: set[str] = set()
        for ipath in list(paths if paths is not None else self._instancers):
            exp = self._instancers.get(ipath)
            if exp is None or (only_time_varying and not exp.time_varying):
                continue
            ip = self.stage.GetPrimAtPath(ipath)
            if not ip:
                continue
            new = expand_point_instancer(
                ip, self.time, self.xform_cache, self._is_light, self._is_mesh
            )
            same = (
                len(new.instance_ids) == len(exp.instance_ids)
                and np.array_equal(new.instance_ids, exp.instance_ids)
                and np.array_equal(new.proto_of_instance, exp.proto_of_instance)
            )
            if same:
                exp.instance_xforms = new.instance_xforms
            else:
                resynced.update(self._resync_path(ipath))
        return resynced

    # -- change notices --
    def _on_changed(self, notice: Usd.Notice.ObjectsChanged, sender) -> None:
        self._pending.resynced.extend(notice.GetResyncedPaths())
        self._pending.changed.extend(notice.GetChangedInfoOnlyPaths())

    @property
    def has_pending_updates(self) -> bool:
        return bool(self._pending.resynced or self._pending.changed)

    def apply_pending_updates(self) -> None:
        """Turn queued USD notices into PrimsRemoved/Added/Dirtied batches."""
        pend, self._pending = self._pending, _Pending()
        if not (pend.resynced or pend.changed):
            return
        self._material_cache.clear()
        resync_roots: set[str] = set()
        props: dict[str, set[str]] = defaultdict(set)
        for sp in pend.resynced:
            if sp.IsPropertyPath():
                props[str(sp.GetPrimPath())].add(sp.name)
            else:
                resync_roots.add(str(sp))
        for sp in pend.changed:
            if sp.IsPropertyPath():
                props[str(sp.GetPrimPath())].add(sp.name)
            elif sp == Sdf.Path.absoluteRootPath:
                resync_roots.add("/")  # stage metadata (upAxis, metersPerUnit, ...)
        # Map prototype paths to every instance proxy.
        resync_roots = self._map_prototypes(resync_roots)
        props = self._map_prototype_props(props)
        if "/" in resync_roots:
            self._full_rebuild()
            return
        for ppath, names in props.items():
            if any(n.startswith("collection:") for n in names):
                self.links.collections_changed(ppath)  # a link collection may read it
        touched: set[str] = set()
        for root in _collapse(resync_roots):
            touched.update(self._resync_path(root))
        self.xform_cache.Clear()
        dirty: dict[str, set[str]] = defaultdict(set)
        for ppath, names in props.items():
            if any(ppath == r or ppath.startswith(r + "/") for r in resync_roots):
                continue
            self._dirty_for_props(ppath, names, dirty)
        entries = [
            DirtiedPrimEntry(p, frozenset(ls)) for p, ls in dirty.items() if p not in touched
        ]
        entries += self._resolve_links(touched)
        if entries:
            self._send_dirtied(entries)

    def _resolve_links(self, skip: set[str]) -> list[DirtiedPrimEntry]:
        """Re-resolve light/shadow links if geometry, lights or collections changed:
        dirty the meshes whose groups and the lights whose masks moved (``skip``: prims
        just re-added, synced in full anyway)."""
        meshes, lights = self.links.resolve()
        out = [DirtiedPrimEntry(p, frozenset({loc.LINKS})) for p in meshes if p not in skip]
        out += [
            DirtiedPrimEntry(p, frozenset({loc.LIGHT_COLLECTION})) for p in lights if p not in skip
        ]
        return out

    def _map_prototypes(self, roots: set[str]) -> set[str]:
        out: set[str] = set()
        for r in roots:
            if is_prototype_path(r):
                out.update(proxy_paths_for(self.stage, r))
            else:
                out.add(r)
        # A resync inside a PointInstancer prototype re-expands the instancer.
        for r in list(out):
            for proto, users in self._proto_users.items():
                if r == proto or r.startswith(proto + "/") or proto.startswith(r + "/"):
                    out.update(users)
        return out

    def _map_prototype_props(self, props: dict[str, set[str]]) -> dict[str, set[str]]:
        out: dict[str, set[str]] = defaultdict(set)
        for p, names in props.items():
            if is_prototype_path(p):
                for q in proxy_paths_for(self.stage, p):
                    out[q].update(names)
            else:
                out[p].update(names)
        return out

    def _full_rebuild(self) -> None:
        removed = list(self._entries)
        self._entries.clear()
        self._time_varying.clear()
        self._derived.clear()
        self._instancers.clear()
        self._proto_users.clear()
        self._geom_cache.clear()
        self._mtlx_prims.clear()
        self.links.clear()
        self._sorted_valid = False
        self._send_removed(removed)
        self._update_frame()
        self.xform_cache = UsdGeom.XformCache(self.time)
        self._populate_all()

    def _remove_paths(self, paths: list[str]) -> None:
        for p in paths:
            e = self._entries.pop(p, None)
            self._time_varying.pop(p, None)
            self.links.remove(p)
            if e is not None and e.prim is not None:
                for k in [k for k in self._geom_cache if k[0] == p]:
                    del self._geom_cache[k]
            self._material_cache.pop(p, None)
        self._sorted_valid = False

    def _resync_path(self, root: str) -> set[str]:
        """Remove every scene prim under ``root`` and re-add from USD."""
        removed = self.subtree(root)
        # Prims derived from USD prims under root (instancer lights, mesh lights).
        for src in list(self._derived):
            if src == root or src.startswith(root + "/"):
                removed.extend(self._derived.pop(src))
        for ipath in list(self._instancers):
            if ipath == root or ipath.startswith(root + "/"):
                exp = self._instancers.pop(ipath)
                for r in exp.prototype_roots:
                    self._proto_users[r].discard(ipath)
                removed.extend(self.subtree(ipath))
                for part in exp.meshes:
                    removed.append(str(part.prim.GetPath()))
        removed = [p for p in dict.fromkeys(removed) if p in self._entries]
        self._remove_paths(removed)
        self._geom_cache.clear()
        self.xform_cache.Clear()
        self._mtlx_prims = {
            p for p in self._mtlx_prims if p != root and not p.startswith(root + "/")
        }
        self._send_removed(removed)
        prim = self.stage.GetPrimAtPath(root)
        added: list[AddedPrimEntry] = []
        if prim and prim.IsActive() and prim.IsDefined() and not prim.IsAbstract():
            if self._inside_instancer(prim):
                ip = self._inside_instancer(prim)
                if ip not in self._instancers:
                    tvx, tvv = self._ancestor_state(ip)
                    added = self._add_instancer(ip, tvx, tvv)
            else:
                tvx, tvv = self._ancestor_state(prim)
                added = self._populate(prim, tvx, tvv)
        # Materials a MaterialX reference above root synthesised under it.
        anc = Sdf.Path(root).GetParentPath() if root != "/" else Sdf.Path.emptyPath
        while anc and anc != Sdf.Path.absoluteRootPath:
            if str(anc) in self._mtlx_prims:
                ap = self.stage.GetPrimAtPath(anc)
                if ap:
                    self._add_mtlx_materials([ap], added)
            anc = anc.GetParentPath()
        self._send_added(added)
        return set(removed) | {a.path for a in added}

    def _inside_instancer(self, prim: Usd.Prim):
        p = prim.GetParent()
        while p and p.GetPath() != Sdf.Path.absoluteRootPath:
            if p.IsA(UsdGeom.PointInstancer):
                return p
            p = p.GetParent()
        return None

    def _dirty_for_props(self, ppath: str, names: set[str], dirty: dict[str, set[str]]) -> None:
        e = self._entries.get(ppath)
        for q in (ppath, *self._derived.get(ppath, ())):
            eq = self._entries.get(q)
            if eq is not None:
                eq.names_hint = None  # the authored set may have changed
        prim = self.stage.GetPrimAtPath(ppath)
        # Keep the time-varying table current (an edit may add time samples).
        if e is not None and prim:
            for n in names:
                a = prim.GetAttribute(n)
                if not a:
                    continue
                lc = loc.locator_for_attribute(e.prim_type, n)
                if lc is None or lc in (loc.XFORM, loc.VISIBILITY):
                    continue
                tv = self._time_varying.setdefault(ppath, set())
                if a.ValueMightBeTimeVarying():
                    tv.add(lc)
                if not tv:
                    self._time_varying.pop(ppath, None)
        inherited = {n for n in names if n.startswith("xformOp") or n == "xformOpOrder"}
        if inherited:
            self._update_tv_subtree(ppath, loc.XFORM, prim)
            for p in self.subtree(ppath):
                dirty[p].add(loc.XFORM)
            for d in self._derived_under(ppath):
                dirty[d].add(loc.XFORM)
        if "visibility" in names or "purpose" in names:
            for p in self.subtree(ppath):
                dirty[p].add(loc.VISIBILITY)
            for d in self._derived_under(ppath):
                dirty[d].add(loc.VISIBILITY)
        if any(n.startswith("material:binding") for n in names):
            for p in self.subtree(ppath):
                if self._entries[p].prim_type == prims.MESH:
                    dirty[p].add(loc.MATERIAL_BINDINGS)
        if any(n.startswith("stb:") for n in names) and (e is None or e.prim_type == prims.MESH):
            for p in self.subtree(ppath):
                if self._entries[p].prim_type == prims.MESH:
                    dirty[p].add(loc.STB)
        if ppath in self._instancers:
            self._refresh_instancers(False, [ppath])
            if ppath in self._instancers:
                for p in self.subtree(ppath):
                    dirty[p].add(loc.XFORM)
                for part in self._instancers[ppath].meshes:
                    dirty[str(part.prim.GetPath())].add(loc.INSTANCER)
            return
        # Local (non-inherited) properties of the prim itself.
        own = names - inherited - {"visibility", "purpose"}
        targets: list[tuple[str, str]] = []
        if e is not None:
            targets.append((ppath, e.prim_type))
        for d in self._derived.get(ppath, ()):
            de = self._entries.get(d)
            if de is not None:
                targets.append((d, de.prim_type))
        if e is None and not self._derived.get(ppath) and prim:
            # A shader (or anything) inside a material dirties the material.
            m = _enclosing_material(prim)
            if m is not None and str(m.GetPath()) in self._entries:
                dirty[str(m.GetPath())].add(loc.MATERIAL)
            return
        for tpath, ttype in targets:
            for n in own:
                lc = loc.locator_for_attribute(ttype, n)
                if lc is not None and not (lc == loc.MATERIAL_BINDINGS and n in inherited):
                    dirty[tpath].add(lc)

    def _derived_under(self, root: str) -> list[str]:
        out = []
        for src, ds in self._derived.items():
            if src == root or src.startswith(root + "/"):
                out.extend(ds)
        return out

    def _update_tv_subtree(self, root: str, lc: str, prim: Usd.Prim | None) -> None:
        """An xform edit may make a subtree's transforms time-varying (or static)."""
        if not prim:
            return
        x = UsdGeom.Xformable(prim)
        tvx = bool(x) and x.TransformMightBeTimeVarying()
        anc, _ = self._ancestor_state(prim)
        for p in self.subtree(root):
            e = self._entries[p]
            if e.prim is None or e.instancer is not None:
                continue
            tv = self._time_varying.get(p, set())
            if tvx or anc or self._own_or_between_tv(e.prim, prim):
                tv.add(lc)
                self._time_varying[p] = tv
            elif lc in tv:
                tv.discard(lc)
                if not tv:
                    self._time_varying.pop(p, None)

    def _own_or_between_tv(self, leaf: Usd.Prim, top: Usd.Prim) -> bool:
        p = leaf
        while p and p != top:
            x = UsdGeom.Xformable(p)
            if x and x.TransformMightBeTimeVarying():
                return True
            p = p.GetParent()
        return False

    # -- convenience --
    def cameras(self) -> list[str]:
        return sorted(p for p, e in self._entries.items() if e.prim_type == prims.CAMERA)

    def light_paths(self) -> list[str]:
        return [p for p, e in self._entries.items() if e.prim_type in prims.LIGHT_TYPES]

    def close(self) -> None:
        if self._listener is not None:
            self._listener.Revoke()
            self._listener = None


def _collapse(roots: set[str]) -> list[str]:
    """Drop roots that lie under another root."""
    out: list[str] = []
    for r in sorted(roots):
        if not any(r == o or r.startswith(o.rstrip("/") + "/") for o in out):
            out.append(r)
    return out


def _enclosing_material(prim: Usd.Prim):
    p = prim
    while p and p.GetPath() != Sdf.Path.absoluteRootPath:
        if p.IsA(UsdShade.Material):
            return p
        p = p.GetParent()
    return None
