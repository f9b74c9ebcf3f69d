"""Light linking and shadow linking, resolved over the scene's geometry prims (no GL).

UsdLuxLightAPI gives every light two collections: ``collection:lightLink`` (the prims
it lights) and ``collection:shadowLink`` (the prims that cast its shadows). Both
default to everything (``includeRoot = true``, nothing excluded). Membership comes
from USD itself -- ``Usd.CollectionAPI.ComputeMembershipQuery()`` and
``IsPathIncluded`` -- so includes, excludes, ``includeRoot``, the expansion rules
(``expandPrims``, ``explicitOnly``, ``expandPrimsAndProperties``), collections that
include other collections and membership expressions all mean what USD says.

What the renderer gets (per kind, light link and shadow link):

* a **group** per geometry prim: prims with the same membership in every non-default
  collection of that kind share one small integer (at most
  ``limits.MAX_LIGHT_LINK_GROUPS`` / ``MAX_SHADOW_LINK_GROUPS``);
* a **mask** per light: bit g set when the light's collection holds group g. A light
  with the default collection gets ``ALL_GROUPS`` and costs nothing.

The light-link group goes into the G-buffer (``g_link``) and every lighting method
multiplies a light's contribution by its bit for the pixel's group; the shadow-link
group rides on the draw batches and each shadow capture draws only the batches its
light's shadow mask keeps (``renderer/link_masks.py``).

Decisions USD leaves to the renderer:

* **Geometry prims** are the scene index's meshes: UsdGeom meshes and implicit
  shapes, instance proxies included (their proxy paths), and the meshes of
  PointInstancer prototypes (one scene prim per prototype mesh, at its prototype path).
* **PointInstancer prototypes.** The instancer stands for its instances: a prototype
  mesh is a member when the instancer's path is, unless the collection says something
  about the prototype's own namespace -- one of its rule paths is the prototype path
  or an ancestor of it that is not the instancer or one of the instancer's ancestors
  -- and then its own path decides. So a link to the instancer (or to anything above
  it) lights every instance whatever the expansion rule (``explicitOnly`` on the
  instancer included), and an include or exclude of one prototype (under the
  instancer, the usual layout, or elsewhere) acts on that prototype only. In
  expression mode a prototype mesh is a member when its own path or the instancer's
  matches. Instances of one prototype share a mesh prim, so they cannot be linked one
  by one.
* **Face sets.** A collection that includes a ``GeomSubset`` of a mesh holds the whole
  mesh (a group is per prim; over-lit, never under-lit) -- warned once per light.
* **Lights** are linked as they are authored on their prim: instance-proxy lights use
  their proxy's collection (targets mapped into the instance), the per-instance lights
  of a PointInstancer share their prototype light's, a MeshLightAPI mesh's light uses
  the mesh's.

Change tracking (``StageSceneIndex`` drives it): adding or removing geometry or lights
and editing any ``collection:*`` property (a light's own, or one of a collection a
light's collection includes) marks the resolver dirty; :meth:`LinkResolver.resolve`
then re-reads only the edited collections, evaluates membership only for prims it has
not evaluated yet, keeps group ids stable (a new group takes the id of the old group
holding most of its prims) and returns the meshes whose groups and the lights whose
masks changed -- the only prims that get dirtied.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

import numpy as np
from pxr import Sdf, Usd, UsdGeom, UsdLux

from .. import limits

LIGHT_LINK = "lightLink"
SHADOW_LINK = "shadowLink"
KINDS = (LIGHT_LINK, SHADOW_LINK)
#: Mask of a light whose collection holds everything (every group bit set).
ALL_GROUPS = 0xFFFFFFFF
#: Group limits per kind.
MAX_GROUPS = {
    LIGHT_LINK: limits.MAX_LIGHT_LINK_GROUPS,
    SHADOW_LINK: limits.MAX_SHADOW_LINK_GROUPS,
}
_EVERYTHING_RULES = ("expandPrims", "expandPrimsAndProperties")

Warn = Callable[[str, str], None]


@dataclass(frozen=True)
class LinkMasks:
    """A light's masks over the link groups (``light``) and shadow groups (``shadow``)."""

    light: int = ALL_GROUPS
    shadow: int = ALL_GROUPS


DEFAULT_MASKS = LinkMasks()


def _collection_api(prim: Usd.Prim, kind: str) -> Usd.CollectionAPI:
    api = UsdLux.LightAPI(prim)
    if kind == LIGHT_LINK:
        return api.GetLightLinkCollectionAPI()
    return api.GetShadowLinkCollectionAPI()


@dataclass
class LinkCollection:
    """One light's non-default link collection and its membership cache."""

    kind: str
    query: Usd.UsdCollectionMembershipQuery
    #: Paths of the query's rule map other than the root (relationship mode).
    rules: tuple[Sdf.Path, ...]
    #: Membership expression instead of a rule map.
    expression: bool
    #: Prim paths whose collections this one includes (change tracking).
    included_prims: frozenset[str]
    #: Meshes held through an included GeomSubset (the whole mesh).
    subset_meshes: frozenset[str]
    #: Scene mesh path -> member (filled lazily by the resolver).
    members: dict[str, bool] = field(default_factory=dict)

    def contains(self, path: Sdf.Path, instancer: Sdf.Path | None) -> bool:
        """Whether the geometry prim at ``path`` (a prototype mesh of ``instancer``,
        if given) is a member (see the module's decisions)."""
        q = self.query
        if str(path) in self.subset_meshes:
            return True
        if instancer is None:
            return bool(q.IsPathIncluded(path))
        if self.expression:
            return bool(q.IsPathIncluded(path) or q.IsPathIncluded(instancer))
        specific = any(path.HasPrefix(r) and not instancer.HasPrefix(r) for r in self.rules)
        return bool(q.IsPathIncluded(path if specific else instancer))


def authored_link(names: Iterable[str], kind: str) -> bool:
    """Whether any of the authored property ``names`` belongs to the ``kind`` collection."""
    prefix = f"collection:{kind}:"
    return any(n.startswith(prefix) for n in names)


def read_collection(
    prim: Usd.Prim, kind: str, names: Iterable[str] | None = None
) -> LinkCollection | None:
    """The ``kind`` link collection of a light prim, or None when it holds everything
    (nothing authored, or ``includeRoot`` with nothing excluded). ``names``: the prim's
    authored property names when the caller has them (skips the query for the common
    light with no linking)."""
    if names is None:
        names = prim.GetAuthoredPropertyNames()
    if not authored_link(names, kind):
        return None
    col = _collection_api(prim, kind)
    query = col.ComputeMembershipQuery()
    expression = not query.UsesPathExpansionRuleMap()
    rules: tuple[Sdf.Path, ...] = ()
    subsets: set[str] = set()
    if not expression:
        rule_map = query.GetAsPathExpansionRuleMap()
        root = rule_map.get(Sdf.Path.absoluteRootPath)
        if root in _EVERYTHING_RULES and "exclude" not in rule_map.values():
            return None
        rules = tuple(p for p in rule_map if p != Sdf.Path.absoluteRootPath)
        stage = prim.GetStage()
        for p, rule in rule_map.items():
            if rule == "exclude" or p == Sdf.Path.absoluteRootPath:
                continue
            sub = stage.GetPrimAtPath(p)
            if sub and sub.IsA(UsdGeom.Subset) and query.IsPathIncluded(p):
                subsets.add(str(p.GetParentPath()))
    included = frozenset(str(c.GetPrimPath()) for c in query.GetIncludedCollections())
    return LinkCollection(kind, query, rules, expression, included, frozenset(subsets))


def merge_groups(sig: np.ndarray, limit: int, union: bool) -> tuple[np.ndarray, np.ndarray]:
    """Merge the rows of a (G, L) bool signature matrix down to ``limit`` groups.

    Repeatedly merges the two closest rows (fewest differing lights; ties: the
    earlier pair), combining them with OR (``union``: light links, a merged group is
    lit by every light that lit a member) or AND (shadow links: it casts a light's
    shadow only if every member did) -- over-lit, never under-lit. Beyond
    ``limits.LINK_MERGE_MAX_SIGNATURES`` rows the ``limit - 1`` first rows are kept
    (callers order rows by size, largest first) and the rest fold into one.
    Returns (new group of each row, merged signatures)."""
    g = len(sig)
    assign = np.arange(g)
    if g <= limit:
        return assign, sig.copy()
    comb = np.logical_or if union else np.logical_and
    if g > limits.LINK_MERGE_MAX_SIGNATURES:
        keep = limit - 1
        rest = comb.reduce(sig[keep:], axis=0)
        assign[keep:] = keep
        return assign, np.vstack([sig[:keep], rest[None]])
    rows = [sig[i].copy() for i in range(g)]
    alive = list(range(g))
    s = sig.astype(np.int32)
    dist = s @ (1 - s).T + (1 - s) @ s.T
    dist = dist.astype(np.float64)
    np.fill_diagonal(dist, np.inf)
    while len(alive) > limit:
        sub = dist[np.ix_(alive, alive)]
        k = int(np.argmin(sub))
        a, b = alive[k // len(alive)], alive[k % len(alive)]
        a, b = min(a, b), max(a, b)
        rows[a] = comb(rows[a], rows[b])
        assign[assign == b] = a
        alive.remove(b)
        ra = rows[a].astype(np.int32)
        for c in alive:
            if c != a:
                rc = rows[c].astype(np.int32)
                dist[a, c] = dist[c, a] = float(np.sum(ra != rc))
    remap = {old: new for new, old in enumerate(alive)}
    return np.array([remap[int(x)] for x in assign]), np.array([rows[a] for a in alive])


@dataclass
class _KindState:
    #: Scene mesh path -> group (every mesh while the kind has links; empty: all 0).
    groups: dict[str, int] = field(default_factory=dict)
    #: USD light prim path -> mask (non-default collections only).
    masks: dict[str, int] = field(default_factory=dict)
    #: USD light prim path -> member count.
    counts: dict[str, int] = field(default_factory=dict)
    #: Distinct groups in use.
    n_groups: int = 1
    #: Lights whose membership the group limit widened (warned).
    merged_lights: tuple[str, ...] = ()


class LinkResolver:
    """Link groups of the scene's meshes and link masks of its lights (see module)."""

    def __init__(self, stage: Usd.Stage, warn_once: Warn | None = None) -> None:
        self.stage = stage
        self._warn_once: Warn = warn_once or (lambda _k, _m: None)
        #: Scene mesh path -> (prim path, PointInstancer path or None).
        self._meshes: dict[str, tuple[Sdf.Path, Sdf.Path | None]] = {}
        #: Scene light path -> USD prim path owning its collections.
        self._lights: dict[str, str] = {}
        #: (USD light prim path, kind) -> its collection (None: everything).
        self._cols: dict[tuple[str, str], LinkCollection | None] = {}
        self._state = {k: _KindState() for k in KINDS}
        self._masks: dict[str, LinkMasks] = {}
        self._dirty = False
        #: Bumped by every :meth:`resolve` that changed a group or a mask.
        self.version = 0

    # -- population --
    def add_mesh(self, path: str, prim_path: str, instancer: str | None = None) -> None:
        self._meshes[path] = (Sdf.Path(prim_path), Sdf.Path(instancer) if instancer else None)
        for col in self._cols.values():
            if col is not None:
                col.members.pop(path, None)
        if self.has_links:
            self._dirty = True

    def add_light(self, path: str, prim: Usd.Prim, names: Iterable[str] | None = None) -> None:
        usd = str(prim.GetPath())
        self._lights[path] = usd
        if names is None:
            names = prim.GetAuthoredPropertyNames()
        names = tuple(names)
        for kind in KINDS:
            key = (usd, kind)
            if key not in self._cols:
                self._cols[key] = read_collection(prim, kind, names)
            if self._cols[key] is not None:
                self._dirty = True

    def remove(self, path: str) -> None:
        if self._meshes.pop(path, None) is not None:
            for col in self._cols.values():
                if col is not None:
                    col.members.pop(path, None)
            if self.has_links:
                self._dirty = True
        usd = self._lights.pop(path, None)
        if usd is not None:
            self._masks.pop(path, None)
            linked = any(self._cols.get((usd, k)) is not None for k in KINDS)
            if usd not in self._lights.values():
                for k in KINDS:
                    self._cols.pop((usd, k), None)
            if linked:
                self._dirty = True

    def clear(self) -> None:
        self._meshes.clear()
        self._lights.clear()
        self._cols.clear()
        self._masks.clear()
        self._state = {k: _KindState() for k in KINDS}
        self._dirty = True

    def collections_changed(self, prim_path: str) -> None:
        """A ``collection:*`` property of ``prim_path`` changed: re-read the link
        collections it is, or that include one of its collections."""
        for (usd, kind), col in list(self._cols.items()):
            if usd != prim_path and (col is None or prim_path not in col.included_prims):
                continue
            prim = self.stage.GetPrimAtPath(usd)
            self._cols[(usd, kind)] = read_collection(prim, kind) if prim else None
            self._dirty = True

    # -- queries --
    @property
    def has_links(self) -> bool:
        """Any light has a non-default light or shadow link."""
        return any(c is not None for c in self._cols.values())

    def active(self, kind: str) -> bool:
        """Some light's ``kind`` collection is not everything (masks matter)."""
        return any(c is not None and k == kind for (_, k), c in self._cols.items())

    @property
    def has_light_links(self) -> bool:
        return self.active(LIGHT_LINK)

    @property
    def has_shadow_links(self) -> bool:
        return self.active(SHADOW_LINK)

    def mesh_groups(self, path: str) -> tuple[int, int]:
        """(light-link group, shadow-link group) of a scene mesh (0, 0 unlinked)."""
        return (
            self._state[LIGHT_LINK].groups.get(path, 0),
            self._state[SHADOW_LINK].groups.get(path, 0),
        )

    def light_masks(self, path: str) -> LinkMasks:
        return self._masks.get(path, DEFAULT_MASKS)

    def collection(self, light_path: str, kind: str) -> LinkCollection | None:
        usd = self._lights.get(light_path)
        return None if usd is None else self._cols.get((usd, kind))

    def is_linked(self, light_path: str) -> bool:
        """The light's light or shadow link is not everything."""
        return any(self.collection(light_path, k) is not None for k in KINDS)

    def group_count(self, kind: str) -> int:
        return self._state[kind].n_groups

    def members(self, light_path: str, kind: str) -> list[str]:
        """Scene mesh paths in the light's ``kind`` collection (every mesh by default)."""
        col = self.collection(light_path, kind)
        if col is None:
            return sorted(self._meshes)
        return sorted(p for p in self._meshes if self._member(col, p))

    def describe(self, light_path: str) -> str:
        """One line for a light's links (the previewer's light list)."""
        n = len(self._meshes)
        parts = []
        for kind, what in ((LIGHT_LINK, "lights"), (SHADOW_LINK, "shadowed by")):
            usd = self._lights.get(light_path)
            col = self._cols.get((usd, kind)) if usd is not None else None
            if col is None:
                parts.append(f"{what} all")
                continue
            k = self._state[kind].counts.get(usd or "", 0)
            parts.append(f"{what} {k} of {n} prims")
        return ", ".join(parts)

    # -- resolution --
    def _member(self, col: LinkCollection, mesh: str) -> bool:
        v = col.members.get(mesh)
        if v is None:
            path, inst = self._meshes[mesh]
            v = col.members[mesh] = col.contains(path, inst)
        return v

    def resolve(self) -> tuple[set[str], set[str]]:
        """Bring groups and masks up to date. Returns (meshes whose groups changed,
        lights whose masks changed) -- empty when nothing relevant changed."""
        if not self._dirty:
            return set(), set()
        self._dirty = False
        meshes = list(self._meshes)
        changed_meshes: set[str] = set()
        for kind in KINDS:
            old = self._state[kind]
            new = self._resolve_kind(kind, meshes, old)
            for m in meshes:
                if new.groups.get(m, 0) != old.groups.get(m, 0):
                    changed_meshes.add(m)
            self._state[kind] = new
        changed_lights: set[str] = set()
        for path, usd in self._lights.items():
            lm = self._state[LIGHT_LINK].masks.get(usd, ALL_GROUPS)
            sm = self._state[SHADOW_LINK].masks.get(usd, ALL_GROUPS)
            m = LinkMasks(lm, sm)
            if m != self._masks.get(path, DEFAULT_MASKS):
                changed_lights.add(path)
            if m == DEFAULT_MASKS:
                self._masks.pop(path, None)
            else:
                self._masks[path] = m
        for usd, kind in self._cols:
            col = self._cols[(usd, kind)]
            if col is not None and col.subset_meshes:
                self._warn_once(
                    f"link-subset:{usd}:{kind}",
                    f"light <{usd}>: collection:{kind} includes a GeomSubset (face set); "
                    "the whole mesh is linked",
                )
        if changed_meshes or changed_lights:
            self.version += 1
        return changed_meshes, changed_lights

    def _resolve_kind(self, kind: str, meshes: list[str], old: _KindState) -> _KindState:
        st = _KindState()
        used = set(self._lights.values())
        linked = sorted(
            usd for (usd, k), c in self._cols.items() if k == kind and c is not None and usd in used
        )
        if not linked or not meshes:
            for usd in linked:
                st.masks[usd] = 0
                st.counts[usd] = 0
            return st
        cols = [self._cols[(usd, kind)] for usd in linked]
        sig = np.zeros((len(meshes), len(linked)), dtype=bool)
        for j, col in enumerate(cols):
            assert col is not None
            for i, m in enumerate(meshes):
                sig[i, j] = self._member(col, m)
        for j, usd in enumerate(linked):
            st.counts[usd] = int(sig[:, j].sum())
        uniq, inverse, sizes = np.unique(sig, axis=0, return_inverse=True, return_counts=True)
        inverse = np.asarray(inverse).reshape(-1)
        order = np.argsort(-sizes, kind="stable")  # largest classes first
        rank = np.empty_like(order)
        rank[order] = np.arange(len(order))
        uniq = uniq[order]
        inverse = rank[inverse]
        limit = MAX_GROUPS[kind]
        assign, merged = merge_groups(uniq, limit, union=kind == LIGHT_LINK)
        if len(merged) < len(uniq):
            widened = [
                linked[j] for j in range(len(linked)) if np.any(merged[assign, j] != uniq[:, j])
            ]
            st.merged_lights = tuple(widened)
            what = (
                "now light prims outside their light-link collection"
                if kind == LIGHT_LINK
                else "lose shadows of prims in their shadow-link collection"
            )
            self._warn_once(
                f"link-groups:{kind}",
                f"{len(uniq)} {kind} groups exceed limits.MAX_"
                f"{'LIGHT' if kind == LIGHT_LINK else 'SHADOW'}_LINK_GROUPS ({limit}); the "
                f"closest were merged: {len(widened)} lights {what}: "
                + ", ".join(f"<{p}>" for p in widened[:5])
                + (" ..." if len(widened) > 5 else ""),
            )
        cls = assign[inverse]  # merged class of each mesh
        # An unlinked scene had every mesh in group 0; a mesh new to a linked one has no
        # old group (-1).
        unknown = -1 if old.groups else 0
        ids = _stable_ids(cls, [old.groups.get(m, unknown) for m in meshes], len(merged))
        for i, m in enumerate(meshes):
            st.groups[m] = int(ids[cls[i]])
        st.n_groups = len(merged)
        for j, usd in enumerate(linked):
            mask = 0
            for c in range(len(merged)):
                if merged[c, j]:
                    mask |= 1 << int(ids[c])
            st.masks[usd] = mask
        return st


def _stable_ids(cls: np.ndarray, old: list[int], n: int) -> np.ndarray:
    """Group id of each of ``n`` classes: the old id most of its meshes had (largest
    classes choose first), else the smallest free one."""
    old_arr = np.asarray(old, dtype=np.int64)
    sizes = np.bincount(cls, minlength=n)
    ids = np.full(n, -1, dtype=np.int64)
    taken: set[int] = set()
    for c in np.argsort(-sizes, kind="stable").tolist():
        prev = old_arr[(cls == c) & (old_arr >= 0)]
        if len(prev):
            vals, counts = np.unique(prev, return_counts=True)
            for v in vals[np.argsort(-counts, kind="stable")].tolist():
                if v not in taken and v < n:
                    ids[c] = v
                    break
        if ids[c] < 0:
            ids[c] = next(i for i in range(n) if i not in taken)
        taken.add(int(ids[c]))
    return ids


__all__ = [
    "ALL_GROUPS",
    "DEFAULT_MASKS",
    "KINDS",
    "LIGHT_LINK",
    "SHADOW_LINK",
    "LinkCollection",
    "LinkMasks",
    "LinkResolver",
    "authored_link",
    "merge_groups",
    "read_collection",
]
