"""Population of :class:`~stb_hydra.scene.stage_scene_index.StageSceneIndex`
(:class:`StagePopulation`): one traversal of a stage subtree (instance proxies
included) that classifies prims (lights, meshes and implicit gprims, cameras,
materials), expands PointInstancers, synthesises the materials of referenced MaterialX
documents, and records which locators of each prim vary in time.
"""

from __future__ import annotations

import numpy as np
from pxr import Sdf, Usd, UsdGeom

from . import locators as loc
from . import materialx as mtlx
from . import prims
from .geometry import MESH_TYPES
from .instancing import InstancerExpansion, expand_point_instancer, instance_light_path
from .lights import light_type_of
from .scene_index import AddedPrimEntry
from .stage_data_sources import StageEntry, data_source_class
from .stage_index_base import StageIndexBase


class StagePopulation(StageIndexBase):
    """Adding scene prims from the stage (see the module docstring)."""

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

    def _keep_light(self, ptype: str, names: frozenset[str], usd_path: str, count: int = 1) -> bool:
        """Whether the light filter adds this prim (True for non-lights); ``count``
        lights left out are remembered under ``usd_path`` (the prim an edit re-traverses)
        in ``_skipped_lights``."""
        if ptype not in prims.LIGHT_TYPES or self._light_filter is None:
            return True
        if self._light_filter(ptype, names):
            return True
        self._skipped_lights[usd_path] = self._skipped_lights.get(usd_path, 0) + count
        return False

    def _drops_leaf_light(self, p: Usd.Prim, names: frozenset[str]) -> bool:
        """A light the filter leaves out, with no children and no composition arcs that
        population reads (MaterialX references): nothing else needs its transform or
        visibility state, so it costs no further USD query (True: skip it)."""
        lt = light_type_of(p)
        if lt is None or lt == prims.MESH_LIGHT or p.GetAllChildrenNames():
            return False
        if p.HasAuthoredReferences() or p.HasAuthoredPayloads():
            return False
        return not self._keep_light(lt, names, str(p.GetPath()))

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
            if self._light_filter is not None and self._drops_leaf_light(p, names):
                continue
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
            if self._light_filter is not None and not self._keep_light(ptype, names, spath):
                if ptype == prims.MESH_LIGHT and self._is_mesh(p):
                    tv = self._prim_time_varying(p, ptype, tvx_of[path], tvv_of[path])
                    self._add_entry(StageEntry(spath, prims.MESH, p), tv, added)
                continue
            tv = self._prim_time_varying(p, ptype, tvx_of[path], tvv_of[path])
            if ptype == prims.MESH_LIGHT and self._is_mesh(p):
                # MeshLightAPI: the mesh is geometry too; the light gets its own path.
                self._add_entry(StageEntry(spath, prims.MESH, p), set(tv), added)
                lpath = spath + "/__light"
                self._add_entry(StageEntry(lpath, prims.MESH_LIGHT, p), tv, added)
                self._derived[spath].append(lpath)
                continue
            self._add_entry(StageEntry(spath, ptype, p, vis_hint=vis, names_hint=names), tv, added)
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
                StageEntry(path, prims.MATERIAL, None, mtlx=(ref.resolved, name)), set(), added
            )
            if path not in derived:
                derived.append(path)

    def mtlx_material(self, e: StageEntry) -> prims.MaterialPrim:
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
                        self._add_entry(StageEntry(path, prims.MATERIAL, p), set(), added)
        self._add_mtlx_materials(candidates, added)

    def _add_entry(self, e: StageEntry, tv: set[str], added: list[AddedPrimEntry]) -> None:
        e.ds = data_source_class(e.prim_type)(self, e)
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
            e = StageEntry(str(part.prim.GetPath()), prims.MESH, part.prim, ipath, -1, part)
            tv = self._prim_time_varying(part.prim, prims.MESH, False, tvv)
            if inst_tv:
                tv.add(loc.INSTANCER)
            self._add_entry(e, tv, added)
        self._add_prototype_materials(exp, ipath, added)
        for part in exp.lights:
            ptype = light_type_of(part.prim) or prims.SPHERE_LIGHT
            rows = np.nonzero(exp.proto_of_instance == part.proto_index)[0]
            names = frozenset(part.prim.GetAuthoredPropertyNames())
            if not self._keep_light(ptype, names, ipath, len(rows)):  # an edit re-expands it
                continue
            base = self._prim_time_varying(part.prim, ptype, False, tvv)
            if inst_tv:
                base.add(loc.XFORM)
            for r in rows:
                iid = int(exp.instance_ids[r])
                lpath = instance_light_path(ipath, iid, part.rel_path)
                e = StageEntry(lpath, ptype, part.prim, ipath, iid, part)
                self._add_entry(e, set(base), added)
                self._derived[str(part.prim.GetPath())].append(lpath)
        return added
