"""``LightLinks`` (stage validator): light and shadow linking (``scene/links.py``).

* ``link_target_missing`` -- a light's ``collection:lightLink`` or
  ``collection:shadowLink`` includes or excludes a prim that is not on the stage, or
  a collection (``</Prim.collection:name>``) whose prim or collection does not exist:
  usually a typo or a prim renamed since (an exclude of nothing excludes nothing; an
  include of nothing lights nothing).
* ``link_matches_nothing`` -- a light's light-link collection holds no geometry prim
  (the engine's own resolution: instance proxies and PointInstancer prototypes
  included), so the light lights nothing and costs its full price.
"""

from __future__ import annotations

from pxr import Sdf, Usd, UsdLux

from ..scene.links import KINDS, LIGHT_LINK
from .analysis import analysis_for
from .common import finding
from .findings import Finding


def check_links(stage: Usd.Stage) -> list[Finding]:
    ana = analysis_for(stage)
    out: list[Finding] = []
    seen: set[str] = set()
    for r in ana.lights:
        if r.light.default_linking or r.prim_path in seen:
            continue
        seen.add(r.prim_path)
        prim = stage.GetPrimAtPath(r.prim_path)
        if prim:
            out += _missing_targets(stage, prim)
    for path, members in ana.light_link_members.items():
        if not members:
            out.append(
                finding(
                    "link_matches_nothing",
                    _site(ana, path),
                    "collection:lightLink holds no geometry prim: the light lights nothing",
                )
            )
    return out


def _site(ana, light_path: str) -> str:
    for r in ana.lights:
        if r.light.path == light_path:
            return r.prim_path
    return light_path


def _missing_targets(stage: Usd.Stage, prim: Usd.Prim) -> list[Finding]:
    api = UsdLux.LightAPI(prim)
    out: list[Finding] = []
    for kind in KINDS:
        col = (
            api.GetLightLinkCollectionAPI()
            if kind == LIGHT_LINK
            else api.GetShadowLinkCollectionAPI()
        )
        for what, rel in (("includes", col.GetIncludesRel()), ("excludes", col.GetExcludesRel())):
            if not rel:
                continue
            for t in rel.GetTargets():
                problem = _target_problem(stage, t)
                if problem:
                    out.append(
                        finding(
                            "link_target_missing",
                            str(prim.GetPath()),
                            f"collection:{kind}:{what} names <{t}>: {problem}",
                        )
                    )
    return out


def _target_problem(stage: Usd.Stage, target: Sdf.Path) -> str | None:
    if target.IsPropertyPath():
        owner = stage.GetPrimAtPath(target.GetPrimPath())
        if not owner:
            return "its prim does not exist"
        if Usd.CollectionAPI.IsCollectionAPIPath(target):
            col = Usd.CollectionAPI.GetCollection(stage, target)
            if not col:
                return "no such collection"
        return None
    if not stage.GetPrimAtPath(target):
        return "no such prim"
    return None
