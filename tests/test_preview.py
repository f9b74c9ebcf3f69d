"""``stb preview`` without a window (EGL): free-camera maths against closed forms,
event-script parsing, and the session's actions (progressive rendering, method and
temporal switches, light edits through change tracking, views, saved edits)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from stagegen import USDA_HEADER, camera_usda, ground_usda

from stb_hydra.preview.camera import OrbitCamera
from stb_hydra.preview.script import ScriptError, load_script, parse_events
from stb_hydra.renderer.camera import view_setup
from stb_hydra.scene.prims import CameraPrim
from stb_hydra.shadows.capture import look_at

W, H = 128, 72

#: A grey floor, a 1 m box, a warm light on the left and a cool one on the right
#: (x = -3 and +3), seen by /Cam from above and in front.
TWO_LIGHTS_USDA = (
    USDA_HEADER
    + camera_usda((0, 6, 6), -45, clipping=(0.1, 100))
    + ground_usda(10)
    + """\
def Cube "Box"
{
    double size = 1
    double3 xformOp:translate = (0, 0.5, 0)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}
def Xform "Lights"
{
    def SphereLight "Left"
    {
        float inputs:intensity = 3000
        float inputs:radius = 0.1
        color3f inputs:color = (1, 0.6, 0.4)
        double3 xformOp:translate = (-3, 1, 0)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }
    def SphereLight "Right"
    {
        float inputs:intensity = 3000
        float inputs:radius = 0.1
        color3f inputs:color = (0.4, 0.6, 1)
        double3 xformOp:translate = (3, 1, 0)
        uniform token[] xformOpOrder = ["xformOp:translate"]
    }
}
"""
)


def _project(cam: CameraPrim, p: np.ndarray, w: int = W, h: int = H) -> np.ndarray:
    v = view_setup(cam, w, h)
    c = np.append(p, 1.0) @ v.view_proj
    return c[:3] / c[3]


# -- camera maths ------------------------------------------------------------------


def test_orbit_eye_is_at_distance_and_looks_at_pivot():
    cam = OrbitCamera(pivot=np.array([1.0, 2.0, 3.0]), distance=5.0, yaw=30.0, pitch=-40.0)
    eye = cam.eye()
    assert np.linalg.norm(eye - cam.pivot) == pytest.approx(5.0)
    # pitch -40: the eye is above the pivot by d sin 40
    assert eye[1] - 2.0 == pytest.approx(5.0 * math.sin(math.radians(40.0)))
    prim = cam.to_prim(16 / 9)
    ndc = _project(prim, cam.pivot)
    assert np.allclose(ndc[:2], 0.0, atol=1e-9)  # the pivot projects to the centre


def test_tumble_keeps_pivot_and_distance_and_turns_by_the_drag():
    cam = OrbitCamera(pivot=np.zeros(3), distance=4.0, yaw=0.0, pitch=0.0)
    d0 = cam.direction()
    cam.tumble(360.0, 0.0)  # 0.25 deg/px -> 90 degrees of yaw
    assert np.linalg.norm(cam.eye()) == pytest.approx(4.0)
    assert float(d0 @ cam.direction()) == pytest.approx(0.0, abs=1e-12)
    cam.tumble(0.0, 1e6)  # pitch is clamped short of the pole
    assert abs(cam.pitch) <= 89.0


def test_track_moves_the_pivot_point_with_the_cursor():
    """A point at the pivot's depth stays under the cursor: tracking by (dx, dy) pixels
    moves the old pivot's projection by exactly (dx, dy) pixels."""
    cam = OrbitCamera(pivot=np.zeros(3), distance=10.0, yaw=20.0, pitch=-30.0)
    aspect = W / H
    p0 = cam.pivot.copy()
    cam.track(12.0, -7.0, H, aspect)
    ndc = _project(cam.to_prim(aspect), p0)
    px = (ndc[0] * 0.5 * W, -ndc[1] * 0.5 * H)  # window pixels, y down
    assert px == pytest.approx((12.0, -7.0), abs=1e-6)


def test_dolly_scales_distance_and_never_crosses_the_pivot():
    cam = OrbitCamera(pivot=np.zeros(3), distance=8.0)
    cam.dolly(wheel=1.0)
    assert cam.distance == pytest.approx(8.0 * math.exp(-0.15))
    cam.dolly(px=1e6)
    assert cam.distance > 0.0


def test_frame_fits_the_bounding_sphere_in_the_view():
    lo, hi = np.array([-1.0, 0.0, -2.0]), np.array([3.0, 2.0, 2.0])
    aspect = 16 / 9
    cam = OrbitCamera.framing(lo, hi, aspect)
    assert np.allclose(cam.pivot, 0.5 * (lo + hi))
    r = 0.5 * np.linalg.norm(hi - lo)
    # every corner projects inside the image
    prim = cam.to_prim(aspect)
    for c in np.array(np.meshgrid(*zip(lo, hi), indexing="ij")).reshape(3, -1).T:
        ndc = _project(prim, c, 160, 90)
        assert np.all(np.abs(ndc[:2]) <= 1.0)
        assert -1.0 <= ndc[2] <= 1.0  # inside the clipping range
    assert cam.distance == pytest.approx(r / math.sin(min(cam.half_fov(aspect))) * 1.05)


def test_from_prim_reproduces_the_stage_camera_view():
    prim = CameraPrim(path="/Cam", focal_length=18.0, horizontal_aperture=36.0)
    prim.transform = look_at([3.0, 4.0, 5.0], [0.0, 1.0, 0.0])
    cam = OrbitCamera.from_prim(prim, pivot_distance=2.0, scene_radius=10.0)
    assert np.allclose(cam.eye(), [3.0, 4.0, 5.0])
    assert np.allclose(cam.transform(), prim.transform, atol=1e-9)


# -- event scripts -----------------------------------------------------------------


def test_script_parses_every_event_kind(tmp_path):
    events = [
        {"wait": 3},
        {"wait": "converged"},
        {"orbit": [10, -5]},
        {"track": [1.5, 2]},
        {"dolly": 20},
        {"key": "F"},
        {"method": "stb", "options": {"N": 4}},
        {"options": {"K": 8}},
        {"temporal": "taa"},
        {"exposure": 1.0, "light": "/L"},
        {"camera": None},
        {"screenshot": "x.png"},
        {"quit": True},
    ]
    p = tmp_path / "s.json"
    p.write_text(json.dumps({"events": events}))
    out = load_script(p)
    assert [e.kind for e in out][:3] == ["wait", "wait", "orbit"]
    assert out[6].extra == {"options": {"N": 4}}
    assert out[9].kind == "light" and out[9].extra == {"exposure": 1.0}


@pytest.mark.parametrize(
    ("events", "needle"),
    [
        ([{"jump": 1}], "event 1: unknown event 'jump'"),
        ([{"wait": -1}], "'wait' needs a frame count"),
        ([{"orbit": [1]}], "'orbit' needs two numbers"),
        ([{"wait": 1}, {"temporal": "fast"}], "event 2: 'temporal' must be one of"),
        ([{"light": "/L"}], "'light' needs at least one of"),
        ([{"light": "/L", "color": [1, 2]}], "'color' must be [r, g, b]"),
        ([{"screenshot": 3}], "bad value 3 for 'screenshot'"),
        ([{"wait_file": 1}], "bad value 1 for 'wait_file'"),
        ([{"wait": 1, "speed": 2}], "unexpected key(s) 'speed'"),
        ({"wait": 1}, "expected a list of events"),
    ],
)
def test_script_errors_are_one_line_and_name_the_event(events, needle):
    with pytest.raises(ScriptError) as ei:
        parse_events(events, "s.json")
    msg = str(ei.value)
    assert needle in msg and "\n" not in msg and msg.startswith("s.json")


def test_script_file_errors(tmp_path):
    with pytest.raises(ScriptError, match="cannot read"):
        load_script(tmp_path / "missing.json")
    bad = tmp_path / "bad.json"
    bad.write_text("[{")
    with pytest.raises(ScriptError, match="not JSON"):
        load_script(bad)


# -- the session (EGL) -------------------------------------------------------------


@pytest.fixture
def scene(tmp_path):
    p = tmp_path / "two_lights.usda"
    p.write_text(TWO_LIGHTS_USDA)
    return p


def _session(scene, gl_ctx, lighting="stb", **kw):
    from stb_hydra.preview.session import PreviewSession
    from stb_hydra.renderer.frame import RenderSettings

    s = PreviewSession(
        scene, RenderSettings(width=W, height=H, lighting=lighting), ctx=gl_ctx, **kw
    )
    assert s.error is None, s.error
    return s


def _display(s) -> np.ndarray:
    t = s.display_texture()
    return np.frombuffer(t.read(), np.uint8).reshape(H, W, 4)[::-1, :, :3].astype(np.float64)


def _converge(s, limit=200) -> int:
    n = 0
    while s.step():
        n += 1
        assert n < limit
    return n


@pytest.mark.gl
def test_progressive_accumulates_to_max_samples_then_stops(scene, gl_ctx):
    s = _session(scene, gl_ctx, max_samples=5)
    try:
        assert _converge(s) == 5
        assert s.engine.settings.temporal == "accumulate" and s.engine.accumulate.count == 5
        assert s.converged and not s.step()
        s.tumble(40.0, 0.0)  # moving: taa, count restarts
        assert s.step() and s.engine.settings.temporal == "taa" and s.samples == 1
        assert _converge(s) == 5  # still again: accumulate to the budget
        assert s.engine.settings.temporal == "accumulate"
        s.moving_scale = 0.5  # --moving-scale 0.5: half resolution while moving
        s.tumble(5.0, 0.0)
        assert s.step() and s.engine.buffers.size == (W // 2, H // 2)
        assert s.display_texture().size == (W // 2, H // 2) and s.size == (W, H)
        _converge(s)
        assert s.engine.buffers.size == (W, H)  # still: full resolution again
        s.moving_scale = 1.0
        s.moving_temporal = "off"  # --while-moving off: raw frames while moving
        s.tumble(5.0, 0.0)
        assert s.step() and s.engine.settings.temporal == "off"
        _converge(s)
        assert s.engine.settings.temporal == "accumulate" and s.engine.accumulate.count == 5
        s.set_temporal("off")
        _converge(s)
        assert s.engine.accumulate.count == 1  # off: every frame on its own
    finally:
        s.release()


@pytest.mark.gl
def test_light_toggle_goes_through_the_session_layer_and_darkens_its_side(scene, gl_ctx):
    s = _session(scene, gl_ctx, max_samples=4)
    try:
        _converge(s)
        a = _display(s)
        assert s.set_light("/Lights/Left", enabled=False)
        layer = s.stage.GetSessionLayer().ExportToString()
        assert "Left" in layer and "invisible" in layer
        assert s.engine.scene_index.has_pending_updates  # change tracking, no reload
        _converge(s)
        b = _display(s)
        left, right = slice(0, W // 3), slice(2 * W // 3, W)
        assert b[:, left].mean() < 0.7 * a[:, left].mean()
        assert b[:, right].mean() == pytest.approx(a[:, right].mean(), rel=0.1)
        enabled = {r["path"]: r["enabled"] for r in s.lights()}
        assert enabled == {"/Lights/Left": False, "/Lights/Right": True}
        assert s.set_light("/Lights/Right", intensity=6000.0, color=[1, 0, 0])
        _converge(s)
        c = _display(s)
        assert c[:, right, 0].mean() > b[:, right, 0].mean()  # brighter, redder
        assert c[:, right, 2].mean() < b[:, right, 2].mean()
        assert not s.set_light("/Nope", enabled=False) and "not found" in s.message
    finally:
        s.release()


@pytest.mark.gl
def test_method_switch_options_views_and_bad_values(scene, gl_ctx, tmp_path):
    s = _session(scene, gl_ctx, max_samples=2)
    try:
        _converge(s)
        a = _display(s)
        assert s.set_method("sun")  # no distant light: the local lights go dark
        _converge(s)
        assert _display(s).mean() < 0.3 * a.mean()
        assert not s.set_method("fast") and "unknown lighting method" in s.message
        assert s.method == "sun"  # a bad switch keeps the current method
        assert s.set_method("stb", {"N": 2})
        assert s.set_options(K=8) and s.options == {"N": 2, "K": 8}
        assert not s.set_options(N="many") and s.options == {"N": 2, "K": 8}
        assert "bigtile" in s.views()
        assert s.set_view("lightcount")
        _converge(s)
        img = s.view_image()
        assert img.shape == (H, W, 3) and img.dtype == np.uint8 and img.max() > 0
        from stb_hydra.io.debug_views import LEGEND_ROWS

        bar = img[-LEGEND_ROWS + 5].astype(int)  # the colour scale: black (0) ... red (many)
        assert bar[1].sum() < 30 and bar[-2, 0] > bar[-2, 2] + 40
        assert s.set_view("bigtile") and s.set_method("reference")
        assert s.view == "color"  # the stb-only view is dropped with the method
        assert not s.set_view("bigtile")
        color = s.engine.color
        other = next(v for v in color.views() if v != color.view)
        assert s.set_ocio_view(other) and s.engine.color.view == other
        assert not s.set_ocio_view("No Such View") and "unknown OCIO view" in s.message
        assert s.engine.color.view == other  # a bad view keeps the current one
        out = s.save_edits(tmp_path / "edits.usda")
        assert out is not None and out.read_text().startswith("#usda 1.0")
    finally:
        s.release()


@pytest.mark.gl
def test_camera_switch_frame_and_properties(scene, gl_ctx):
    s = _session(scene, gl_ctx, "reference", max_samples=1)  # noise-free
    try:
        assert s.camera_path == "/Cam"  # the stage's camera first
        _converge(s)
        a = _display(s)
        s.select("/Box")
        s.frame_selection()  # leaves the stage camera for the free one
        assert s.camera_path is None
        lo, hi = s.prim_bounds("/Box")
        assert np.allclose(lo, [-0.5, 0.0, -0.5]) and np.allclose(hi, [0.5, 1.0, 0.5])
        assert np.allclose(s.orbit.pivot, [0.0, 0.5, 0.0])
        _converge(s)
        assert np.abs(_display(s) - a).mean() > 2.0
        assert s.set_camera("/Cam")
        _converge(s)
        assert np.abs(_display(s) - a).mean() < 1.0  # back to the same view
        assert not s.set_camera("/Nope")
        props = dict(s.properties("/Lights/Left"))
        assert props["type"] == "SphereLight" and "intensity [cd]" in props
        assert props["shadow"] == "on static" and float(props["range [m]"]) > 3.0
        assert props["inputs:intensity"] == "3000"
        assert "/Lights/Left" in s.prim_paths("left")
        assert s.children("/Lights") == ["/Lights/Left", "/Lights/Right"]
    finally:
        s.release()


def test_missing_and_broken_stages_are_one_line_errors(tmp_path, gl_ctx):
    from stb_hydra.preview.session import PreviewSession
    from stb_hydra.renderer.frame import RenderSettings

    s = PreviewSession(tmp_path / "nope.usda", RenderSettings(width=W, height=H), ctx=gl_ctx)
    assert not s.ok and "file not found" in s.error and "\n" not in s.error
    assert not s.step() and s.display_texture() is None
    bad = tmp_path / "bad.usda"
    bad.write_text("#usda 1.0\ndef Mesh (\n")
    s = PreviewSession(bad, RenderSettings(width=W, height=H), ctx=gl_ctx)
    assert not s.ok and "bad.usda" in s.error and "\n" not in s.error


def _stage_camera_pixel(s):
    """World point -> viewport pixel (x, y) through /Cam's own USD frustum (its 16:9
    aperture like the viewport's, so its window maps to NDC [-1, 1])."""
    from pxr import Gf, Usd, UsdGeom

    frustum = UsdGeom.Camera(s.stage.GetPrimAtPath("/Cam")).GetCamera(Usd.TimeCode()).frustum
    to_ndc = frustum.ComputeViewMatrix() * frustum.ComputeProjectionMatrix()

    def pixel(p):
        ndc = to_ndc.Transform(Gf.Vec3d(*p))
        return int((ndc[0] + 1) * 0.5 * W), int((1 - ndc[1]) * 0.5 * H)

    return pixel


@pytest.mark.gl
def test_pick_selects_the_prim_under_the_pixel(scene, gl_ctx):
    """The box's centre and a floor pixel, located with the stage camera's own
    projection (USD's frustum, not the renderer's)."""
    s = _session(scene, gl_ctx, "reference", max_samples=1)
    try:
        _converge(s)
        pixel = _stage_camera_pixel(s)
        assert s.pick(*pixel((0.0, 0.6, 0.5))) == "/Box"
        assert s.selected == "/Box"
        assert s.pick(*pixel((-4.0, 0.0, 2.0))) == "/Ground"  # near the left edge
        assert s.pick(0, 0) is None and s.selected is None  # sky: nothing
    finally:
        s.release()


#: Four pawns of one prototype at x = -3, -1, 1, 3 (instance 1 hidden), over the floor.
INSTANCED_USDA = (
    USDA_HEADER
    + camera_usda((0, 6, 6), -45, clipping=(0.1, 100))
    + ground_usda(10)
    + """\
def PointInstancer "Pawns"
{
    point3f[] positions = [(-3, 0.5, 0), (-1, 0.5, 0), (1, 0.5, 0), (3, 0.5, 0)]
    int[] protoIndices = [0, 0, 0, 0]
    int64[] invisibleIds = [1]
    rel prototypes = [</Pawns/Protos/Pawn>]
    def Scope "Protos"
    {
        def Xform "Pawn"
        {
            def Cube "Body"
            {
                double size = 1
            }
        }
    }
}
def SphereLight "Key"
{
    float inputs:intensity = 3000
    float inputs:radius = 0.1
    double3 xformOp:translate = (0, 3, 2)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}
"""
)


@pytest.mark.gl
def test_pick_selects_one_point_instance_not_its_prototype(tmp_path, gl_ctx):
    """Each pawn picks as its own instance path (the scheme lights are synced under),
    the hidden instance is not there to pick, and the selection frames that pawn."""
    p = tmp_path / "pawns.usda"
    p.write_text(INSTANCED_USDA)
    s = _session(p, gl_ctx, "reference", max_samples=1)
    try:
        _converge(s)
        pixel = _stage_camera_pixel(s)
        for i, x in ((0, -3.0), (2, 1.0), (3, 3.0)):
            path = f"/Pawns/__instance_{i}/Pawn/Body"
            assert s.pick(*pixel((x, 0.6, 0.5))) == path
            lo, hi = s.prim_bounds(path)
            np.testing.assert_allclose(lo, [x - 0.5, 0.0, -0.5], atol=1e-5)
            np.testing.assert_allclose(hi, [x + 0.5, 1.0, 0.5], atol=1e-5)
            rows = dict(s.properties(path))
            assert rows["instance id"] == str(i) and rows["instancer"] == "/Pawns"
            assert rows["prototype"] == "/Pawns/Protos/Pawn/Body"
        assert s.pick(*pixel((-1.0, 0.6, 0.5))) == "/Ground"  # invisibleIds = [1]
        assert s.prim_bounds("/Pawns/__instance_1/Pawn/Body") is None
        assert s.properties("/Pawns/__instance_9/Pawn/Body") == []
    finally:
        s.release()


ANIMATED_USDA = TWO_LIGHTS_USDA.replace(
    "#usda 1.0\n(\n", "#usda 1.0\n(\n    startTimeCode = 1\n    endTimeCode = 10\n"
).replace(
    "double3 xformOp:translate = (-3, 1, 0)",
    "double3 xformOp:translate.timeSamples = { 1: (-3, 1, 0), 10: (3, 1, 0) }",
)


@pytest.mark.gl
def test_time_scrub_and_play_move_animated_lights_through_the_scene_index(tmp_path, gl_ctx):
    p = tmp_path / "anim.usda"
    p.write_text(ANIMATED_USDA)
    s = _session(p, gl_ctx, "reference", max_samples=1)
    try:
        assert s.time_range() == (1.0, 10.0)
        _converge(s)
        assert s.time == 1.0
        a = _display(s)
        index = s.engine.scene_index
        s.set_time(10.0)  # the warm light moves from x = -3 to x = +3
        _converge(s)
        assert s.engine.scene_index is index and s.time == 10.0  # no reload
        b = _display(s)
        third = W // 3
        assert b[:, :third, 0].mean() < 0.7 * a[:, :third, 0].mean()
        assert b[:, -third:, 0].mean() > 1.2 * a[:, -third:, 0].mean()
        s.set_playing(True)  # one time code per frame, wrapping at the end
        assert s.step() and s.time == 1.0
        assert s.step() and s.time == 2.0
        s.set_playing(False)
        _converge(s)
        assert s.time == 2.0
    finally:
        s.release()


@pytest.mark.gl
def test_live_reload_keeps_the_camera_and_survives_a_broken_file(scene, gl_ctx):
    """The file changes on disk (watchdog): reloaded, same camera; then it breaks:
    the last good scene stays and the message says why; then it is fixed again."""
    import time

    s = _session(scene, gl_ctx, "reference", max_samples=1)
    try:
        assert s.watch()
        s.tumble(30.0, 0.0)  # a free-camera view that a reload must keep
        _converge(s)
        orbit = (s.orbit.yaw, s.orbit.pitch, s.orbit.distance)
        a = _display(s)

        def wait_reload(n):
            t0 = time.monotonic()
            while s.reloads < n:
                s.step()
                time.sleep(0.05)
                assert time.monotonic() - t0 < 20, "no reload within 20 s"
            _converge(s)

        scene.write_text(
            TWO_LIGHTS_USDA.replace(
                "float inputs:intensity = 3000", "float inputs:intensity = 300", 1
            )
        )
        wait_reload(1)
        b = _display(s)
        assert (s.orbit.yaw, s.orbit.pitch, s.orbit.distance) == orbit and s.camera_path is None
        assert b[:, : W // 3].mean() < 0.7 * a[:, : W // 3].mean()  # the left light dimmed
        scene.write_text("#usda 1.0\ndef Mesh (\n")
        wait_reload(2)
        assert s.ok and "cannot reload" in s.message and "last good scene" in s.message
        assert np.array_equal(_display(s), b)
        scene.write_text(TWO_LIGHTS_USDA)
        wait_reload(3)
        assert s.message is None
        assert np.abs(_display(s) - a).mean() < 1.0
    finally:
        s.release()


@pytest.mark.gl
def test_shadow_atlas_view_outlines_every_map(scene, gl_ctx):
    from stb_hydra.preview.atlas_view import STATIC

    s = _session(scene, gl_ctx, "reference", max_samples=1)
    try:
        _converge(s)
        assert s.set_view("shadow_atlas")
        img = s.view_image()
        assert img.shape == (H, W, 3)
        outline = np.all(img == np.array(STATIC, np.uint8), axis=-1)
        task = s.engine.task("shadow_atlas")
        assert sorted(task.registered_keys()) == ["/Lights/Left", "/Lights/Right"]
        assert outline.sum() > 0  # both static maps outlined in green
        inner = img[~outline]
        assert inner.max() > 24  # the atlas depths drawn in grey inside the square
    finally:
        s.release()


def test_prim_tree_and_search_include_instance_proxies(tmp_path, gl_ctx):
    p = tmp_path / "inst.usda"
    p.write_text(
        TWO_LIGHTS_USDA
        + """
def Xform "Proto"
{
    def Cube "Part"
    {
        double size = 0.2
    }
}
def Xform "Inst1" (
    instanceable = true
    references = </Proto>
)
{
    double3 xformOp:translate = (2, 0, 2)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}
def Xform "Inst2" (
    instanceable = true
    references = </Proto>
)
{
    double3 xformOp:translate = (-2, 0, 2)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}
"""
    )
    s = _session(p, gl_ctx, "reference", max_samples=1)
    try:
        assert s.children("/Inst1") == ["/Inst1/Part"]  # an instance proxy
        assert {"/Inst1/Part", "/Inst2/Part", "/Proto/Part"} <= set(s.prim_paths("part"))
        assert s.select("/Inst2/Part") and dict(s.properties("/Inst2/Part"))["type"] == "Cube"
    finally:
        s.release()


@pytest.fixture
def imgui_ctx():
    """A Dear ImGui context without a window (panels are drawn, nothing displayed)."""
    imgui = pytest.importorskip("imgui_bundle").imgui
    ctx = imgui.create_context()
    io = imgui.get_io()
    io.set_ini_filename(None)
    io.display_size = imgui.ImVec2(800, 600)
    io.backend_flags |= imgui.BackendFlags_.renderer_has_textures
    yield imgui
    imgui.destroy_context(ctx)


def _draw_panels(imgui, s, ps, tab, mouse=None, down=False):
    from stb_hydra.preview import panels

    io = imgui.get_io()
    if mouse is not None:
        io.add_mouse_pos_event(*mouse)
        io.add_mouse_button_event(0, down)
    io.delta_time = 1 / 60
    imgui.new_frame()
    panels.draw_hud(s, ps)
    panels.draw_controls(s, ps, (800, 600))
    imgui.set_next_window_pos(imgui.ImVec2(0, 0))
    imgui.begin("tab", None, imgui.WindowFlags_.no_title_bar | imgui.WindowFlags_.no_move)
    tab(s) if tab is not panels._prims_tab else tab(s, ps)
    imgui.end()
    imgui.render()


@pytest.mark.gl
def test_panels_draw_every_tab_and_a_click_toggles_a_light(scene, gl_ctx, imgui_ctx):
    from stb_hydra.preview import panels

    imgui = imgui_ctx
    s = _session(scene, gl_ctx, max_samples=1)
    try:
        _converge(s)
        ps = panels.PanelState()
        for method in ("stb", "clustered"):
            s.set_method(method)
            s.select("/Lights/Left")
            for tab in (panels._render_tab, panels._method_options, panels._lights_tab):
                _draw_panels(imgui, s, ps, tab)
            for search in ("", "light"):
                ps.search = search
                _draw_panels(imgui, s, ps, panels._prims_tab)
            _draw_panels(imgui, s, ps, panels._time_tab)
        # the light list's first widget is /Lights/Left's enable checkbox, at the
        # window's padding: press and release on it
        assert s.lights()[0]["path"] == "/Lights/Left" and s.lights()[0]["enabled"]
        for down in (False, True, False):
            _draw_panels(imgui, s, ps, panels._lights_tab, mouse=(16.0, 16.0), down=down)
        layer = s.stage.GetSessionLayer().ExportToString()
        assert "invisible" in layer  # the click authored visibility on the session layer
        _converge(s)
        assert not s.lights()[0]["enabled"] and s.lights()[1]["enabled"]
    finally:
        s.release()


@pytest.mark.gl
def test_free_camera_keeps_the_stage_cameras_exposure(tmp_path, gl_ctx):
    """Leaving a stage camera with exposure -1 for the free camera (a zero-pixel tumble:
    the same view) shows the same image, not one twice as bright."""
    p = tmp_path / "exposed.usda"
    p.write_text(
        TWO_LIGHTS_USDA.replace(
            "float focalLength = 18", "float focalLength = 18\n    float exposure = -1", 1
        )
    )
    s = _session(p, gl_ctx, "reference", max_samples=1)
    try:
        _converge(s)
        a = _display(s)
        s.tumble(0.0, 0.0)
        assert s.camera_path is None
        _converge(s)
        b = _display(s)
        assert abs(b.mean() - a.mean()) < 0.02 * a.mean()
        assert np.abs(b - a).mean() < 1.0
    finally:
        s.release()


@pytest.mark.gl
def test_light_list_shows_links(scene, gl_ctx):
    """The light list's ``links`` line follows a light-link edit made on the stage (two
    geometry prims: the ground and the box; the edit reaches the engine by change
    tracking)."""
    from pxr import Sdf, UsdLux

    s = _session(scene, gl_ctx, max_samples=1)
    try:
        _converge(s)
        rec = {r["path"]: r for r in s.lights()}
        assert rec["/Lights/Left"]["links"] == "lights all, shadowed by all"
        assert not rec["/Lights/Left"]["linked"]
        col = UsdLux.LightAPI(s.stage.GetPrimAtPath("/Lights/Left")).GetLightLinkCollectionAPI()
        col.CreateIncludeRootAttr(False)
        col.CreateIncludesRel().SetTargets([Sdf.Path("/Ground")])
        _converge(s)
        rec = {r["path"]: r for r in s.lights()}
        assert rec["/Lights/Left"]["links"] == "lights 1 of 2 prims, shadowed by all"
        assert rec["/Lights/Left"]["linked"] and not rec["/Lights/Right"]["linked"]
    finally:
        s.release()


@pytest.mark.gl
def test_time_display_says_default_for_the_default_time_code(scene, tmp_path, gl_ctx, capfd):
    """HUD and ``stb inspect``: a stage without a time range is read at the default
    (earliest) time code, shown as "default", never as -1.79769e+308; an animated
    stage shows its time code's value."""
    from stb_hydra.apps import cli

    s = _session(scene, gl_ctx, "reference", max_samples=1)
    try:
        assert s.time is None and s.time_text == "default"
    finally:
        s.release()
    p = tmp_path / "anim.usda"
    p.write_text(ANIMATED_USDA)
    s = _session(p, gl_ctx, "reference", max_samples=1)
    try:
        assert s.time == 1.0 and s.time_text == "1"
        s.set_time(7.5)
        _converge(s)
        assert s.time_text == "7.5"
    finally:
        s.release()
    for args in ([], ["--json"]):
        capfd.readouterr()
        assert cli.main(["inspect", str(scene), *args]) == 0
        out = capfd.readouterr().out
        assert "default" in out and "e+308" not in out and "1.79769" not in out
    capfd.readouterr()
    assert cli.main(["inspect", str(scene), "--json", "--time", "3"]) == 0
    assert json.loads(capfd.readouterr().out)["time"] == 3.0


@pytest.mark.gl
def test_sun_only_session_lists_the_local_lights(scene, gl_ctx):
    """``--lighting sun`` builds its engine without the local lights it cannot draw
    (``light_filter``); the previewer's light list still shows them, so they can be
    edited before switching to a method that draws them."""
    s = _session(scene, gl_ctx, lighting="sun")
    try:
        assert [r["path"] for r in s.lights()] == ["/Lights/Left", "/Lights/Right"]
        assert s.step()
        assert s.engine.scene_index.skipped_lights == 0
    finally:
        s.release()
