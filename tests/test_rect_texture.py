"""Textured RectLights (issue 37 item 3): the rect emits and shows its texture.

* Closed form: a 1 m x 0.5 m rect 0.6 m above a Lambertian floor, facing it, whose
  texture is white on one half and black on the other lights every floor point exactly
  as the white half alone, an untextured 0.5 m x 0.5 m rect: L rho F_half, F_half the
  parallel-rectangle form factor (tests/test_area_lights.py). The exact methods cut the
  rect into 8 x 8 cells, STB into 2 x 2: both are exact for this texture.
* UsdLux's orientation: the image's first column on the rect's +X edge, its top row on
  +Y; the camera facing the emitting side sees the image upright, unmirrored.
* A missing file: one warning and uniform white; an edit of the path re-syncs.
* Mitsuba 3 (when installed): a four-colour texture over a floor and a box, per-pixel.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import OpenImageIO as oiio
import pytest
from pxr import Sdf
from stagegen import LAMBERT_FLOOR_USDA, plane_points, usda_stage
from test_area_lights import _rect_corner_ff

import stb_hydra
from stb_hydra.renderer.delegate import RenderDelegate
from stb_hydra.renderer.render_index import RenderIndex
from stb_hydra.scene.stage_scene_index import StageSceneIndex

RHO = 0.5
W, H = 96, 54
L = 1000.0


def write_png(path: Path, img8: np.ndarray) -> str:
    """An 8-bit RGB PNG (sRGB: 0 and 255 decode to exactly 0 and 1)."""
    h, w = img8.shape[:2]
    out = oiio.ImageOutput.create(str(path))
    assert out is not None
    out.open(str(path), oiio.ImageSpec(w, h, 3, oiio.UINT8))
    out.write_image(np.ascontiguousarray(img8, np.uint8))
    out.close()
    return str(path)


def half_texture(tmp_path: Path, white_left: bool = True) -> str:
    """2 x 1 texture: white left column (on the rect's +X half), black right one."""
    img = np.zeros((1, 2, 3), np.uint8)
    img[0, 0 if white_left else 1] = 255
    return write_png(tmp_path / f"half_{int(white_left)}.png", img)


def rect_light(tex: str | None, w: float = 1.0, x: float = 0.0, extra: str = "") -> str:
    """A w x 0.5 m RectLight 0.6 m above the floor at x, facing down (rotateX -90: light
    +X = world +X, light +Y = world -Z); specular off."""
    t = f"    asset inputs:texture:file = @{tex}@\n" if tex else ""
    return (
        f'def RectLight "L" {{\n    float inputs:intensity = {L}\n    float inputs:specular = 0\n'
        f"    float inputs:width = {w}\n    float inputs:height = 0.5\n{t}{extra}"
        f"    double3 xformOp:translate = ({x}, 0.6, 0)\n    float xformOp:rotateX = -90\n"
        '    uniform token[] xformOpOrder = ["xformOp:translate", "xformOp:rotateX"]\n}\n'
    )


def floor_stage(light: str):
    return usda_stage(LAMBERT_FLOOR_USDA.format(rho=RHO, light=light))


def white_half_expected(stage) -> tuple[np.ndarray, np.ndarray]:
    """(floor points, L rho F) of the white half: x in [0, 0.5], z in [-0.25, 0.25]."""
    p = plane_points(stage, W, H)
    x, z = p[..., 0], p[..., 2]
    F = sum(
        _rect_corner_ff(x0 - x, sz * 0.25 - z, 0.6) * sx * sz
        for sx, x0 in ((1, 0.5), (-1, 0.0))
        for sz in (-1, 1)
    )
    return p, RHO * L * F


@pytest.mark.parametrize("method", ["reference", "stb"])
def test_half_texture_lights_like_its_white_half(gl_ctx, tmp_path, method):
    """Every floor pixel = L rho F of the white half (the mean would be 0.5 L over the
    whole rect: up to 2x off beside it); the white side is the bright one."""
    stage = floor_stage(rect_light(half_texture(tmp_path)))
    img = stb_hydra.render(stage, width=W, height=H, lighting=method, shadows=False)
    g = img[..., 1].astype(np.float64)
    p, expect = white_half_expected(stage)
    m = expect > 0.01 * expect.max()
    rel = np.abs(g[m] - expect[m]) / expect[m]
    assert np.median(rel) < 2e-3 and rel.max() < 1e-2, (np.median(rel), rel.max())
    # 1 m to the white (+X) side against 1 m to the black side, on the light's axis.
    d = np.hypot(p[..., 0] - 1.0, p[..., 2]), np.hypot(p[..., 0] + 1.0, p[..., 2])
    white, black = g.flat[np.argmin(d[0])], g.flat[np.argmin(d[1])]
    assert white > 3.0 * black > 0.0, (white, black)


def test_exact_methods_equal_the_reference(gl_ctx, tmp_path):
    """tiled and clustered share the reference's light code (RECT_TEXTURE_EXACT): the
    same image to 1e-4 (tests/test_baselines.py's bar), on a texture that is not
    constant over the 8 x 8 cells (a smooth gradient x a checker)."""
    yy, xx = np.mgrid[0:16, 0:16]
    img = np.stack([xx * 16, yy * 16, ((xx + yy) % 2) * 255], axis=-1).astype(np.uint8)
    stage = floor_stage(rect_light(write_png(tmp_path / "grad.png", img)))
    kw = {"width": 64, "height": 36, "shadows": False}
    ref = stb_hydra.render(stage, lighting="reference", **kw).astype(np.float64)
    assert ref.max() > 0
    for method in ("tiled", "clustered"):
        got = stb_hydra.render(stage, lighting=method, **kw).astype(np.float64)
        assert np.abs(got - ref).max() <= 1e-4 * ref.max(), method


@pytest.mark.parametrize(
    ("method", "coat"), [("reference", False), ("stb", False), ("reference", True)]
)
def test_half_texture_glossy_equals_its_white_half(gl_ctx, tmp_path, method, coat):
    """The specular lobe (LTC, per cell): on a GGX metal floor (roughness 0.3; with
    ``coat``, under a clearcoat of roughness 0.1) the half texture reflects exactly what
    the white half alone, an untextured 0.5 m rect, does (LTC integrals add over the
    cells; both lights are wide for the lobes)."""
    from area_scenes import glossy_stage

    def stage(light: str):
        st = glossy_stage("rect", 0.3, light.replace("inputs:specular = 0", "inputs:specular = 1"))
        if coat:
            pbr = st.GetPrimAtPath("/Looks/Grey/PBR")
            pbr.CreateAttribute("inputs:clearcoat", Sdf.ValueTypeNames.Float).Set(1.0)
            rough = pbr.CreateAttribute("inputs:clearcoatRoughness", Sdf.ValueTypeNames.Float)
            rough.Set(0.1)
        return st

    kw = {"width": W, "height": H, "lighting": method, "shadows": False}
    on = stage(rect_light(half_texture(tmp_path)))
    got = stb_hydra.render(on, **kw)[..., 1].astype(np.float64)
    want = stb_hydra.render(stage(rect_light(None, w=0.5, x=0.25)), **kw)[..., 1].astype(np.float64)
    m = want > 0.01 * want.max()
    rel = np.abs(got[m] - want[m]) / want[m]
    assert np.median(rel) < 2e-3 and rel.max() < 2e-2, (np.median(rel), rel.max())


# --- what the camera sees ---------------------------------------------------------------

FACING_USDA = """#usda 1.0
(
    metersPerUnit = 1
    upAxis = "Y"
)
def Camera "Cam"
{{
    float focalLength = 35
    float horizontalAperture = 36
    float verticalAperture = 20.25
    float2 clippingRange = (0.1, 100)
    double3 xformOp:translate = (0, 0, 3)
    uniform token[] xformOpOrder = ["xformOp:translate"]
}}
def RectLight "L"
{{
    float inputs:intensity = 2
    float inputs:width = 1.2
    float inputs:height = 0.8
    asset inputs:texture:file = @{tex}@
{extra}    float xformOp:rotateY = {turn}
    uniform token[] xformOpOrder = ["xformOp:rotateY"]
}}
"""

#: (row, column) of the 2 x 2 test image -> its colour (8-bit).
QUAD = {(0, 0): (255, 255, 255), (0, 1): (255, 0, 0), (1, 0): (0, 255, 0), (1, 1): (0, 0, 255)}


def quad_texture(tmp_path: Path) -> str:
    img = np.zeros((2, 2, 3), np.uint8)
    for (r, c), rgb in QUAD.items():
        img[r, c] = rgb
    return write_png(tmp_path / "quad.png", img)


def test_camera_sees_the_texture_upright(gl_ctx, tmp_path):
    """A rect turned to face the camera (rotateY 180: it emits along +Z): the image as
    a picture, top-left texel top-left, at radiance L x texel; its back shows nothing,
    nor does a light with visibleInPrimaryRay = 0."""
    tex = quad_texture(tmp_path)
    w, h = 128, 72
    img = stb_hydra.render(
        usda_stage(FACING_USDA.format(tex=tex, turn=180, extra="")), width=w, height=h
    )
    # The rect spans x +-0.6, y +-0.4 at 3 m: quadrant centres at +-0.3, +-0.2 m.
    f = 35.0 / 36.0 * w  # focal length in pixels
    for (r, c), rgb in QUAD.items():
        x, y = (-0.3 if c == 0 else 0.3), (0.2 if r == 0 else -0.2)
        px = img[int(h / 2 - y / 3.0 * f), int(w / 2 + x / 3.0 * f)]
        np.testing.assert_allclose(px, 2.0 * np.array(rgb) / 255.0, atol=0.02)
    back = stb_hydra.render(usda_stage(FACING_USDA.format(tex=tex, turn=0, extra="")), width=w)
    hidden = stb_hydra.render(
        usda_stage(
            FACING_USDA.format(tex=tex, turn=180, extra="    bool visibleInPrimaryRay = 0\n")
        ),
        width=w,
    )
    assert back.max() == 0.0 and hidden.max() == 0.0


# --- fallbacks and edits ------------------------------------------------------------------


def test_missing_texture_warns_once_and_emits_white(gl_ctx, tmp_path):
    stage = floor_stage(rect_light(str(tmp_path / "nope.png")))
    ri = RenderIndex(StageSceneIndex(stage), RenderDelegate())
    ri.sync_all()
    lp = ri.delegate.lights["/L"].light
    assert lp is not None and lp.rect_texture is None
    assert len([w for w in lp.warnings if "nope.png" in w]) == 1
    np.testing.assert_allclose(lp.intensity, L * 1.0 * 0.5, rtol=1e-6)  # L x area, white
    kw = {"width": 64, "height": 36, "shadows": False}
    got = stb_hydra.render(stage, **kw)
    plain = stb_hydra.render(floor_stage(rect_light(None)), **kw)
    np.testing.assert_array_equal(got, plain)


def _mirror_edit(gl_ctx, tmp_path, edit) -> tuple[np.ndarray, np.ndarray]:
    """The floor under the half texture (white on +X) rendered, ``edit(stage, tex,
    engine)`` mirrors the texture somehow, rendered again: (before, after) green
    channels; the bright side must have moved from +X to -X."""
    from stb_hydra.renderer.engine import Engine
    from stb_hydra.renderer.frame import RenderSettings

    tex = half_texture(tmp_path, True)
    stage = floor_stage(rect_light(tex))
    p = plane_points(stage, 64, 36)
    right = np.argmin(np.hypot(p[..., 0] - 1.0, p[..., 2]))
    left = np.argmin(np.hypot(p[..., 0] + 1.0, p[..., 2]))
    settings = RenderSettings(width=64, height=36, lighting="stb", temporal="off")
    eng = Engine(stage, settings, ctx=gl_ctx)
    try:
        eng.request_aovs({"color"})
        eng.render(None)
        before = eng.aovs["color"][..., 1].copy()
        edit(stage, tex, eng)
        eng.render(None)
        after = eng.aovs["color"][..., 1].copy()
    finally:
        eng.release()
    assert before.flat[right] > 3.0 * before.flat[left]
    assert after.flat[left] > 3.0 * after.flat[right]
    return before, after


def test_texture_edit_resyncs(gl_ctx, tmp_path):
    """Authoring the mirrored texture on inputs:texture:file re-reads the light: the
    bright side of the floor moves from +X to -X."""

    def edit(stage, _tex, _eng):
        attr = stage.GetPrimAtPath("/L").GetAttribute("inputs:texture:file")
        attr.Set(Sdf.AssetPath(half_texture(tmp_path, False)))

    before, after = _mirror_edit(gl_ctx, tmp_path, edit)
    # the floor under a centred, mirrored light: the mirrored image
    assert np.abs(after - before[:, ::-1]).max() <= 1e-4 * before.max()


def test_texture_file_rewritten_on_disk_reloads(gl_ctx, tmp_path):
    """The previewer's watcher path (``Engine.reload_files``): the texture file itself
    is rewritten with the mirrored image; the light and its texture-array layer are read
    again and the bright side of the floor moves from +X to -X."""
    import os
    import time

    def edit(_stage, tex, eng):
        assert os.path.realpath(tex) in {os.path.realpath(f) for f in eng.delegate.texture_files()}
        (tmp_path / "m").mkdir()
        os.replace(half_texture(tmp_path / "m", False), tex)
        st = os.stat(tex)  # a new mtime even on a coarse clock (the texture cache's key)
        os.utime(tex, ns=(st.st_atime_ns, max(st.st_mtime_ns, time.time_ns()) + 10**9))
        assert eng.reload_files({tex}) == 1

    _mirror_edit(gl_ctx, tmp_path, edit)


# --- against Mitsuba 3 ----------------------------------------------------------------------


def test_textured_rect_against_mitsuba(gl_ctx, tmp_path):
    """The four-colour texture on the 1 m x 0.5 m rect of tests/area_scenes.py over its
    floor (no box: unshadowed, as the area-light Mitsuba tests), per-pixel relative
    luminance error against Mitsuba (tests/mitsuba_ref.py: one constant rectangle emitter
    per texel), 128 spp x 32 light samples (the same scene untextured: median 0.64 %,
    p95 2.1 % -- Mitsuba's noise); reference and STB (2 x 2 cells: exact here)."""
    mr = pytest.importorskip("mitsuba_ref")
    from area_scenes import LIGHTS, SCENE_USDA

    tex = quad_texture(tmp_path)
    light = LIGHTS["rect"].replace(
        "    float inputs:height = 0.5\n",
        f"    float inputs:height = 0.5\n    asset inputs:texture:file = @{tex}@\n",
    )
    text = SCENE_USDA.format(light=light)
    text = text[: text.index('def Cube "Box"')] + text[text.index('def Scope "Looks"') :]
    stage = usda_stage(text)
    w, h = 80, 45
    ref, hit, lit, nrm = mr.render_mitsuba(stage, w, h, 128, emitter_samples=32)
    for method in ("reference", "stb"):
        ours = stb_hydra.render(stage, width=w, height=h, lighting=method)
        err, mask, _ = mr.compare(ours, ref, hit, lit, nrm)
        assert mask.sum() > 300
        med, p95 = float(np.median(err)), float(np.percentile(err, 95))
        assert med < 0.02 and p95 < 0.06, (method, med, p95)
        ratio = float(np.median(mr.luminance(ours)[mask] / mr.luminance(ref)[mask]))
        assert abs(ratio - 1.0) < 0.01, (method, ratio)
