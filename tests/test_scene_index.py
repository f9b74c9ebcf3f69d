"""Change tracking of the stage scene index and the render index (real USD stages)."""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom, UsdLux
from stagegen import many_lights_stage, usda_stage

from stb_hydra.renderer.delegate import RenderDelegate
from stb_hydra.renderer.render_index import RenderIndex
from stb_hydra.scene.locators import DirtyBits as D
from stb_hydra.scene.materials import read_material
from stb_hydra.scene.stage_scene_index import StageSceneIndex


def _index(stage, time=None):
    si = StageSceneIndex(stage, time)
    ri = RenderIndex(si, RenderDelegate())
    ri.sync_all()
    return si, ri


@pytest.fixture(scope="module")
def big_first_sync():
    """The 10k-light stage, its indices, and what the first sync left (taken before any
    test edits the shared stage, so the tests hold in any order)."""
    stage = many_lights_stage(10_000, animated=100, animated_group=True)
    si, ri = _index(stage, 1.0)
    first = (len(ri.delegate.lights), dict(ri.counters.by_type), si.counts_by_type())
    return stage, si, ri, first


@pytest.fixture
def big(big_first_sync):
    return big_first_sync[:3]


def test_first_sync_creates_every_light(big_first_sync):
    n_lights, by_type, counts = big_first_sync[3]
    assert n_lights == 10_010
    assert by_type["sphereLight"] == 10_010
    assert counts == {"sphereLight": 10_010}


def test_intensity_edit_resyncs_exactly_one_light_params_only(big):
    stage, si, ri = big
    prim = stage.GetPrimAtPath("/World/Lights/L4321")
    before = ri.prims["/World/Lights/L4321"].light.intensity.copy()
    prim.GetAttribute("inputs:intensity").Set(4000.0)
    si.apply_pending_updates()
    n = ri.sync_all()
    assert n == 1
    assert ri.counters.last == {"/World/Lights/L4321": D.DirtyParams}
    after = ri.prims["/World/Lights/L4321"].light.intensity
    # intensity 1000 + 4321 % 7 = 1002 -> 4000: the cd value scales with it
    np.testing.assert_allclose(after / before, 4000.0 / 1002.0, rtol=1e-6)


def test_move_resyncs_transform_only(big):
    stage, si, ri = big
    prim = stage.GetPrimAtPath("/World/Lights/L4017")
    UsdGeom.XformCommonAPI(prim).SetTranslate((1.0, 2.0, 3.0))
    si.apply_pending_updates()
    assert ri.sync_all() == 1
    assert ri.counters.last == {"/World/Lights/L4017": D.DirtyTransform}
    lp = ri.prims["/World/Lights/L4017"].light
    np.testing.assert_allclose(lp.position, [1.0, 2.0, 3.0])
    row = ri.delegate.light_table.rows["/World/Lights/L4017"]
    np.testing.assert_allclose(ri.delegate.light_table.position[row], [1.0, 2.0, 3.0])


def test_set_time_dirties_only_time_varying(big):
    _stage, si, ri = big
    n = si.set_time(10.0)
    # 100 lights with their own animation + 10 under an animated group
    assert n == 110
    assert ri.sync_all() == 110
    assert set(ri.counters.last.values()) == {D.DirtyTransform}
    moved = ri.prims["/World/Moving/M3"].light.position
    np.testing.assert_allclose(moved[1], 5.0 * 9.0 / 47.0, rtol=1e-6)
    assert si.set_time(10.0) == 0  # same time: nothing


def test_ancestor_edit_reaches_descendants():
    stage = many_lights_stage(50, animated_group=True)
    si, ri = _index(stage, 1.0)
    UsdGeom.Xformable(stage.GetPrimAtPath("/World")).AddTranslateOp().Set((0.0, 100.0, 0.0))
    si.apply_pending_updates()
    assert ri.sync_all() == 60
    assert set(ri.counters.last.values()) == {D.DirtyTransform}
    assert ri.prims["/World/Lights/L0"].light.position[1] > 49.0


def test_visibility_edit_turns_light_off_and_on():
    stage = many_lights_stage(5)
    si, ri = _index(stage, 1.0)
    img = UsdGeom.Imageable(stage.GetPrimAtPath("/World/Lights"))
    img.MakeInvisible()
    si.apply_pending_updates()
    assert ri.sync_all() == 5
    assert all(not p.light.enabled for p in ri.delegate.lights.values())
    assert not ri.delegate.light_table.local_mask().any()
    img.MakeVisible()
    si.apply_pending_updates()
    ri.sync_all()
    assert all(p.light.enabled for p in ri.delegate.lights.values())


def test_add_and_remove_prims():
    stage = many_lights_stage(3)
    si, ri = _index(stage, 1.0)
    UsdLux.DiskLight.Define(stage, "/World/Lights/NewDisk")
    si.apply_pending_updates()
    ri.sync_all()
    assert "/World/Lights/NewDisk" in ri.delegate.lights
    assert ri.counters.last["/World/Lights/NewDisk"] == D.AllDirty
    stage.RemovePrim("/World/Lights/L1")
    si.apply_pending_updates()
    ri.sync_all()
    assert "/World/Lights/L1" not in ri.delegate.lights
    assert "/World/Lights/L1" not in ri.delegate.light_table.rows
    assert len(ri.delegate.lights) == 3


def test_edit_adding_time_samples_becomes_time_varying():
    stage = many_lights_stage(3)
    si, ri = _index(stage, 1.0)
    a = stage.GetPrimAtPath("/World/Lights/L2").GetAttribute("inputs:intensity")
    a.Set(10.0, 1.0)
    a.Set(20.0, 11.0)
    si.apply_pending_updates()
    ri.sync_all()
    assert si.set_time(6.0) == 1
    ri.sync_all()
    assert ri.counters.last == {"/World/Lights/L2": D.DirtyParams}


LAYER_WITH_PROTO = """#usda 1.0
(
    defaultPrim = "Lamp"
    metersPerUnit = 1
    upAxis = "Y"
)
def Xform "Lamp"
{
    def SphereLight "Bulb"
    {
        float inputs:intensity = 100
        float inputs:radius = 0.1
        double3 xformOp:translate = (0, 2, 0)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }
}
"""


def _instanced_stage(tmp_path):
    lamp = tmp_path / "lamp.usda"
    lamp.write_text(LAYER_WITH_PROTO)
    stage = usda_stage(
        f"""#usda 1.0
(
    metersPerUnit = 1
    upAxis = "Y"
)
def Xform "World"
{{
    def Xform "A" (
        instanceable = true
        references = @{lamp}@
    )
    {{
        double3 xformOp:translate = (5, 0, 0)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }}
    def Xform "B" (
        instanceable = true
        references = @{lamp}@
    )
    {{
        double3 xformOp:translate = (-5, 0, 0)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }}
    def PointInstancer "Orbs"
    {{
        point3f[] positions = [(0, 1, 0), (0, 2, 0), (0, 3, 0)]
        int[] protoIndices = [0, 0, 0]
        rel prototypes = </World/Orbs/Proto>
        def Xform "Proto"
        {{
            def SphereLight "Glow"
            {{
                float inputs:intensity = 50
                double3 xformOp:translate = (1, 0, 0)
                uniform token[] xformOpOrder = ["xformOp:translate"]
            }}
            def Sphere "Ball"
            {{
                double radius = 0.2
            }}
        }}
    }}
}}
"""
    )
    return stage, lamp


def test_instance_proxies_and_point_instancer_expansion(tmp_path):
    stage, _lamp = _instanced_stage(tmp_path)
    _si, ri = _index(stage)
    lights = ri.delegate.lights
    assert set(lights) == {
        "/World/A/Bulb",
        "/World/B/Bulb",
        "/World/Orbs/__instance_0/Proto/Glow",
        "/World/Orbs/__instance_1/Proto/Glow",
        "/World/Orbs/__instance_2/Proto/Glow",
    }
    np.testing.assert_allclose(lights["/World/A/Bulb"].light.position, [5, 2, 0])
    np.testing.assert_allclose(
        lights["/World/Orbs/__instance_2/Proto/Glow"].light.position, [1, 3, 0]
    )
    ball = ri.delegate.meshes["/World/Orbs/Proto/Ball"].mesh
    assert ball.num_instances == 3
    np.testing.assert_allclose(ball.world_transforms()[:, 3, :3], [[0, 1, 0], [0, 2, 0], [0, 3, 0]])


def test_prototype_edit_reaches_every_instance(tmp_path):
    stage, lamp = _instanced_stage(tmp_path)
    si, ri = _index(stage)
    layer = Sdf.Layer.FindOrOpen(str(lamp))
    layer.GetAttributeAtPath("/Lamp/Bulb.inputs:intensity").default = 200.0
    si.apply_pending_updates()
    ri.sync_all()
    assert {"/World/A/Bulb", "/World/B/Bulb"} <= set(ri.counters.last)
    assert ri.counters.last["/World/A/Bulb"] & D.DirtyParams
    lp = ri.delegate.lights["/World/B/Bulb"].light
    np.testing.assert_allclose(lp.intensity, 200.0 * np.pi * 0.01, rtol=1e-6)


def test_point_instancer_positions_edit(tmp_path):
    stage, _ = _instanced_stage(tmp_path)
    si, ri = _index(stage)
    inst = UsdGeom.PointInstancer(stage.GetPrimAtPath("/World/Orbs"))
    inst.GetPositionsAttr().Set([(0, 1, 0), (0, 2, 0), (0, 9, 0)])
    si.apply_pending_updates()
    ri.sync_all()
    lp = ri.delegate.lights["/World/Orbs/__instance_2/Proto/Glow"].light
    np.testing.assert_allclose(lp.position, [1, 9, 0])
    # a fourth instance re-expands the instancer
    inst.GetPositionsAttr().Set([(0, 1, 0), (0, 2, 0), (0, 9, 0), (4, 4, 4)])
    inst.GetProtoIndicesAttr().Set([0, 0, 0, 0])
    si.apply_pending_updates()
    ri.sync_all()
    assert "/World/Orbs/__instance_3/Proto/Glow" in ri.delegate.lights
    assert ri.delegate.meshes["/World/Orbs/Proto/Ball"].mesh.num_instances == 4


def test_invisible_ids_hide_only_their_instances(tmp_path):
    """invisibleIds = [1] of four instances over two prototypes: instance 1 is gone,
    the others keep their own position, prototype and path (the mask once shifted
    every later instance onto its neighbour's index and prototype)."""
    stage, _ = _instanced_stage(tmp_path)
    orbs = stage.GetPrimAtPath("/World/Orbs")
    second = stage.DefinePrim("/World/Orbs/Proto2", "Xform")
    UsdGeom.Cube.Define(stage, second.GetPath().AppendChild("Box"))
    inst = UsdGeom.PointInstancer(orbs)
    inst.GetPrototypesRel().SetTargets(["/World/Orbs/Proto", "/World/Orbs/Proto2"])
    inst.GetPositionsAttr().Set([(0, 1, 0), (0, 2, 0), (0, 3, 0), (0, 4, 0)])
    inst.GetProtoIndicesAttr().Set([0, 0, 1, 0])
    inst.GetInvisibleIdsAttr().Set([1])
    _si, ri = _index(stage)
    glows = sorted(p for p in ri.delegate.lights if p.startswith("/World/Orbs/"))
    assert glows == [
        "/World/Orbs/__instance_0/Proto/Glow",
        "/World/Orbs/__instance_3/Proto/Glow",
    ]
    np.testing.assert_allclose(
        ri.delegate.lights["/World/Orbs/__instance_3/Proto/Glow"].light.position, [1, 4, 0]
    )
    ball = ri.delegate.meshes["/World/Orbs/Proto/Ball"].mesh
    np.testing.assert_allclose(ball.world_transforms()[:, 3, :3], [[0, 1, 0], [0, 4, 0]])
    np.testing.assert_array_equal(ball.instance_ids, [0, 3])
    box = ri.delegate.meshes["/World/Orbs/Proto2/Box"].mesh
    np.testing.assert_allclose(box.world_transforms()[:, 3, :3], [[0, 3, 0]])


def test_render_frame_from_z_up_centimetres():
    stage = usda_stage(
        """#usda 1.0
(
    metersPerUnit = 0.01
    upAxis = "Z"
)
def SphereLight "L"
{
    float inputs:radius = 10
    float inputs:intensity = 100
    double3 xformOp:translate = (100, 200, 300)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}
"""
    )
    _si, ri = _index(stage)
    lp = ri.delegate.lights["/L"].light
    np.testing.assert_allclose(lp.position, [1.0, 3.0, -2.0], atol=1e-9)
    assert lp.radius == pytest.approx(0.1)
    np.testing.assert_allclose(lp.intensity, 100 * np.pi * 0.01, rtol=1e-6)


def test_material_binding_and_shader_edit():
    stage = usda_stage(
        """#usda 1.0
(
    metersPerUnit = 1
    upAxis = "Y"
)
def Xform "W"
{
    def Cube "Box" (prepend apiSchemas = ["MaterialBindingAPI"])
    {
        rel material:binding = </W/Looks/Red>
    }
    def Scope "Looks"
    {
        def Material "Red"
        {
            token outputs:surface.connect = </W/Looks/Red/PBR.outputs:surface>
            def Shader "PBR"
            {
                uniform token info:id = "UsdPreviewSurface"
                color3f inputs:diffuseColor = (0.8, 0.1, 0.1)
                float inputs:roughness = 0.3
                token outputs:surface
            }
        }
    }
}
"""
    )
    si, ri = _index(stage)
    assert ri.delegate.meshes["/W/Box"].mesh.material == "/W/Looks/Red"
    m = ri.delegate.materials["/W/Looks/Red"].material
    np.testing.assert_allclose(m.diffuse_color, [0.8, 0.1, 0.1], rtol=1e-6)
    stage.GetPrimAtPath("/W/Looks/Red/PBR").GetAttribute("inputs:roughness").Set(0.9)
    si.apply_pending_updates()
    ri.sync_all()
    assert set(ri.counters.last) == {"/W/Looks/Red"}
    assert ri.delegate.materials["/W/Looks/Red"].material.roughness == pytest.approx(0.9)
    assert not m.uses_defaults


@pytest.mark.parametrize(
    ("surface", "why"),
    [
        ("", "no UsdPreviewSurface surface"),
        # (ND_standard_surface_surfaceshader is read as MaterialX: tests/test_materialx.py.)
        (
            'uniform token info:id = "PxrSurface"',
            "surface shader 'PxrSurface' is not UsdPreviewSurface",
        ),
    ],
)
def test_material_without_preview_surface_uses_defaults(surface, why):
    shader = (
        f"""
        token outputs:surface.connect = </W/M/S.outputs:surface>
        def Shader "S"
        {{
            {surface}
            token outputs:surface
        }}"""
        if surface
        else ""
    )
    stage = usda_stage(
        f"""#usda 1.0
def Xform "W"
{{
    def Material "M"
    {{{shader}
    }}
}}
"""
    )
    m = read_material(stage.GetPrimAtPath("/W/M"), Usd.TimeCode.Default())
    assert m.uses_defaults
    assert m.warnings == [f"material </W/M>: {why}; using defaults"]
    np.testing.assert_allclose(m.diffuse_color, 0.18)


def test_notices_are_queued_until_applied():
    stage = many_lights_stage(3)
    si, ri = _index(stage)
    stage.GetPrimAtPath("/World/Lights/L0").GetAttribute("inputs:intensity").Set(5.0)
    assert si.has_pending_updates
    assert ri.sync_all() == 0
    si.apply_pending_updates()
    assert ri.sync_all() == 1


def test_unreadable_prims_do_not_break_population():
    stage = usda_stage(
        """#usda 1.0
def "Unknown" { }
def FooBarType "Custom" { }
def Mesh "Broken"
{
    int[] faceVertexCounts = [3, 3]
    int[] faceVertexIndices = [0, 1, 7]
    point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]
}
def SphereLight "Ok" { }
"""
    )
    si, ri = _index(stage)
    assert "/Ok" in ri.delegate.lights
    assert any("Broken" in w for w in si.warnings)


def test_time_default_is_stage_start():
    stage = many_lights_stage(2, animated=2)
    si = StageSceneIndex(stage)
    assert si.time == Usd.TimeCode(1.0)


def test_attribute_authored_between_population_and_first_sync_is_read():
    """Population caches each light's authored names for its first read; an edit
    that authors a new attribute before that read must not be lost."""
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    light = UsdLux.SphereLight.Define(stage, "/L")
    light.CreateIntensityAttr(10.0)
    si = StageSceneIndex(stage)
    ri = RenderIndex(si, RenderDelegate())  # nothing synced yet
    # New attribute specs, no schema change (which would resync the whole prim).
    light.GetPrim().CreateAttribute("inputs:shaping:cone:angle", Sdf.ValueTypeNames.Float).Set(30.0)
    light.CreateColorAttr((1.0, 0.0, 0.0))
    si.apply_pending_updates()
    ri.sync_all()
    lp = ri.prims["/L"].light
    assert lp.has_cone and lp.cone_angle == pytest.approx(30.0)
    assert lp.intensity[1] == 0.0 and lp.intensity[0] > 0.0


MESH_VIS_USDA = """#usda 1.0
(
    upAxis = "Y"
    metersPerUnit = 1
)
def Xform "World"
{
    def Cube "Box"
    {
        double size = 1
    }
    def Mesh "Quad"
    {
        int[] faceVertexCounts = [4]
        int[] faceVertexIndices = [0, 1, 2, 3]
        point3f[] points = [(-1, 0, -1), (1, 0, -1), (1, 0, 1), (-1, 0, 1)]
        token visibility.timeSamples = {
            1: "inherited",
            2: "invisible",
        }
    }
}
"""


def test_mesh_visibility_edits_and_samples_reach_a_running_index():
    """A plain mesh's visibility is read from the stage after the first sync: hiding it
    (an edit, on the prim or an ancestor) and a time sample that hides it reach the
    render prims as a fresh index at the same state sees them. (The population's
    visibility hint answered every later read until 2026-12-06: an edited mesh stayed
    drawn.)"""
    stage = usda_stage(MESH_VIS_USDA)
    si, ri = _index(stage, 1.0)

    def shown():
        return {p: rp.mesh.visible for p, rp in ri.delegate.meshes.items()}

    assert shown() == {"/World/Box": True, "/World/Quad": True}
    UsdGeom.Imageable(stage.GetPrimAtPath("/World/Box")).MakeInvisible()
    si.apply_pending_updates()
    ri.sync_all()
    assert shown() == {"/World/Box": False, "/World/Quad": True}
    si.set_time(2.0)
    ri.sync_all()
    assert shown() == {"/World/Box": False, "/World/Quad": False}
    UsdGeom.Imageable(stage.GetPrimAtPath("/World/Box")).MakeVisible()
    si.apply_pending_updates()
    ri.sync_all()
    fresh = _index(stage, 2.0)[1]
    assert shown() == {p: rp.mesh.visible for p, rp in fresh.delegate.meshes.items()}
    assert shown() == {"/World/Box": True, "/World/Quad": False}
