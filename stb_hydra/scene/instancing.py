"""Instancing helpers: native instances (instance proxies) and PointInstancers.

* Native instances (``instanceable = true`` prefabs) are traversed as instance
  proxies (``Usd.TraverseInstanceProxies``); edits inside a prototype are
  mapped back to every instance's proxy path with :func:`proxy_paths_for`.
* A ``UsdGeom.PointInstancer`` is expanded: each mesh of a prototype becomes one
  mesh prim (the prototype's own path) carrying all its instance transforms;
  each light of a prototype becomes one light prim per instance, at the
  synthesised path ``<instancer>/__instance_<i>/<path below the prototype's parent>``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from pxr import Usd, UsdGeom

PROTOTYPE_PREFIX = "/__Prototype_"


def is_prototype_path(path: str) -> bool:
    return path.startswith(PROTOTYPE_PREFIX)


def proxy_paths_for(stage: Usd.Stage, proto_path: str) -> list[str]:
    """Instance-proxy paths of a path inside a native-instance prototype."""
    root_end = proto_path.find("/", 1)
    root = proto_path if root_end < 0 else proto_path[:root_end]
    rest = "" if root_end < 0 else proto_path[root_end:]
    proto = stage.GetPrimAtPath(root)
    if not proto or not proto.IsPrototype():
        return []
    return [str(inst.GetPath()) + rest for inst in proto.GetInstances()]


@dataclass
class PrototypePart:
    """A mesh or light inside a PointInstancer prototype."""

    prim: Usd.Prim
    proto_index: int
    #: Transform from the part to the prototype root's parent (row-vector).
    local: np.ndarray
    #: Path of the part relative to the prototype root's parent ("/Orb/Light").
    rel_path: str


@dataclass
class InstancerExpansion:
    instancer_path: str
    #: (k, 4, 4) instance -> instancer-space matrices for visible instances.
    instance_xforms: np.ndarray
    #: Prototype index of each row of ``instance_xforms``.
    proto_of_instance: np.ndarray
    #: Each row's index among all the instancer's instances (USD's instance id when
    #: ``ids`` is not authored): stable light and picking paths.
    instance_ids: np.ndarray
    meshes: list[PrototypePart] = field(default_factory=list)
    lights: list[PrototypePart] = field(default_factory=list)
    prototype_roots: list[str] = field(default_factory=list)
    time_varying: bool = False
    warnings: list[str] = field(default_factory=list)


def instance_light_path(instancer_path: str, instance_id: int, rel_path: str) -> str:
    """The synthesised path of one instance's copy of a prototype prim (lights are
    synced under it; picking names a mesh instance by it)."""
    return f"{instancer_path}/__instance_{instance_id}{rel_path}"


def parse_instance_path(path: str) -> tuple[str, int, str] | None:
    """(instancer path, instance id, path below the prototype root's parent) of a
    path made by :func:`instance_light_path`, else None."""
    head, sep, tail = path.partition("/__instance_")
    if not sep or not head:
        return None
    digits, slash, rest = tail.partition("/")
    if not digits.isdigit():
        return None
    return head, int(digits), slash + rest


def expand_point_instancer(
    prim: Usd.Prim,
    time: Usd.TimeCode,
    xform_cache: UsdGeom.XformCache,
    is_light,
    is_mesh,
) -> InstancerExpansion:
    """Instance transforms and prototype contents of a PointInstancer.

    ``is_light(prim)``/``is_mesh(prim)`` classify prototype descendants.
    """
    inst = UsdGeom.PointInstancer(prim)
    path = str(prim.GetPath())
    warnings: list[str] = []
    # All instances, masked below with ComputeMaskAtTime: the default ApplyMask drops
    # the invisible ones here, which shifted every later instance's index and
    # prototype (protoIndices is not masked).
    xf = inst.ComputeInstanceTransformsAtTime(
        time,
        time,
        UsdGeom.PointInstancer.IncludeProtoXform,
        UsdGeom.PointInstancer.IgnoreMask,
    )
    mats = np.asarray(xf, dtype=np.float64).reshape(-1, 4, 4) if xf else np.zeros((0, 4, 4))
    proto_idx = inst.GetProtoIndicesAttr().Get(time)
    proto_idx = np.asarray(proto_idx if proto_idx is not None else [], dtype=np.int64)
    n = min(len(mats), len(proto_idx))
    mats, proto_idx = mats[:n], proto_idx[:n]
    ids = np.arange(n)
    mask = inst.ComputeMaskAtTime(time)
    if mask is not None and len(mask) == n:
        keep = np.asarray(mask, dtype=bool)
        mats, proto_idx, ids = mats[keep], proto_idx[keep], ids[keep]
    targets = inst.GetPrototypesRel().GetTargets()
    bad = (proto_idx < 0) | (proto_idx >= len(targets))
    if np.any(bad):
        warnings.append(
            f"point instancer <{path}>: {int(bad.sum())} instances reference missing "
            "prototypes; skipped"
        )
        mats, proto_idx, ids = mats[~bad], proto_idx[~bad], ids[~bad]

    tv = any(
        a.ValueMightBeTimeVarying()
        for a in (
            inst.GetPositionsAttr(),
            inst.GetOrientationsAttr(),
            inst.GetScalesAttr(),
            inst.GetProtoIndicesAttr(),
            inst.GetInvisibleIdsAttr(),
            inst.GetVelocitiesAttr(),
        )
    )
    exp = InstancerExpansion(path, mats, proto_idx, ids, time_varying=tv, warnings=warnings)
    stage = prim.GetStage()
    for pi, tgt in enumerate(targets):
        root = stage.GetPrimAtPath(tgt)
        if not root:
            warnings.append(f"point instancer <{path}>: prototype <{tgt}> not found")
            continue
        exp.prototype_roots.append(str(tgt))
        parent = root.GetParent()
        parent_path = str(parent.GetPath())
        it = iter(Usd.PrimRange(root, Usd.TraverseInstanceProxies(Usd.PrimDefaultPredicate)))
        for p in it:
            if p != root and p.IsA(UsdGeom.PointInstancer):
                warnings.append(f"nested point instancer <{p.GetPath()}> is not expanded")
                it.PruneChildren()
                continue
            img = UsdGeom.Imageable(p)
            if img and img.GetVisibilityAttr().Get(time) == UsdGeom.Tokens.invisible:
                it.PruneChildren()
                continue
            light, mesh = is_light(p), is_mesh(p)
            if not (light or mesh):
                continue
            rel, _reset = xform_cache.ComputeRelativeTransform(p, parent)
            local = np.asarray(rel, dtype=np.float64)
            pp = str(p.GetPath())
            rel_path = pp[len(parent_path) :] if parent_path != "/" else pp
            part = PrototypePart(p, pi, local, rel_path)
            (exp.lights if light else exp.meshes).append(part)
    return exp
