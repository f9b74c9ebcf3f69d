"""Change processing of :class:`~stb_hydra.scene.stage_scene_index.StageSceneIndex`
(:class:`StageChanges`): ``Usd.Notice.ObjectsChanged`` notices are queued as they
arrive and applied by :meth:`StageChanges.apply_pending_updates`: resynced subtrees are
removed and re-added, value edits become ``PrimsDirtied`` with the locators they touch
(transform and visibility edits reach every descendant); :meth:`StageChanges.set_time`
dirties only what varies in time.
"""

from __future__ import annotations

from collections import defaultdict

import numpy as np
from pxr import Sdf, Usd, UsdGeom, UsdShade

from . import locators as loc
from . import prims
from .instancing import expand_point_instancer, is_prototype_path, proxy_paths_for
from .scene_index import AddedPrimEntry, DirtiedPrimEntry
from .stage_index_base import PendingNotices
from .stage_population import StagePopulation


class StageChanges(StagePopulation):
    """Time changes and USD edits turned into scene index notices."""

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
        pend, self._pending = self._pending, PendingNotices()
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
        # A light the light filter left out (or inside an instancer of one left out):
        # an edit may make the filter keep it.
        if self._skipped_lights:
            resync_roots.update(r for p in props if (r := self._skipped_root(p)))
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

    def _skipped_root(self, path: str) -> str | None:
        """The ``_skipped_lights`` key at or above ``path`` (None: none)."""
        p = path
        while p and p != "/":
            if p in self._skipped_lights:
                return p
            p = p.rsplit("/", 1)[0]
        return None

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
        self._skipped_lights.clear()
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
        if self._skipped_lights:  # the traversal below finds those still left out
            self._skipped_lights = {
                p: n
                for p, n in self._skipped_lights.items()
                if p != root and not p.startswith(root + "/")
            }
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
