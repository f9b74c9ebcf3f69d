"""Light linking and shadow linking (issue 30): ``collection:lightLink`` /
``collection:shadowLink`` resolved with USD's own collection API (``scene/links.py``)
and honoured by every lighting method, the shadow maps and the bake. Real USD stages
(edited through ``Usd.Stage`` + ``apply_pending_updates``), real GL (llvmpipe), tiny
images. Every image check compares against a render of the same scene without the
light, or with the light unlinked -- never against numbers taken from this code."""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom, UsdLux
from stagegen import USDA_HEADER, camera_usda
from test_stb_reuse import SHARE_TILE

from stb_hydra import limits
from stb_hydra.renderer.engine import Engine
from stb_hydra.renderer.frame import RenderSettings
from stb_hydra.renderer.gl import preprocess, shader_library
from stb_hydra.scene.links import ALL_GROUPS, LIGHT_LINK, SHADOW_LINK, merge_groups
from stb_hydra.scene.stage_scene_index import StageSceneIndex

W, H = 128, 72
#: Image columns of the two quads (camera 5 m above the origin, 36 mm aperture at 18 mm:
#: 10 m across 128 px = 12.8 px/m; Q1 spans x in [-5, -0.5], Q2 [0.5, 5]).
Q1_COLS = slice(2, 55)
Q2_COLS = slice(73, 126)
#: Columns more than one interleaved STB footprint (32 px) from the other quad.
Q1_FAR = slice(2, 24)
Q2_FAR = slice(104, 126)
METHODS = ("reference", "tiled", "clustered", "lighttree", "stb")


def _stage(text: str) -> Usd.Stage:
    layer = Sdf.Layer.CreateAnonymous(".usda")
    layer.ImportFromString(text)
    return Usd.Stage.Open(layer)


def _quad(name: str, x0: float, x1: float, y: float = 0.0, z: float = 3.0) -> str:
    return f'''
    def Mesh "{name}"
    {{
        int[] faceVertexCounts = [4]
        int[] faceVertexIndices = [0, 1, 2, 3]
        point3f[] points = [({x0}, {y}, {-z}), ({x0}, {y}, {z}),
                            ({x1}, {y}, {z}), ({x1}, {y}, {-z})]
        color3f[] primvars:displayColor = [(0.5, 0.5, 0.5)]
    }}'''


def _links(light_link: str | None = None, shadow_exclude: str | None = None) -> str:
    out = ""
    if light_link is not None:
        out += f"""
    rel collection:lightLink:includes = <{light_link}>
    uniform bool collection:lightLink:includeRoot = 0"""
    if shadow_exclude is not None:
        out += f"""
    rel collection:shadowLink:excludes = <{shadow_exclude}>"""
    return out


def _sphere(name: str, pos, intensity: float, extra: str = "") -> str:
    return f'''
def SphereLight "{name}"
{{
    float inputs:intensity = {intensity}
    float inputs:radius = 0.05{extra}
    double3 xformOp:translate = {tuple(pos)}
    uniform token[] xformOpOrder = ["xformOp:translate"]
}}'''


HEADER = USDA_HEADER + camera_usda((0, 5, 0), -90, clipping=(0.1, 100))


def two_quads(a: str | None = "", *, b: bool = True, extra: str = "") -> Usd.Stage:
    """Quads /Geom/Q1 (left) and /Geom/Q2 (right), light A over Q1 (``a``: its link
    attributes; None: no light A) and B over Q2, both lighting both quads unlinked."""
    geom = 'def Xform "Geom"\n{' + _quad("Q1", -5, -0.5) + _quad("Q2", 0.5, 5) + "\n}\n"
    lights = ""
    if a is not None:
        lights += _sphere("A", (-2.5, 1.5, 0.0), 3000, a)
    if b:
        lights += _sphere("B", (2.5, 1.5, 0.5), 2000)
    return _stage(HEADER + geom + lights + extra)


def _render(stage: Usd.Stage, method: str, **kw) -> np.ndarray:
    opts = kw.pop("method_options", {})
    eng = Engine(
        stage, RenderSettings(width=W, height=H, lighting=method, method_options=opts, **kw)
    )
    try:
        eng.render()
        img = eng.aovs["color"][..., :3].astype(np.float64)
        assert np.isfinite(img).all()
        return img
    finally:
        eng.release()


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    """Mean absolute difference relative to the mean of ``b``."""
    return float(np.abs(a - b).mean() / max(float(np.abs(b).mean()), 1e-12))


# --- resolution (no GL) ---------------------------------------------------------------

RESOLVE_USDA = """#usda 1.0
(
    metersPerUnit = 1
    upAxis = "Y"
)
def Xform "Geom"
{
    def Mesh "a"
    {
    }
    def Mesh "b"
    {
        def GeomSubset "fs"
        {
        }
    }
    def Xform "c"
    {
        def Mesh "d"
        {
        }
        def Cube "e"
        {
        }
    }
}
def Xform "Sets" (
    prepend apiSchemas = ["CollectionAPI:hero"]
)
{
    rel collection:hero:includes = </Geom/c>
}
def SphereLight "All"
{
}
def SphereLight "OnlyA"
{
    rel collection:lightLink:includes = </Geom/a>
    uniform bool collection:lightLink:includeRoot = 0
}
def SphereLight "AllButC"
{
    rel collection:lightLink:excludes = </Geom/c>
}
def SphereLight "ExplicitC"
{
    uniform token collection:lightLink:expansionRule = "explicitOnly"
    rel collection:lightLink:includes = [</Geom/c>, </Geom/c/e>]
    uniform bool collection:lightLink:includeRoot = 0
}
def SphereLight "Hero"
{
    rel collection:lightLink:includes = </Sets.collection:hero>
    uniform bool collection:lightLink:includeRoot = 0
    rel collection:shadowLink:excludes = </Geom/a>
}
def SphereLight "FaceSet"
{
    rel collection:lightLink:includes = </Geom/b/fs>
    uniform bool collection:lightLink:includeRoot = 0
}
def SphereLight "RootOn"
{
    uniform bool collection:lightLink:includeRoot = 1
}
"""


def _lit(si: StageSceneIndex, light: str) -> set[str]:
    """Meshes whose link group the light's mask holds (what the renderer sees)."""
    mask = si.links.light_masks(light).light
    return {m for m in si.links._meshes if (mask >> si.links.mesh_groups(m)[0]) & 1}


def _shadowed_by(si: StageSceneIndex, light: str) -> set[str]:
    mask = si.links.light_masks(light).shadow
    return {m for m in si.links._meshes if (mask >> si.links.mesh_groups(m)[1]) & 1}


def test_membership_follows_usd_collection_rules():
    """includeRoot, includes, excludes, explicitOnly, a collection that includes another
    collection and a face-set include (whole mesh, warned), against the paths USD's own
    ``Usd.ComputeIncludedPathsFromCollection`` lists for each light."""
    stage = _stage(RESOLVE_USDA)
    si = StageSceneIndex(stage)
    meshes = {"/Geom/a", "/Geom/b", "/Geom/c/d", "/Geom/c/e"}
    assert set(si.links._meshes) == meshes
    for light in ("/OnlyA", "/AllButC", "/ExplicitC", "/Hero"):
        col = UsdLux.LightAPI(stage.GetPrimAtPath(light)).GetLightLinkCollectionAPI()
        usd = {
            str(p)
            for p in Usd.ComputeIncludedPathsFromCollection(col.ComputeMembershipQuery(), stage)
        }
        assert _lit(si, light) == meshes & usd, light
    assert _lit(si, "/OnlyA") == {"/Geom/a"}
    assert _lit(si, "/AllButC") == {"/Geom/a", "/Geom/b"}
    assert _lit(si, "/ExplicitC") == {"/Geom/c/e"}
    assert _lit(si, "/Hero") == {"/Geom/c/d", "/Geom/c/e"}
    assert _lit(si, "/FaceSet") == {"/Geom/b"}  # the subset's mesh, whole
    assert any("GeomSubset" in w and "/FaceSet" in w for w in si.warnings)
    assert _shadowed_by(si, "/Hero") == meshes - {"/Geom/a"}
    # Default collections cost nothing: no mask work, every bit set.
    for light in ("/All", "/RootOn"):
        assert si.links.light_masks(light).light == ALL_GROUPS
        assert not si.links.is_linked(light)
    # Prims with the same membership share a group.
    g = {m: si.links.mesh_groups(m)[0] for m in meshes}
    assert g["/Geom/c/d"] != g["/Geom/c/e"]  # ExplicitC tells them apart
    assert len(set(g.values())) == si.links.group_count(LIGHT_LINK) == 4
    assert si.links.group_count(SHADOW_LINK) == 2
    assert not any("not supported" in w for w in si.warnings)


INSTANCED_USDA = """#usda 1.0
(
    metersPerUnit = 1
    upAxis = "Y"
)
def Xform "Proto"
{
    def Mesh "Body"
    {
    }
}
def Xform "World"
{
    def Xform "I1" (
        instanceable = true
        references = </Proto>
    )
    {
    }
    def Xform "I2" (
        instanceable = true
        references = </Proto>
    )
    {
    }
    def PointInstancer "Inst"
    {
        rel prototypes = [</World/Inst/Protos/Ball>, </World/Inst/Protos/Cone>]
        int[] protoIndices = [0, 1, 0]
        point3f[] positions = [(0, 0, 0), (1, 0, 0), (2, 0, 0)]
        def Scope "Protos"
        {
            def Mesh "Ball"
            {
            }
            def Mesh "Cone"
            {
            }
        }
    }
}
def Scope "Elsewhere"
{
}
def SphereLight "ProxyI1"
{
    rel collection:lightLink:includes = </World/I1>
    uniform bool collection:lightLink:includeRoot = 0
}
def SphereLight "Instancer"
{
    uniform token collection:lightLink:expansionRule = "explicitOnly"
    rel collection:lightLink:includes = </World/Inst>
    uniform bool collection:lightLink:includeRoot = 0
}
def SphereLight "NoBall"
{
    rel collection:lightLink:excludes = </World/Inst/Protos/Ball>
}
def SphereLight "OnlyCone"
{
    rel collection:lightLink:includes = </World/Inst/Protos/Cone>
    uniform bool collection:lightLink:includeRoot = 0
}
def SphereLight "NoInstancer"
{
    rel collection:lightLink:excludes = </World/Inst>
}
def SphereLight "Outside"
{
    rel collection:lightLink:includes = [</World/Inst>, </Elsewhere/Cone>]
    rel collection:lightLink:excludes = </Elsewhere/Ball>
    uniform bool collection:lightLink:includeRoot = 0
}
"""


def test_instance_proxies_and_point_instancer_prototypes():
    """Native instances are linked by their proxy paths; a PointInstancer's prototype
    meshes follow the instancer (explicitOnly on the instancer included) unless the
    collection names the prototype's own namespace -- also for prototypes that live
    outside the instancer."""
    stage = _stage(INSTANCED_USDA)
    si = StageSceneIndex(stage)
    ball, cone = "/World/Inst/Protos/Ball", "/World/Inst/Protos/Cone"
    b1, b2 = "/World/I1/Body", "/World/I2/Body"
    assert {ball, cone, b1, b2} <= set(si.links._meshes)
    assert _lit(si, "/ProxyI1") == {b1}
    assert _lit(si, "/Instancer") == {ball, cone}
    assert _lit(si, "/NoBall") == {cone, b1, b2, "/Proto/Body"}
    assert _lit(si, "/OnlyCone") == {cone}
    assert _lit(si, "/NoInstancer") == {b1, b2, "/Proto/Body"}
    # A prototype outside its instancer (the scene index keys it by its own path).
    col = si.links.collection("/Outside", LIGHT_LINK)
    inst = Sdf.Path("/World/Inst")
    assert col.contains(Sdf.Path("/Elsewhere/Cone"), inst)  # named: its own path decides
    assert not col.contains(Sdf.Path("/Elsewhere/Ball"), inst)  # excluded by name
    assert col.contains(Sdf.Path("/Other/Disk"), inst)  # not named: the instancer's
    assert not si.links.collection("/OnlyCone", LIGHT_LINK).contains(Sdf.Path("/Other/Disk"), inst)


def test_group_limit_merges_over_lit_never_under_lit():
    """More distinct memberships than ``MAX_LIGHT_LINK_GROUPS``: groups are merged so a
    light may light prims outside its collection but always lights its own, with one
    warning naming lights; the merge helper combines shadow groups with AND."""
    n = limits.MAX_LIGHT_LINK_GROUPS + 8
    geom = "".join(f'    def Mesh "M{i}"\n    {{\n    }}\n' for i in range(n))
    lights = "".join(
        f'def SphereLight "L{i}"\n{{\n    rel collection:lightLink:includes = </Geom/M{i}>\n'
        "    uniform bool collection:lightLink:includeRoot = 0\n}\n"
        for i in range(n)
    )
    si = StageSceneIndex(_stage(HEADER + 'def Xform "Geom"\n{\n' + geom + "}\n" + lights))
    assert si.links.group_count(LIGHT_LINK) == limits.MAX_LIGHT_LINK_GROUPS
    widened = 0
    for i in range(n):
        lit = _lit(si, f"/L{i}")
        assert f"/Geom/M{i}" in lit  # never under-lit
        widened += len(lit) > 1
    assert widened > 0
    warns = [w for w in si.warnings if "MAX_LIGHT_LINK_GROUPS" in w]
    assert len(warns) == 1 and "</L" in warns[0]
    assert max(si.links.mesh_groups(f"/Geom/M{i}")[0] for i in range(n)) < 32
    sig = np.array([[1, 0, 1], [1, 1, 1], [0, 0, 1]], dtype=bool)
    assign, merged = merge_groups(sig, 2, union=False)
    assert len(merged) == 2 and assign[0] == assign[1]
    assert merged[assign[0]].tolist() == [True, False, True]  # AND: fewer shadows


# --- change tracking (no GL) ----------------------------------------------------------


class _Recorder:
    def __init__(self):
        self.dirtied: dict[str, set[str]] = {}

    def prims_added(self, sender, entries):
        pass

    def prims_removed(self, sender, paths):
        pass

    def prims_dirtied(self, sender, entries):
        for e in entries:
            self.dirtied.setdefault(e.path, set()).update(e.locators)


def test_collection_edits_dirty_only_what_changed():
    """Editing includes / excludes / includeRoot / expansionRule on the stage re-resolves
    the links and dirties only the lights whose masks and the meshes whose groups moved."""
    geom = 'def Xform "Geom"\n{' + "".join(_quad(f"Q{i}", i, i + 0.5) for i in range(4)) + "\n}\n"
    stage = _stage(HEADER + geom + _sphere("A", (0, 1, 0), 100, _links("/Geom/Q0")))
    stage.DefinePrim("/B", "SphereLight")
    si = StageSceneIndex(stage)
    rec = _Recorder()
    si.add_observer(rec)
    col = UsdLux.LightAPI(stage.GetPrimAtPath("/A")).GetLightLinkCollectionAPI()
    assert _lit(si, "/A") == {"/Geom/Q0"}

    col.GetIncludesRel().AddTarget("/Geom/Q1")
    si.apply_pending_updates()
    assert _lit(si, "/A") == {"/Geom/Q0", "/Geom/Q1"}
    assert "/B" not in rec.dirtied and "/Geom/Q2" not in rec.dirtied
    assert "light/collection" in rec.dirtied["/A"]
    moved = {p for p, locs in rec.dirtied.items() if "linking" in locs}
    assert moved and moved <= {"/Geom/Q0", "/Geom/Q1"}  # stable ids: Q2, Q3 keep theirs

    rec.dirtied.clear()
    col.GetIncludeRootAttr().Set(True)
    col.GetExcludesRel().AddTarget("/Geom/Q3")
    si.apply_pending_updates()
    assert _lit(si, "/A") == {"/Geom/Q0", "/Geom/Q1", "/Geom/Q2"}
    assert "/B" not in rec.dirtied

    rec.dirtied.clear()
    col.GetExcludesRel().ClearTargets(True)
    si.apply_pending_updates()  # includeRoot, nothing excluded: the default again
    assert si.links.light_masks("/A").light == ALL_GROUPS and not si.links.has_light_links

    col.GetIncludeRootAttr().Set(False)
    col.GetExpansionRuleAttr().Set("explicitOnly")
    col.GetIncludesRel().SetTargets(["/Geom"])
    si.apply_pending_updates()
    assert _lit(si, "/A") == set()  # /Geom itself is no mesh

    # Geometry added under an included prim joins the collection.
    col.GetExpansionRuleAttr().Set("expandPrims")
    si.apply_pending_updates()
    rec.dirtied.clear()
    UsdGeom.Mesh.Define(stage, "/Geom/New")
    si.apply_pending_updates()
    assert "/Geom/New" in _lit(si, "/A")
    assert "/B" not in rec.dirtied
    si.close()


# --- every method honours light links (GL) -------------------------------------------


@pytest.fixture(scope="module")
def renders(gl_ctx):
    """Per method: A linked to Q1, A unlinked, no A."""
    out = {}
    for m in ("reference", "tiled", "clustered", "lighttree"):
        out[m] = {
            "link": _render(two_quads(_links("/Geom/Q1")), m),
            "free": _render(two_quads(""), m),
            "noA": _render(two_quads(None), m),
        }
    return out


@pytest.mark.parametrize("method", ("reference", "tiled", "clustered", "lighttree"))
def test_light_linked_to_one_quad_every_exact_method(renders, method):
    """A linked to Q1 adds nothing to Q2 (= the scene without A) and all of its light to
    Q1 (= A unlinked), within 1 %; and A does light Q2 when unlinked (the test can fail)."""
    r = renders[method]
    assert _rel(r["link"][:, Q2_COLS], r["noA"][:, Q2_COLS]) < 0.01
    assert _rel(r["link"][:, Q1_COLS], r["free"][:, Q1_COLS]) < 0.01
    assert _rel(r["free"][:, Q2_COLS], r["noA"][:, Q2_COLS]) > 0.05


#: STB's two pipelines: the talk's with one sample per small tile (A and B compete in
#: every stream), and the reuse's quad-shared reservoirs (A and B in two big-tile slots,
#: each pixel's target ranks them; the slot target reads the link mask from a texture).
STB_PIPELINES = [
    pytest.param({"reuse": False, "N": 1}, id="talk"),
    pytest.param(SHARE_TILE, id="share"),
]


@pytest.mark.parametrize("pipeline", STB_PIPELINES)
def test_stb_never_selects_a_light_where_it_lights_nothing(gl_ctx, pipeline):
    """STB, same seed: far from the other quad, Q2 equals the scene without A (A is never
    selected there, so B keeps weight 1: no noise) and Q1 equals A unlinked (same
    targets, same random choices), within 1 %. With A unlinked, Q2 is not that clean
    (A steals samples). Under share, the quad's MIS weights must not depend on which
    pixel's stratum held B's slot (they did with the balance heuristic: 7 %)."""
    o = {"method_options": pipeline}
    link = _render(two_quads(_links("/Geom/Q1")), "stb", **o)
    free = _render(two_quads(""), "stb", **o)
    no_a = _render(two_quads(None), "stb", **o)
    assert _rel(link[:, Q2_FAR], no_a[:, Q2_FAR]) < 0.01
    assert _rel(link[:, Q1_FAR], free[:, Q1_FAR]) < 0.01
    assert _rel(free[:, Q2_FAR], no_a[:, Q2_FAR]) > 0.05


def test_stb_with_links_is_unbiased(gl_ctx):
    """Unbiased mode (no weight cap), N = 1: the mean of many STB frames with A linked to
    Q1 converges to the reference with the same link, quads side by side (small tiles
    hold pixels of both groups: A stays selectable there and is dropped only where it
    lights nothing). Mean radiance of the lit quad, the unlit one and the image within
    2.5 % (48 frames; dropping A from every tile that holds Q2 pixels would take >10 %
    off Q1's half next to Q2), and less noise on Q2 than with A unlinked."""
    o = {"method_options": {"N": 1, "weight_cap": None}}
    st = two_quads(_links("/Geom/Q1"))
    ref = _render(st, "reference")
    stb = _render(st, "stb", accumulate=48, **o)
    for cols in (Q1_COLS, slice(30, 55), Q2_COLS, slice(None)):
        bias = stb[:, cols].mean() / ref[:, cols].mean() - 1.0
        assert abs(bias) < 0.025, (cols, bias)
    free = two_quads("")
    noise_free = _rel(
        _render(free, "stb", accumulate=48, **o)[:, Q2_COLS], _render(free, "reference")[:, Q2_COLS]
    )
    assert _rel(stb[:, Q2_COLS], ref[:, Q2_COLS]) < noise_free


def _distant(name: str, lux: float, rot: tuple[float, float, float], extra: str = "") -> str:
    return f'''
def DistantLight "{name}"
{{
    float inputs:intensity = {lux}{extra}
    float3 xformOp:rotateXYZ = {rot}
    uniform token[] xformOpOrder = ["xformOp:rotateXYZ"]
}}'''


def _dome(name: str, nits: float, extra: str = "") -> str:
    return f'''
def DomeLight "{name}"
{{
    float inputs:intensity = {nits}{extra}
}}'''


def test_distant_and_dome_lights_are_linkable(gl_ctx):
    """`sun` and `reference`: the sun (brightest distant light) linked to Q1, a second
    distant light linked to Q2 and a dome linked to Q1 light only their quads: each quad
    equals the scene without the lights linked elsewhere, within 1 %."""
    sun = _distant("Sun", 3.0, (-60, 20, 0), _links("/Geom/Q1"))
    fill = _distant("Fill", 1.0, (-50, -40, 0), _links("/Geom/Q2"))
    dome = _dome("Sky", 0.2, _links("/Geom/Q1"))
    free = _distant("Sun", 3.0, (-60, 20, 0)) + _distant("Fill", 1.0, (-50, -40, 0))
    for method in ("sun", "reference"):
        link = _render(two_quads(None, b=False, extra=sun + fill + dome), method)
        q1_only = _render(
            two_quads(None, b=False, extra=_distant("Sun", 3.0, (-60, 20, 0)) + _dome("Sky", 0.2)),
            method,
        )
        q2_only = _render(
            two_quads(None, b=False, extra=_distant("Fill", 1.0, (-50, -40, 0))), method
        )
        unlinked = _render(two_quads(None, b=False, extra=free + _dome("Sky", 0.2)), method)
        assert _rel(link[:, Q1_COLS], q1_only[:, Q1_COLS]) < 0.01, method
        assert _rel(link[:, Q2_COLS], q2_only[:, Q2_COLS]) < 0.01, method
        assert _rel(unlinked[:, Q2_COLS], q2_only[:, Q2_COLS]) > 0.05  # the test can fail


def shadow_scene(a_extra: str = "", *, blocker: bool = True, sun: str = "") -> Usd.Stage:
    """A floor, a 2 m plate 1 m above its centre, A up-left and B up-right of it: the
    plate's shadow from A falls on x in [1, 5], from B on [-5, -1]."""
    geom = 'def Xform "Geom"\n{' + _quad("Floor", -5, 5)
    if blocker:
        geom += _quad("Plate", -1.0, 1.0, y=1.0, z=1.0)
    geom += "\n}\n"
    lights = _sphere("A", (-3.0, 2.0, 0.0), 40000, a_extra) + _sphere("B", (3.0, 2.0, 0.0), 40000)
    return _stage(HEADER + geom + lights + sun)


#: Image columns of x in [1.5, 4.5] (A's plate shadow) and [-4.5, -1.5] (B's).
A_SHADOW = slice(83, 122)
B_SHADOW = slice(6, 45)
ROWS = slice(27, 45)  # z in [-0.7, 0.7]: inside the plate's shadow along z


@pytest.mark.parametrize("method", ("reference", "stb"))
def test_shadow_link_excludes_a_blocker_for_one_light(gl_ctx, method):
    """A's shadow link excludes the plate: A's map holds no plate (the image equals the
    scene where A casts no shadows at all, within 1 %), while B still gets the plate's
    shadow (as unlinked, and darker than without the plate). STB with N = 4, two lights
    takes every light with weight 1: its terms read the same maps."""
    o = {"method_options": {"N": 4}} if method == "stb" else {}
    link = _render(shadow_scene(_links(shadow_exclude="/Geom/Plate")), method, **o)
    a_unshadowed = _render(shadow_scene("\n    bool inputs:shadow:enable = 0"), method, **o)
    free = _render(shadow_scene(""), method, **o)
    no_plate = _render(shadow_scene("", blocker=False), method, **o)
    assert _rel(link, a_unshadowed) < 0.01
    assert _rel(link[ROWS, A_SHADOW], no_plate[ROWS, A_SHADOW]) < 0.01  # no A shadow
    # B's shadow is untouched (= the unlinked scene there) and is a shadow.
    assert _rel(link[ROWS, B_SHADOW], free[ROWS, B_SHADOW]) < 0.01
    assert link[ROWS, B_SHADOW].mean() < 0.98 * no_plate[ROWS, B_SHADOW].mean()
    assert free[ROWS, A_SHADOW].mean() < 0.98 * no_plate[ROWS, A_SHADOW].mean()  # can fail


def test_sun_shadow_link(gl_ctx):
    """The sun's map holds only its shadow-link collection: with the plate excluded the
    image equals the sun with shadows off (within 1 %), and the unlinked sun does cast
    the plate's shadow."""

    def sun(extra: str) -> str:
        return _distant("Sun", 5.0, (-70, 0, 30), extra)

    kw = {"a_extra": "", "blocker": True}
    link = _render(shadow_scene(**kw, sun=sun(_links(shadow_exclude="/Geom/Plate"))), "sun")
    off = _render(shadow_scene(**kw, sun=sun("\n    bool inputs:shadow:enable = 0")), "sun")
    free = _render(shadow_scene(**kw, sun=sun("")), "sun")
    assert _rel(link, off) < 0.01
    assert _rel(free, off) > 0.01


def _static(name: str, pos, intensity: float, extra: str = "") -> str:
    return f'''
def SphereLight "{name}" (
    prepend apiSchemas = ["StbLightAPI"]
)
{{
    float inputs:intensity = {intensity}
    float inputs:radius = 0.05
    uniform token stb:mobility = "static"{extra}
    double3 xformOp:translate = {tuple(pos)}
    uniform token[] xformOpOrder = ["xformOp:translate"]
}}'''


def _bake(tmp_path, name: str, lights: str) -> dict[str, np.ndarray]:
    from stb_hydra.bake import bake_stage
    from stb_hydra.renderer.tasks.lightmap import read_lightmap

    # Q3: dynamic (not baked): the baked lights reach it per pixel at run time.
    q3 = _quad("Q3", 1.5, 3.5, y=0.2, z=1.0).replace("{\n", "{\n        bool stb:dynamic = 1\n", 1)
    geom = 'def Xform "Geom"\n{' + _quad("Q1", -5, -0.5) + _quad("Q2", 0.5, 5) + q3 + "\n}\n"
    src = tmp_path / f"{name}.usda"
    src.write_text(HEADER + geom + lights)
    out = tmp_path / f"{name}_baked.usda"
    rep = bake_stage(src, out, texel_density=2.0, cache_dir=tmp_path / "cache", progress=False)
    assert sorted(rep.meshes) == ["/Geom/Q1", "/Geom/Q2"]
    stage = Usd.Stage.Open(str(out))
    maps = {}
    for m in rep.meshes:
        f = stage.GetPrimAtPath(m).GetAttribute("stb:lightmap:file").Get().resolvedPath
        maps[m] = read_lightmap(f)[0]  # diffuse irradiance plane
        assert np.isfinite(maps[m]).all()
    maps["render"] = _render(stage, "reference")
    return maps


def test_bake_honours_light_links(tmp_path, gl_ctx):
    """`stb bake`: the static light A linked to Q1 bakes nothing into Q2's lightmap (= the
    bake without A, where only the static light C lights Q2) and all of its light into
    Q1's (= A unlinked), within 1 %; rendered, the baked A lights the dynamic Q3 (per
    pixel, no lightmap) only when unlinked."""
    c = _static("C", (2.5, 1.5, 0.5), 1000)
    link = _bake(tmp_path, "link", _static("A", (-2.5, 1.5, 0.0), 3000, _links("/Geom/Q1")) + c)
    free = _bake(tmp_path, "free", _static("A", (-2.5, 1.5, 0.0), 3000) + c)
    no_a = _bake(tmp_path, "noa", c)
    assert _rel(link["/Geom/Q2"], no_a["/Geom/Q2"]) < 0.01
    assert _rel(link["/Geom/Q1"], free["/Geom/Q1"]) < 0.01
    assert _rel(free["/Geom/Q2"], no_a["/Geom/Q2"]) > 0.05  # A does reach Q2 unlinked
    # At run time the baked A (left the light set) reaches the dynamic Q3 only unlinked.
    q3 = (slice(23, 49), slice(83, 109))  # z in [-1, 1], x in [1.5, 3.5]
    assert _rel(link["render"][q3], no_a["render"][q3]) < 0.01
    assert _rel(free["render"][q3], no_a["render"][q3]) > 0.05
    assert _rel(link["render"][:, Q1_COLS], free["render"][:, Q1_COLS]) < 0.01


def _edit_link(col: Usd.CollectionAPI, step: str) -> None:
    """One edit of A's light-link collection on the stage."""
    if step == "Q1":
        col.GetIncludeRootAttr().Set(False)
        col.GetIncludesRel().SetTargets(["/Geom/Q1"])
    elif step == "Q2":
        col.GetIncludesRel().SetTargets(["/Geom/Q2"])
    elif step == "not Q1":
        col.GetIncludeRootAttr().Set(True)
        col.GetIncludesRel().ClearTargets(True)
        col.GetExcludesRel().SetTargets(["/Geom/Q1"])
    elif step == "free again":
        col.GetExcludesRel().ClearTargets(True)


#: Edit steps and the same links authored in a fresh scene.
EDIT_STEPS = (
    ("free", ""),
    ("Q1", _links("/Geom/Q1")),
    ("Q2", _links("/Geom/Q2")),
    ("not Q1", "\n    rel collection:lightLink:excludes = </Geom/Q1>"),
    ("free again", ""),
)


def test_live_edits_re_render_without_rebuilding_the_engine(gl_ctx):
    """One engine: A unlinked, then linked to Q1, Q2, excluded from Q1, unlinked again;
    each frame equals a fresh engine on the same edited scene (reference; stb's talk
    pipeline with N = 4: two lights, every one taken with weight 1; stb's default, the
    reuse, whose slot pass writes the link masks when links exist: every frame with the
    fresh engine's seed), and the G-buffer's link target comes and goes with the links."""
    for method, opts in (
        ("reference", {}),
        ("stb", {"reuse": False, "N": 4}),
        ("stb", {}),
    ):
        stage = two_quads("")
        eng = Engine(stage, RenderSettings(width=W, height=H, lighting=method, method_options=opts))
        col = UsdLux.LightAPI(stage.GetPrimAtPath("/A")).GetLightLinkCollectionAPI()
        try:
            for step, fresh in EDIT_STEPS:
                _edit_link(col, step)
                eng.render_frame(seed=0)
                live = eng.aovs["color"][..., :3].astype(np.float64)
                assert np.isfinite(live).all()
                linked = step not in ("free", "free again")
                assert ("g_link" in eng.buffers.textures) == linked, (method, step)
                ref = _render(two_quads(fresh), method, method_options=opts)
                assert _rel(live, ref) < 0.01, (method, step)
        finally:
            eng.release()


def _strip_links(src: str) -> str:
    """``src`` without comments and without its ``#ifdef HAS_LINKS`` branches (their
    ``#else`` branches kept): what the compiler sees when HAS_LINKS is not defined."""
    out: list[str] = []
    stack: list[str] = []  # "links" (dropped), "links_else" (kept), "other"
    for raw in src.splitlines():
        line = raw.split("//", 1)[0]
        t = line.strip()
        dropping = "links" in stack
        if t.startswith(("#ifdef", "#ifndef", "#if ", "#if(")):
            stack.append("links" if t == "#ifdef HAS_LINKS" else "other")
            if stack[-1] == "other" and not dropping:
                out.append(line)
        elif t.startswith("#else") and stack and stack[-1] == "links":
            stack[-1] = "links_else"
        elif t.startswith("#endif") and stack:
            if stack.pop() == "other" and not dropping:
                out.append(line)
        elif not dropping:
            out.append(line)
    return "\n".join(out)


@pytest.mark.parametrize("method", (*METHODS, "sun"))
def test_link_free_scene_compiles_and_allocates_nothing_for_links(gl_ctx, method, monkeypatch):
    """A scene without light links (shadow links only: they never reach a shader) asks
    for no HAS_LINKS variant, allocates no g_link and no link SSBO, and every program it
    uses holds link code only inside #ifdef HAS_LINKS (so it is today's program)."""
    stage = two_quads(_links(shadow_exclude="/Geom/Q2"))
    lib = shader_library(gl_ctx)
    asked: list[tuple[tuple[str, ...], dict]] = []
    program, compute = lib.program, lib.compute

    def rec_program(vertex, fragment=None, defines=None, geometry=None):
        asked.append(((vertex, fragment or "", geometry or ""), dict(defines or {})))
        return program(vertex, fragment, defines, geometry)

    def rec_compute(name, defines=None):
        asked.append(((name,), dict(defines or {})))
        return compute(name, defines)

    monkeypatch.setattr(lib, "program", rec_program)
    monkeypatch.setattr(lib, "compute", rec_compute)
    eng = Engine(stage, RenderSettings(width=W, height=H, lighting=method))
    try:
        eng.render()
        if method == "sun":  # its scene index leaves the (linked) local lights out
            assert eng.scene_index.skipped_lights and not eng.scene_index.links.has_shadow_links
        else:
            assert eng.scene_index.links.has_shadow_links
        assert not eng.scene_index.links.has_light_links
        assert "g_link" not in eng.buffers.textures and "g_link" not in eng.describe()
        lu = next(p for p in eng.tasks if p.name == "light_upload")
        assert lu.links.ssbo is None
    finally:
        eng.release()
    assert any(st[0] == "gbuffer.vert" for st, _ in asked)
    for stages, defines in asked:
        assert "HAS_LINKS" not in defines, stages
        for name in stages:
            if name:
                src = _strip_links(preprocess(name, defines))
                for ident in ("g_link", "link_mask", "u_link_group", "link_group(", "LinkBuffer"):
                    assert ident not in src, (name, ident)
