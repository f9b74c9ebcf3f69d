"""Lights a method cannot show are not populated (issue 34: ``stb render --lighting
sun`` with 5,000 local lights near its 50-light time).

A method without local lights (``uses_local_lights`` False: ``sun``) gets a scene
index that leaves them out (``renderer.lighting.base.light_filter``, Hydra's supported
sprim types). The peer is the same engine built for a method with local lights and
switched to ``sun`` (every light populated, synced and uploaded): the images must be
the same, and switching a filtered engine to a method with local lights must bring
every light back.
"""

from __future__ import annotations

import numpy as np
from pxr import Sdf, Usd, UsdLux

from stb_hydra.renderer.engine import Engine
from stb_hydra.renderer.frame import RenderSettings
from stb_hydra.renderer.lighting.base import drawn_without_local_lighting
from stb_hydra.scene import prims
from stb_hydra.scene.stage_scene_index import StageSceneIndex
from stb_hydra.scenegen.lights import build_lights_stage

_HEADER = '#usda 1.0\n(\n    metersPerUnit = 1\n    upAxis = "Y"\n)\n'

_LIGHTS = """
def DistantLight "sun"
{
    float inputs:intensity = 2
}
def DomeLight "dome"
{
}
def SphereLight "plain"
{
}
def SphereLight "baked"
{
    bool stb:baked = 1
    token stb:mobility = "static"
}
def RectLight "textured"
{
    asset inputs:texture:file = @missing.png@
}
def RectLight "rect"
{
}
def Mesh "emitter" (
    prepend apiSchemas = ["MeshLightAPI"]
)
{
    int[] faceVertexCounts = [3]
    int[] faceVertexIndices = [0, 1, 2]
    point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]
}
"""


def _stage(text: str) -> Usd.Stage:
    layer = Sdf.Layer.CreateAnonymous(".usda")
    layer.ImportFromString(_HEADER + text)
    return Usd.Stage.Open(layer)


def _types(si: StageSceneIndex) -> dict[str, str]:
    return {p: si.get_prim(p).prim_type for p in si.prim_paths()}  # type: ignore[union-attr]


def test_filter_keeps_the_lights_a_sun_image_shows_and_edits_bring_lights_back():
    stage = _stage(_LIGHTS)
    si = StageSceneIndex(stage, light_filter=drawn_without_local_lighting)
    assert _types(si) == {
        "/sun": prims.DISTANT_LIGHT,
        "/dome": prims.DOME_LIGHT,
        "/baked": prims.SPHERE_LIGHT,  # the lightmap pass evaluates it
        "/textured": prims.RECT_LIGHT,  # the camera may see its texture
        "/emitter": prims.MESH,  # the mesh stays, its light does not
    }
    assert si.skipped_lights == 3  # /plain, /rect, /emitter's light
    # An edit that makes a left-out light one the filter keeps adds it.
    stage.GetPrimAtPath("/plain").CreateAttribute("stb:baked", Sdf.ValueTypeNames.Bool).Set(True)
    si.apply_pending_updates()
    assert _types(si)["/plain"] == prims.SPHERE_LIGHT
    assert si.skipped_lights == 2
    # No filter: every light, as an index built without one.
    si.set_light_filter(None)
    assert si.skipped_lights == 0
    full = StageSceneIndex(stage)
    assert _types(si) == _types(full)
    assert "/emitter/__light" in _types(si)
    si.close()
    full.close()


def _local_light_count(stage: Usd.Stage) -> int:
    return sum(
        1
        for p in stage.Traverse()
        if p.HasAPI(UsdLux.LightAPI)
        and not p.IsA(UsdLux.DistantLight)
        and not p.IsA(UsdLux.DomeLight)
    )


def test_sun_engine_without_local_lights_renders_the_same_image(gl_ctx):
    stage = build_lights_stage(n_lights=40, seed=2)
    sun = UsdLux.DistantLight.Define(stage, "/Sun")
    sun.CreateIntensityAttr(3.0)
    sun.AddRotateXYZOp().Set((-50.0, 30.0, 0.0))
    n_local = _local_light_count(stage)
    assert n_local >= 30
    settings = dict(width=48, height=27, shadow_atlas_size=512, sun_shadow_size=256)
    filtered = Engine(stage, RenderSettings(lighting="sun", **settings), ctx=gl_ctx)
    full = Engine(stage, RenderSettings(lighting="bare", **settings), ctx=gl_ctx)
    try:
        assert filtered.scene_index.skipped_lights == n_local
        kinds = {sp.prim_type for sp in filtered.delegate.lights.values()}
        assert kinds == {prims.DISTANT_LIGHT}
        assert len(full.delegate.lights) == len(filtered.delegate.lights) + n_local
        full.set_lighting("sun")
        filtered.render()
        a = filtered.aovs["color"][..., :3].copy()
        full.render()
        b = full.aovs["color"][..., :3].copy()
        assert a.max() > 0.0
        np.testing.assert_array_equal(a, b)
        # A method with local lights: every light populated again, the same frame.
        filtered.set_lighting("bare")
        full.set_lighting("bare")
        assert filtered.scene_index.skipped_lights == 0
        assert set(filtered.delegate.lights) == set(full.delegate.lights)
        filtered.render()
        a = filtered.aovs["color"][..., :3].copy()
        full.render()
        b = full.aovs["color"][..., :3].copy()
        np.testing.assert_allclose(a, b, rtol=1e-5, atol=1e-6)
    finally:
        filtered.release()
        full.release()


def test_sun_engine_keeps_local_lights_of_a_stage_without_geometry(gl_ctx):
    """Nothing to frame but the lights: they are populated (camera and emptiness as
    before the filter existed)."""
    stage = _stage(
        _LIGHTS.split('def Mesh "emitter"')[0]
        + 'def SphereLight "far"\n{\n    double3 xformOp:translate = (5, 0, 0)\n'
        '    uniform token[] xformOpOrder = ["xformOp:translate"]\n}\n'
    )
    eng = Engine(stage, RenderSettings(lighting="sun", width=16, height=9), ctx=gl_ctx)
    try:
        assert eng.scene_index.skipped_lights == 0
        assert "/far" in eng.delegate.lights
    finally:
        eng.release()


def test_left_out_light_still_hands_its_state_to_its_children():
    """A light the filter leaves out that has a child: the child's inherited transform
    animation and visibility are those of an index that holds every light."""
    stage = _stage(
        'def SphereLight "moving"\n{\n'
        "    double3 xformOp:translate.timeSamples = {0: (0, 0, 0), 10: (1, 0, 0)}\n"
        '    uniform token[] xformOpOrder = ["xformOp:translate"]\n'
        '    def Mesh "child"\n    {\n        int[] faceVertexCounts = [3]\n'
        "        int[] faceVertexIndices = [0, 1, 2]\n"
        "        point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]\n    }\n}\n"
        'def SphereLight "leaf"\n{\n'
        "    double3 xformOp:translate.timeSamples = {0: (0, 0, 0), 10: (1, 0, 0)}\n"
        '    uniform token[] xformOpOrder = ["xformOp:translate"]\n}\n'
    )
    si = StageSceneIndex(stage, light_filter=drawn_without_local_lighting)
    full = StageSceneIndex(stage)
    assert _types(si) == {"/moving/child": prims.MESH}
    assert si.skipped_lights == 2
    tv = si.time_varying_paths()
    assert tv["/moving/child"] == full.time_varying_paths()["/moving/child"]
    assert tv == {"/moving/child": full.time_varying_paths()["/moving/child"]}
    si.close()
    full.close()
