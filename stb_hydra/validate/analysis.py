"""Per-stage analysis shared by the aggregate validators (photometry, shadows, overlap).

One pass of the engine's own extraction -- ``StageSceneIndex`` + ``RenderIndex`` with
the CPU ``RenderDelegate`` -- gives every light in physical units (render frame: Y up,
metres; cd, lm) including lights inside native instances (instance proxies) and
PointInstancer prototypes (one light per instance), plus every mesh with its
world transforms. Each light is mapped back to a real USD prim (for error sites) and
to the *prefab* it belongs to:

* the nearest ancestor-or-self prim that brings in another layer through a reference
  or payload (a placed prefab);
* else, for a PointInstancer light, the prototype root (all instances are alike, so
  only the first instance of each prototype is aggregated);
* else the top-level prim holding it (a prefab file's default prim).

Analyses are cached per stage and dropped when the stage changes (ObjectsChanged),
so the validators of one ``ValidationContext.Validate`` call share one extraction.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from dataclasses import dataclass, field

import numpy as np
from pxr import Sdf, Tf, Usd

from ..scene import prims
from ..scene.links import LIGHT_LINK
from ..scene.prims import LightPrim, MeshPrim


@dataclass
class LightRecord:
    """A light in physical units and where it lives."""

    light: LightPrim
    #: Real USD prim path (instance-proxy paths kept; PointInstancer lights map to
    #: the prototype's light prim).
    prim_path: str
    #: Prim path of the prefab this light belongs to.
    prefab: str
    #: PointInstancer path and instance id, or ("", -1).
    instancer: str = ""
    instance_id: int = -1
    #: False for the 2nd..nth instance of a PointInstancer prototype (not aggregated).
    aggregate: bool = True


@dataclass
class StageAnalysis:
    lights: list[LightRecord] = field(default_factory=list)
    meshes: list[MeshPrim] = field(default_factory=list)
    #: stage units/up-axis -> render frame (row-vector 4x4).
    render_from_stage: np.ndarray = field(default_factory=lambda: np.eye(4))
    warnings: list[str] = field(default_factory=list)
    #: Light-link members of each light with a non-default light link: scene light
    #: path -> geometry prims its ``collection:lightLink`` holds (``scene/links.py``).
    light_link_members: dict[str, list[str]] = field(default_factory=dict)

    def local_lights(self) -> list[LightRecord]:
        """Valid local (sampled, shadow-mapped) lights."""
        return [r for r in self.lights if r.light.type in prims.LOCAL_LIGHT_TYPES and r.light.valid]

    def prefabs(self) -> dict[str, list[LightRecord]]:
        """Prefab path -> its aggregated local lights."""
        out: dict[str, list[LightRecord]] = {}
        for r in self.local_lights():
            if r.aggregate:
                out.setdefault(r.prefab, []).append(r)
        return out


def _brings_layer(p: Usd.Prim) -> bool:
    return p.HasAuthoredReferences() or p.HasAuthoredPayloads()


def _top_level(path: Sdf.Path) -> str:
    prefixes = path.GetPrefixes()
    return str(prefixes[0]) if prefixes else "/"


def prefab_of(prim: Usd.Prim, stop: Sdf.Path | None = None) -> str | None:
    """Nearest ancestor-or-self prim with a reference/payload (not above ``stop``)."""
    p = prim
    while p and p.GetPath() != Sdf.Path.absoluteRootPath:
        if _brings_layer(p):
            return str(p.GetPath())
        if stop is not None and p.GetPath() == stop:
            return None
        p = p.GetParent()
    return None


def build_analysis(stage: Usd.Stage) -> StageAnalysis:
    """Extract lights and meshes of ``stage`` at its start time (see module doc)."""
    from ..renderer.delegate import RenderDelegate
    from ..renderer.render_index import RenderIndex
    from ..scene.stage_scene_index import StageSceneIndex

    si = StageSceneIndex(stage)
    try:
        ri = RenderIndex(si, RenderDelegate())
        ri.sync_all()
        out = StageAnalysis(render_from_stage=si.render_from_stage.copy())
        first_iid: dict[str, int] = {}
        for path in sorted(ri.delegate.lights):
            lp = ri.delegate.lights[path].light
            if lp is None:
                continue
            sp = si.get_prim(path)
            entry = getattr(sp.data_source, "entry", None) if sp is not None else None
            uprim = getattr(entry, "prim", None)
            if uprim is None or not uprim:
                continue
            rec = LightRecord(lp, str(uprim.GetPath()), "/")
            instancer = getattr(entry, "instancer", None)
            if instancer:
                rec.instancer, rec.instance_id = instancer, int(entry.instance_id)
                part = entry.part
                proto_root = _proto_root(stage, instancer, part.proto_index)
                stop = Sdf.Path(proto_root) if proto_root else None
                rec.prefab = prefab_of(uprim, stop) or proto_root or _top_level(uprim.GetPath())
                iid = first_iid.setdefault(f"{instancer}|{rec.prefab}", rec.instance_id)
                rec.aggregate = iid == rec.instance_id
            else:
                rec.prefab = prefab_of(uprim) or _default_or_top(stage, uprim.GetPath())
            out.lights.append(rec)
        for path in sorted(ri.delegate.meshes):
            m = ri.delegate.meshes[path].mesh
            if m is not None and m.visible and len(m.indices):
                out.meshes.append(m)
        for path in sorted(ri.delegate.lights):
            if si.links.collection(path, LIGHT_LINK) is not None:
                out.light_link_members[path] = si.links.members(path, LIGHT_LINK)
        out.warnings = list(dict.fromkeys(si.warnings + ri.delegate.warnings))
        return out
    finally:
        si.close()


def _proto_root(stage: Usd.Stage, instancer: str, proto_index: int) -> str:
    from pxr import UsdGeom

    ip = stage.GetPrimAtPath(instancer)
    if not ip:
        return ""
    targets = UsdGeom.PointInstancer(ip).GetPrototypesRel().GetTargets()
    return str(targets[proto_index]) if 0 <= proto_index < len(targets) else ""


def _default_or_top(stage: Usd.Stage, path: Sdf.Path) -> str:
    dp = stage.GetDefaultPrim()
    if dp and path.HasPrefix(dp.GetPath()):
        return str(dp.GetPath())
    return _top_level(path)


# --- cache ------------------------------------------------------------------------------

_CACHE_SIZE = 4
_lock = threading.Lock()
_cache: OrderedDict[tuple[str, str], tuple[StageAnalysis, object]] = OrderedDict()


def _key(stage: Usd.Stage) -> tuple[str, str]:
    return (stage.GetRootLayer().identifier, stage.GetSessionLayer().identifier)


def analysis_for(stage: Usd.Stage) -> StageAnalysis:
    """Cached :func:`build_analysis` (thread-safe; invalidated on stage edits)."""
    key = _key(stage)
    with _lock:
        hit = _cache.get(key)
        if hit is not None:
            _cache.move_to_end(key)
            return hit[0]
        ana = build_analysis(stage)

        def _drop(notice, sender, key=key):
            with _lock:
                _cache.pop(key, None)

        listener = Tf.Notice.Register(Usd.Notice.ObjectsChanged, _drop, stage)
        _cache[key] = (ana, listener)
        while len(_cache) > _CACHE_SIZE:
            _, (_, old) = _cache.popitem(last=False)
            old.Revoke()
        return ana


def cached(stage: Usd.Stage) -> StageAnalysis | None:
    """The cached analysis of ``stage`` if a validator built one, else None."""
    with _lock:
        hit = _cache.get(_key(stage))
    return hit[0] if hit is not None else None


def clear_cache() -> None:
    """Forget every cached analysis (the runner calls it after each asset)."""
    with _lock:
        for _, listener in _cache.values():
            listener.Revoke()
        _cache.clear()
