"""Textured UsdPreviewSurface materials against closed forms (real files through OIIO,
real GL): the albedo AOV equals the texture's linearised texels, wrap modes, colour
spaces, UsdTransform2d, primvar readers, UDIM tiles, tangent-space normal maps
(radiance ratio 1/cos 30 deg), cut-outs in the image and in shadows, bad files.

Expected values come from the image files as written here and the closed-form
pixel -> st mapping of ``material_scenes`` (an orthographic camera framing the quad),
never from the renderer's own output.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from material_scenes import (
    cells,
    expected_st,
    interior,
    lookup_cells,
    ortho_camera,
    preview_material,
    primvar_reader,
    quad,
    srgb_to_linear,
    uv_texture,
    write_image,
    write_stage,
)
from pxr import Sdf, Usd

from stb_hydra.renderer.engine import Engine
from stb_hydra.renderer.frame import RenderSettings

W = H = 64
#: UsdPreviewSurface inputs of a Lambertian surface (no specular lobe).
LAMBERT = (
    "        int inputs:useSpecularWorkflow = 1\n"
    "        color3f inputs:specularColor = (0, 0, 0)\n"
    "        color3f inputs:diffuseColor = ({rho}, {rho}, {rho})\n"
)
N_CELLS = 8
CELL = 8


def render_aovs(path, aovs=("albedo",), lighting="sun", w=W, h=H, **kw):
    stage = Usd.Stage.Open(str(path))
    eng = Engine(stage, RenderSettings(width=w, height=h, lighting=lighting, **kw))
    try:
        eng.request_aovs({"color", *aovs})
        eng.render(None)
        out = {k: np.array(eng.aovs[k]) for k in ("color", *aovs)}
        return out, list(eng.delegate.warnings)
    finally:
        eng.release()


def textured_quad(tmp_path, img, color_space="auto", tex_extra="", st_scale=1.0, nodes=""):
    write_image(tmp_path / "tex.png", img)
    body = (
        ortho_camera()
        + quad("Q", "M", st_scale=st_scale)
        + preview_material(
            "M",
            textures={"color3f inputs:diffuseColor": "T.outputs:rgb"},
            nodes=uv_texture("T", "./tex.png", color_space=color_space, extra=tex_extra)
            + (nodes or primvar_reader()),
        )
    )
    return write_stage(tmp_path, body)


@pytest.mark.parametrize(
    ("color_space", "decode"),
    [("sRGB", "srgb"), ("raw", "raw"), ("auto", "srgb")],
)
def test_albedo_equals_linearised_texels(tmp_path, gl_ctx, color_space, decode):
    img = cells(N_CELLS, CELL)
    path = textured_quad(
        tmp_path,
        img,
        color_space,
        st_scale=2.0,
        tex_extra='        token inputs:wrapS = "repeat"\n        token inputs:wrapT = "repeat"\n',
    )
    out, warnings = render_aovs(path)
    s, t = expected_st(W, H, 2.0)
    v = img.astype(np.float64) / 255.0
    exp_v = srgb_to_linear(v) if decode == "srgb" else v
    exp = lookup_cells(exp_v, s % 1.0, t % 1.0)
    got = out["albedo"][..., :3].astype(np.float64)
    m = interior(s % 1.0, t % 1.0, N_CELLS)
    err = np.abs(got - exp)[m]
    assert np.median(err) <= 0.01, f"median |error| {np.median(err):.4f}"
    assert np.percentile(err, 95) <= 0.02
    assert not [w for w in warnings if "texture" in w], warnings


def test_auto_single_channel_is_raw(tmp_path, gl_ctx):
    """UsdUVTexture 'auto' (as Storm): 8-bit with 3-4 channels is sRGB, else raw."""
    img = cells(N_CELLS, CELL, channels=1)
    path = textured_quad(tmp_path, img, "auto")
    out, _ = render_aovs(path)
    s, t = expected_st(W, H)
    exp = lookup_cells(img.astype(np.float64) / 255.0, s, t)  # (h, w, 1)
    got = out["albedo"][..., :3].astype(np.float64)
    m = interior(s, t, N_CELLS)
    # 1 channel -> (r, r, r): every colour channel is the raw value.
    assert np.median(np.abs(got - exp)[m]) <= 0.01


def test_transform2d_rotates_scales_and_translates(tmp_path, gl_ctx):
    img = cells(N_CELLS, CELL)
    nodes = primvar_reader() + (
        '    def Shader "X"\n    {\n        uniform token info:id = "UsdTransform2d"\n'
        "        float2 inputs:in.connect = </M/P.outputs:result>\n"
        "        float inputs:rotation = 90\n        float2 inputs:scale = (0.5, 0.5)\n"
        "        float2 inputs:translation = (0.75, 0.25)\n        float2 outputs:result\n    }\n"
    )
    write_image(tmp_path / "tex.png", img)
    body = (
        ortho_camera()
        + quad("Q", "M")
        + preview_material(
            "M",
            textures={"color3f inputs:diffuseColor": "T.outputs:rgb"},
            nodes=uv_texture("T", "./tex.png", st_source="X.outputs:result", color_space="raw")
            + nodes,
        )
    )
    out, _ = render_aovs(write_stage(tmp_path, body))
    s, t = expected_st(W, H)
    # The spec: scale, then rotate counter-clockwise, then translate.
    a = math.radians(90.0)
    ss, tt = 0.5 * s, 0.5 * t
    u = math.cos(a) * ss - math.sin(a) * tt + 0.75
    v = math.sin(a) * ss + math.cos(a) * tt + 0.25
    assert u.min() > -1e-6 and u.max() < 1 + 1e-6 and v.min() > -1e-6 and v.max() < 1 + 1e-6
    exp = lookup_cells(img.astype(np.float64) / 255.0, u, v)
    got = out["albedo"][..., :3].astype(np.float64)
    m = interior(u, v, N_CELLS)
    assert m.sum() > 100
    assert np.median(np.abs(got - exp)[m]) <= 0.01


def _wrap(x: np.ndarray, mode: str) -> tuple[np.ndarray, np.ndarray]:
    """(coordinate in [0, 1), inside) after a wrap mode, computed here."""
    if mode == "repeat":
        return x % 1.0, np.ones_like(x, bool)
    if mode == "mirror":
        f = x % 2.0
        return np.where(f < 1.0, f, 2.0 - f), np.ones_like(x, bool)
    inside = (x >= 0.0) & (x < 1.0)
    return np.clip(x, 0.0, 1.0 - 1e-9), inside if mode == "black" else np.ones_like(x, bool)


@pytest.mark.parametrize("mode", ["repeat", "mirror", "clamp", "black", "useMetadata"])
def test_wrap_modes(tmp_path, gl_ctx, mode):
    """st spans [-1, 2): each wrap mode's copy of the texture outside [0, 1)
    (useMetadata on a PNG without wrap metadata is black, as in Storm)."""
    img = cells(4, 16)
    nodes = primvar_reader() + (
        '    def Shader "X"\n    {\n        uniform token info:id = "UsdTransform2d"\n'
        "        float2 inputs:in.connect = </M/P.outputs:result>\n"
        "        float2 inputs:scale = (3, 3)\n        float2 inputs:translation = (-1, -1)\n"
        "        float2 outputs:result\n    }\n"
    )
    extra = f'        token inputs:wrapS = "{mode}"\n        token inputs:wrapT = "{mode}"\n'
    write_image(tmp_path / "tex.png", img)
    body = (
        ortho_camera()
        + quad("Q", "M")
        + preview_material(
            "M",
            textures={"color3f inputs:diffuseColor": "T.outputs:rgb"},
            nodes=uv_texture(
                "T", "./tex.png", st_source="X.outputs:result", color_space="raw", extra=extra
            )
            + nodes,
        )
    )
    w = h = 96
    out, _ = render_aovs(write_stage(tmp_path, body), w=w, h=h)
    s, t = expected_st(w, h)
    u_raw, v_raw = 3 * s - 1, 3 * t - 1
    eff = "black" if mode == "useMetadata" else mode
    u, iu = _wrap(u_raw, eff)
    v, iv = _wrap(v_raw, eff)
    exp = lookup_cells(img.astype(np.float64) / 255.0, u, v) * (iu & iv)[..., None]
    got = out["albedo"][..., :3].astype(np.float64)
    # Away from cell edges and from the quad's own unit-square edges (filter footprint).
    m = interior(u_raw % 1.0, v_raw % 1.0, 4) & interior(u_raw, v_raw, 1, 0.05)
    assert np.median(np.abs(got - exp)[m]) <= 0.01, mode


def test_scale_bias_and_channel_outputs(tmp_path, gl_ctx):
    """rgb from a 4-channel texture through scale/bias; roughness from its 'a' output."""
    rng = np.random.default_rng(3)
    img = np.repeat(np.repeat(rng.integers(0, 255, (4, 4, 4), dtype=np.uint8), 16, 0), 16, 1)
    write_image(tmp_path / "tex.png", img)
    extra = "        float4 inputs:scale = (0.5, 0.25, 1, 0.5)\n"
    extra += "        float4 inputs:bias = (0.1, 0.2, 0, 0.25)\n"
    body = (
        ortho_camera()
        + quad("Q", "M")
        + preview_material(
            "M",
            textures={
                "color3f inputs:diffuseColor": "T.outputs:rgb",
                "float inputs:roughness": "T.outputs:a",
            },
            nodes=uv_texture("T", "./tex.png", color_space="raw", extra=extra) + primvar_reader(),
        )
    )
    out, _ = render_aovs(write_stage(tmp_path, body), aovs=("albedo",))
    s, t = expected_st(W, H)
    v = lookup_cells(img.astype(np.float64) / 255.0, s, t)
    exp_rgb = np.clip(v[..., :3] * [0.5, 0.25, 1.0] + [0.1, 0.2, 0.0], 0, 1)
    m = interior(s, t, 4)
    got = out["albedo"][..., :3].astype(np.float64)
    assert np.median(np.abs(got - exp_rgb)[m]) <= 0.01


def test_primvar_reader_float3_drives_diffuse(tmp_path, gl_ctx):
    """diffuseColor <- UsdPrimvarReader_float3 of a primvar with any name (per vertex)."""
    colors = (
        "    color3f[] primvars:tint = [(1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 0)] "
        '(interpolation = "vertex")\n'
    )
    body = (
        ortho_camera()
        + quad("Q", "M", extra=colors)
        + preview_material(
            "M",
            textures={"color3f inputs:diffuseColor": "P3.outputs:result"},
            nodes=primvar_reader("P3", "tint", "float3"),
        )
    )
    out, _ = render_aovs(write_stage(tmp_path, body))
    s, t = expected_st(W, H)
    corners = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0]], float)
    # Two triangles (0,1,2), (0,2,3): barycentric interpolation on each.
    lower = s >= t
    exp = np.where(
        lower[..., None],
        corners[0] * (1 - s)[..., None]
        + corners[1] * (s - t)[..., None]
        + corners[2] * t[..., None],
        corners[0] * (1 - t)[..., None]
        + corners[2] * s[..., None]
        + corners[3] * (t - s)[..., None],
    )
    got = out["albedo"][..., :3].astype(np.float64)
    assert np.percentile(np.abs(got - exp), 95) <= 0.02


def test_missing_texture_warns_once_and_uses_fallback(tmp_path, gl_ctx):
    body = (
        ortho_camera()
        + quad("Q", "M")
        + preview_material(
            "M",
            textures={"color3f inputs:diffuseColor": "T.outputs:rgb"},
            nodes=uv_texture(
                "T", "./nope.png", extra="        float4 inputs:fallback = (0.2, 0.4, 0.6, 1)\n"
            )
            + primvar_reader(),
        )
    )
    out, warnings = render_aovs(write_stage(tmp_path, body))
    got = out["albedo"][..., :3]
    np.testing.assert_allclose(np.median(got.reshape(-1, 3), axis=0), [0.2, 0.4, 0.6], atol=2e-3)
    msgs = [w for w in warnings if "nope.png" in w]
    assert len(msgs) == 1 and "</M/T>" in msgs[0], warnings


def test_corrupt_texture_warns_and_renders(tmp_path, gl_ctx):
    (tmp_path / "bad.png").write_bytes(b"\x89PNG\r\n\x1a\nthis is not a png")
    body = (
        ortho_camera()
        + quad("Q", "M")
        + preview_material(
            "M",
            textures={"color3f inputs:diffuseColor": "T.outputs:rgb"},
            nodes=uv_texture(
                "T", "./bad.png", extra="        float4 inputs:fallback = (0.5, 0.5, 0.5, 1)\n"
            )
            + primvar_reader(),
        )
    )
    out, warnings = render_aovs(write_stage(tmp_path, body))
    assert np.isfinite(out["color"]).all()
    np.testing.assert_allclose(np.median(out["albedo"][..., :3]), 0.5, atol=2e-3)
    assert len([w for w in warnings if "bad.png" in w]) == 1, warnings


def test_udim_tiles(tmp_path, gl_ctx):
    """<UDIM>: tile 1001 at st [0,1)^2, 1002 at [1,2) x [0,1); 1011 missing -> fallback."""
    a = np.full((16, 16, 3), (200, 20, 20), np.uint8)
    b = np.full((16, 16, 3), (20, 200, 20), np.uint8)
    write_image(tmp_path / "t.1001.png", a)
    write_image(tmp_path / "t.1002.png", b)
    write_image(tmp_path / "t.1012.png", a)  # makes the layer range cover 1011
    extra = "        float4 inputs:fallback = (0, 0, 1, 1)\n"
    body = (
        ortho_camera()
        + quad("Q", "M", st_scale=2.0)
        + preview_material(
            "M",
            textures={"color3f inputs:diffuseColor": "T.outputs:rgb"},
            nodes=uv_texture("T", "./t.<UDIM>.png", color_space="raw", extra=extra)
            + primvar_reader(),
        )
    )
    out, warnings = render_aovs(write_stage(tmp_path, body))
    got = out["albedo"][..., :3]
    s, t = expected_st(W, H, 2.0)
    m = interior(s, t, 2, 0.1)
    pick = lambda sel: np.median(got[m & sel], axis=0)  # noqa: E731
    np.testing.assert_allclose(pick((s < 1) & (t < 1)), np.array([200, 20, 20]) / 255, atol=0.01)
    np.testing.assert_allclose(pick((s > 1) & (t < 1)), np.array([20, 200, 20]) / 255, atol=0.01)
    np.testing.assert_allclose(pick((s < 1) & (t > 1)), [0, 0, 1], atol=0.01)  # 1011 missing
    np.testing.assert_allclose(pick((s > 1) & (t > 1)), np.array([200, 20, 20]) / 255, atol=0.01)
    assert not [w for w in warnings if "UDIM" in w or "t.<UDIM>" in w], warnings


# --- normal maps --------------------------------------------------------------------------


def _normal_scene(tmp_path, mapped: bool, tilt_deg: float = 30.0) -> str:
    """A quad (+Z) under a distant light tilted ``tilt_deg`` towards +X (= +s); with
    ``mapped`` its constant tangent-space normal map tilts the normal by the same angle
    towards +u, so the mapped surface faces the light."""
    a = math.radians(tilt_deg)
    n = np.array([math.sin(a), 0.0, math.cos(a)])
    texel = np.round((n * 0.5 + 0.5) * 65535).astype(np.uint16)
    write_image(tmp_path / "n.png", np.broadcast_to(texel, (8, 8, 3)).copy())
    inputs = LAMBERT.format(rho=0.5)
    tex = {}
    nodes = ""
    if mapped:
        tex = {"normal3f inputs:normal": "N.outputs:rgb"}
        nodes = (
            uv_texture(
                "N",
                "./n.png",
                color_space="raw",
                extra="        float4 inputs:scale = (2, 2, 2, 1)\n"
                "        float4 inputs:bias = (-1, -1, -1, 0)\n",
            )
            + primvar_reader()
        )
    light = (
        'def DistantLight "Sun"\n{\n    float inputs:intensity = 2\n'
        "    float inputs:angle = 0.01\n    bool inputs:normalize = 1\n"
        f"    float xformOp:rotateY = {tilt_deg:g}\n"
        '    uniform token[] xformOpOrder = ["xformOp:rotateY"]\n}\n'
    )
    body = ortho_camera() + quad("Q", "M") + preview_material("M", inputs, tex, nodes) + light
    return str(write_stage(tmp_path, body, f"n_{int(mapped)}.usda"))


@pytest.mark.parametrize("lighting", ["reference", "stb"])
def test_normal_map_tilts_the_shading_normal(tmp_path, gl_ctx, lighting):
    flat, _ = render_aovs(_normal_scene(tmp_path, False), aovs=(), lighting=lighting)
    mapped, _ = render_aovs(_normal_scene(tmp_path, True), aovs=(), lighting=lighting)
    ratio = np.median(mapped["color"][8:-8, 8:-8, 0]) / np.median(flat["color"][8:-8, 8:-8, 0])
    assert ratio == pytest.approx(1.0 / math.cos(math.radians(30.0)), rel=0.04)


def test_tangents_follow_st(gl_ctx):
    """compute_tangents: +s on a quad whose st is rotated by 90 deg is -y in object
    space... (closed form), with the bitangent along +t."""
    from stb_hydra.scene.geometry import compute_tangents

    pts = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float32)
    nrm = np.tile([0, 0, 1], (4, 1)).astype(np.float32)
    tris = np.array([[0, 1, 2], [0, 2, 3]], np.uint32)
    # st rotated: s grows along +y, t along -x.
    uv = np.array([[0, 1], [0, 0], [1, 0], [1, 1]], np.float32)
    t = compute_tangents(pts, nrm, uv, tris)
    np.testing.assert_allclose(t[:, :3], np.tile([0, 1, 0], (4, 1)), atol=1e-6)
    b = t[:, 3:4] * np.cross(nrm, t[:, :3])
    np.testing.assert_allclose(b, np.tile([-1, 0, 0], (4, 1)), atol=1e-6)
    # Mirrored st (t flipped): the sign flips.
    uv2 = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], np.float32)
    t2 = compute_tangents(pts, nrm, uv2, tris)
    np.testing.assert_allclose(t2[:, 3], -1.0)


# --- cut-outs -----------------------------------------------------------------------------


def _cutout_scene(tmp_path) -> str:
    """A 2x2-cell opacity checker quad (cut cells: opacity 0) 1 m above a floor quad,
    lit straight down by a shadowed distant light; the camera looks down through it."""
    chk = np.zeros((32, 32, 1), np.uint8)
    chk[:16, :16] = 255
    chk[16:, 16:] = 255
    write_image(tmp_path / "op.png", chk)
    top = preview_material(
        "Top",
        "        color3f inputs:diffuseColor = (0.9, 0.1, 0.1)\n"
        "        float inputs:opacityThreshold = 0.5\n",
        {"float inputs:opacity": "T.outputs:r"},
        uv_texture("T", "./op.png", material="Top", color_space="raw") + primvar_reader(),
    )
    floor = preview_material("Floor", LAMBERT.format(rho=0.5))
    light = (
        'def DistantLight "Sun"\n{\n    float inputs:intensity = 3\n'
        "    float inputs:angle = 0.01\n    bool inputs:normalize = 1\n}\n"
    )
    body = (
        ortho_camera(z=5.0)
        + quad("Checker", "Top", z=1.0)
        + quad("Ground", "Floor", x0=-1.0, y0=-1.0, size=3.0, z=0.0)
        + top
        + floor
        + light
    )
    return str(write_stage(tmp_path, body))


def test_cutout_shows_floor_through_holes_and_in_shadow(tmp_path, gl_ctx):
    """Cut cells show the floor (grey), kept cells the red top; the light shines
    through the cut cells onto the floor (alpha-tested shadow map): tilt the camera
    view to the floor under the cells via a second camera-free check -- the floor
    region seen through a cut cell is lit as an unshadowed floor."""
    out, warnings = render_aovs(_cutout_scene(tmp_path), aovs=("albedo",), lighting="reference")
    alb = out["albedo"][..., :3]
    s, t = expected_st(W, H)
    m = interior(s, t, 2, 0.15)
    kept = ((s < 0.5) & (t > 0.5)) | ((s > 0.5) & (t < 0.5))  # image rows top first
    np.testing.assert_allclose(np.median(alb[m & kept], axis=0), [0.9, 0.1, 0.1], atol=0.01)
    np.testing.assert_allclose(np.median(alb[m & ~kept], axis=0), [0.5, 0.5, 0.5], atol=0.01)
    # The floor seen through a cut cell is lit (its shadow has the same hole): radiance
    # = albedo / pi * E (E = 3 lux straight down, the floor faces the light).
    col = out["color"][..., 0]
    lit = 0.5 / math.pi * 3.0
    assert np.median(col[m & ~kept]) == pytest.approx(lit, rel=0.03)
    assert not [w for w in warnings if "material" in w], warnings


def test_cutout_shadow_pattern_on_floor(tmp_path, gl_ctx):
    """Seen from beside the checker (camera framing only the floor next to... ): the
    shadow of a cut-out checker on the floor has its holes."""
    path = _cutout_scene(tmp_path)
    text = open(path).read()
    # Move the camera below the checker (between it and the floor): it sees the floor
    # alone, with the checker's shadow pattern.
    text = text.replace(
        "double3 xformOp:translate = (0.5, 0.5, 5)", "double3 xformOp:translate = (0.5, 0.5, 0.5)"
    )
    (tmp_path / "below.usda").write_text(text)
    out, _ = render_aovs(tmp_path / "below.usda", aovs=(), lighting="reference")
    col = out["color"][..., 0]
    s, t = expected_st(W, H)
    m = interior(s, t, 2, 0.15)
    kept = ((s < 0.5) & (t > 0.5)) | ((s > 0.5) & (t < 0.5))
    lit = 0.5 / math.pi * 3.0
    assert np.median(col[m & ~kept]) == pytest.approx(lit, rel=0.03)  # through the holes
    assert np.median(col[m & kept]) < 0.02 * lit  # under the kept cells: shadow


# --- change tracking ----------------------------------------------------------------------


def test_editing_one_texture_path_reloads_only_that_texture(tmp_path, gl_ctx):
    """Two textured inputs (diffuse, roughness); the diffuse file's asset path is
    edited on the open stage: the next frame shows the new image and loads exactly one
    texture; the roughness texture stays on the GPU."""
    a = np.full((8, 8, 3), (200, 10, 10), np.uint8)
    b = np.full((8, 8, 3), (10, 10, 200), np.uint8)
    r = np.full((8, 8, 1), 128, np.uint8)
    for name, img in (("a.png", a), ("b.png", b), ("r.png", r)):
        write_image(tmp_path / name, img)
    body = (
        ortho_camera()
        + quad("Q", "M")
        + preview_material(
            "M",
            textures={
                "color3f inputs:diffuseColor": "T.outputs:rgb",
                "float inputs:roughness": "R.outputs:r",
            },
            nodes=uv_texture("T", "./a.png", color_space="raw")
            + uv_texture("R", "./r.png", color_space="raw")
            + primvar_reader(),
        )
    )
    stage = Usd.Stage.Open(str(write_stage(tmp_path, body)))
    eng = Engine(stage, RenderSettings(width=16, height=16, lighting="sun"))
    try:
        eng.request_aovs({"color", "albedo"})
        eng.render(None)
        np.testing.assert_allclose(np.median(eng.aovs["albedo"][..., 0]), 200 / 255, atol=0.01)
        cache = eng.delegate.textures
        loads = cache.stats["loads"]
        rough = next(t for k, t in cache.textures.items() if k.file.endswith("r.png"))
        stage.GetPrimAtPath("/M/T").GetAttribute("inputs:file").Set(Sdf.AssetPath("./b.png"))
        eng.render(None)
        np.testing.assert_allclose(np.median(eng.aovs["albedo"][..., 2]), 200 / 255, atol=0.01)
        assert cache.stats["loads"] == loads + 1
        still = next(t for k, t in cache.textures.items() if k.file.endswith("r.png"))
        assert still is rough  # the same GPU texture: not reloaded
        assert not [k for k in cache.textures if k.file.endswith("a.png")]  # freed
    finally:
        eng.release()


def test_changed_image_file_reloads(tmp_path, gl_ctx):
    """The previewer's file watcher calls ``reload_textures`` for a changed image: the
    next frame shows the new pixels."""
    write_image(tmp_path / "a.png", np.full((8, 8, 3), (200, 10, 10), np.uint8))
    path = textured_quad(tmp_path, cells(1, 8), "raw")  # writes tex.png
    write_image(tmp_path / "tex.png", np.full((8, 8, 3), (10, 200, 10), np.uint8))
    stage = Usd.Stage.Open(str(path))
    eng = Engine(stage, RenderSettings(width=16, height=16, lighting="sun"))
    try:
        eng.request_aovs({"color", "albedo"})
        eng.render(None)
        np.testing.assert_allclose(np.median(eng.aovs["albedo"][..., 1]), 200 / 255, atol=0.01)
        write_image(tmp_path / "tex.png", np.full((8, 8, 3), (10, 10, 200), np.uint8))
        assert eng.delegate.reload_textures({str(tmp_path / "tex.png")}) == 1
        eng.render(None)
        np.testing.assert_allclose(np.median(eng.aovs["albedo"][..., 2]), 200 / 255, atol=0.01)
    finally:
        eng.release()


def test_previewer_material_panel_records(tmp_path, gl_ctx):
    """The previewer's Materials panel: each input as a constant / texture / fallback,
    the texture as loaded on the GPU, and the warnings of what fell back."""
    from stb_hydra.preview.session import PreviewSession

    img = cells(2, 8)
    write_image(tmp_path / "tex.png", img)
    body = (
        ortho_camera()
        + quad("Q", "M")
        + preview_material(
            "M",
            "        float inputs:roughness = 0.25\n",
            {
                "color3f inputs:diffuseColor": "T.outputs:rgb",
                "float inputs:metallic": "Gone.outputs:r",
            },
            uv_texture("T", "./tex.png") + uv_texture("Gone", "./gone.png") + primvar_reader(),
        )
    )
    s = PreviewSession(
        write_stage(tmp_path, body), RenderSettings(width=32, height=32, lighting="sun"), ctx=gl_ctx
    )
    assert s.error is None, s.error
    try:
        s.step()
        (rec,) = s.materials()
        rows = {name: (kind, text) for name, kind, text in rec["inputs"]}
        assert rec["source"] == "UsdPreviewSurface" and rec["meshes"] == 1
        assert rows["diffuseColor"][0] == "texture"
        assert "tex.png" in rows["diffuseColor"][1] and "16x16" in rows["diffuseColor"][1]
        assert "sRGB" in rows["diffuseColor"][1]  # auto on an 8-bit RGB file
        assert rows["roughness"] == ("constant", "0.25")
        assert rows["metallic"][0] == "constant"  # the missing file's fallback
        assert any("gone.png" in w for w in rec["warnings"])
        assert ("material", "/M") in s.properties("/Q")
    finally:
        s.release()


def test_bake_honours_cutout_shadows(tmp_path, gl_ctx):
    """``stb bake`` of a static point light above the cut-out checker: the floor's
    lightmap has the checker's holes. The baked image (reference method, the camera
    under the checker looking at the floor) against the closed form I cos / d^2 where
    the ray to the light passes a cut cell, 0 where a kept cell blocks it."""
    from stb_hydra.bake import bake_stage

    text = open(_cutout_scene(tmp_path)).read()
    text = text[: text.index("def DistantLight")] + (
        'def SphereLight "L" (\n    prepend apiSchemas = ["StbLightAPI"]\n)\n{\n'
        "    float inputs:intensity = 30000\n    float inputs:radius = 0.01\n"
        "    float inputs:specular = 0\n    bool treatAsPoint = 1\n"
        '    uniform token stb:mobility = "static"\n'
        "    double3 xformOp:translate = (0.5, 0.5, 3)\n"
        '    uniform token[] xformOpOrder = ["xformOp:translate"]\n}\n'
    )
    text = text.replace(
        "double3 xformOp:translate = (0.5, 0.5, 5)", "double3 xformOp:translate = (0.5, 0.5, 0.5)"
    )
    src = tmp_path / "src.usda"
    src.write_text(text)
    rep = bake_stage(
        src,
        tmp_path / "baked.usda",
        texel_density=24.0,
        cache_dir=tmp_path / "cache",
        progress=False,
    )
    assert "/Ground" in rep.meshes
    out, _ = render_aovs(tmp_path / "baked.usda", aovs=(), lighting="reference")
    col = out["color"][..., 0].astype(np.float64)
    s, t = expected_st(W, H)  # the floor point (x, y) = (s, t) at z = 0
    lpos = np.array([0.5, 0.5, 3.0])
    I = 30000 * math.pi * 0.01**2
    d = np.stack([lpos[0] - s, lpos[1] - t, np.full_like(s, lpos[2])], -1)
    dist = np.linalg.norm(d, axis=-1)
    exp_lit = 0.5 / math.pi * I * d[..., 2] / dist**3
    # Where the ray to the light crosses the checker plane z = 1 (1/3 of the way up).
    hx, hy = s + (lpos[0] - s) / 3.0, t + (lpos[1] - t) / 3.0
    kept = ((hx < 0.5) & (hy > 0.5)) | ((hx > 0.5) & (hy < 0.5))
    m = interior(hx, hy, 2, 0.2)
    rel = np.abs(col - exp_lit) / exp_lit
    assert np.median(rel[m & ~kept]) < 0.03, np.median(rel[m & ~kept])
    assert np.median(col[m & kept] / exp_lit[m & kept]) < 0.05


def _write_mip_chain(path, levels):
    """A ``.tx`` (OIIO's maketx) whose stored mip levels have the given constant
    colours (level 0 16x16, each next level half the size; ``maketx:mipimages``)."""
    import OpenImageIO as oiio

    names, size = [], 16
    for i, c in enumerate(levels):
        b = oiio.ImageBuf(oiio.ImageSpec(size, size, 3, "float"))
        oiio.ImageBufAlgo.fill(b, c)
        names.append(str(path.parent / f"level{i}.exr"))
        assert b.write(names[-1]), b.geterror()
        size //= 2
    cfg = oiio.ImageSpec()
    cfg.attribute("maketx:mipimages", ";".join(names[1:]))
    cfg.attribute("maketx:fileformatname", "exr")
    src = oiio.ImageBuf(names[0])
    assert oiio.ImageBufAlgo.make_texture(oiio.MakeTxTexture, src, str(path), cfg), oiio.geterror()


def test_stored_mip_levels_are_used(tmp_path, gl_ctx):
    """A file's own mip chain (e.g. a .tx) is uploaded as stored, not rebuilt: at 4
    texels per pixel the lookup reads level 2 (blue), which level 0 (red) would never
    produce."""
    levels = [(1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 0), (1, 0, 1)]
    _write_mip_chain(tmp_path / "mips.tx", levels)
    body = (
        ortho_camera()
        + quad("Q", "M", st_scale=8.0)
        + preview_material(
            "M",
            textures={"color3f inputs:diffuseColor": "T.outputs:rgb"},
            nodes=uv_texture(
                "T",
                "./mips.tx",
                color_space="raw",
                extra='        token inputs:wrapS = "repeat"\n'
                '        token inputs:wrapT = "repeat"\n',
            )
            + primvar_reader(),
        )
    )
    out, warnings = render_aovs(write_stage(tmp_path, body), w=32, h=32)
    rgb = np.median(out["albedo"][4:-4, 4:-4, :3].reshape(-1, 3), axis=0)
    assert rgb[2] > 0.8 and rgb[0] < 0.2, rgb
    assert not warnings, warnings


def test_texture_budget_downscales_with_one_warning(tmp_path, gl_ctx):
    """Over the texture budget the largest texture is halved (its texels still read
    right: a constant-cell image) and one warning names it."""
    img = cells(4, 64)  # 256 x 256
    path = textured_quad(tmp_path, img, "raw")
    stage = Usd.Stage.Open(str(path))
    # 0.1 MiB < 256 x 256 x 4 bytes x 4/3 (the mips).
    settings = RenderSettings(width=W, height=H, lighting="sun", texture_budget_mib=0.1)
    eng = Engine(stage, settings)
    try:
        eng.request_aovs({"color", "albedo"})
        eng.render(None)
        (t,) = eng.delegate.textures.textures.values()
        assert t.shrink >= 2 and t.nbytes <= 0.1 * 2**20
        warn = [w for w in eng.delegate.warnings if "budget" in w]
        assert len(warn) == 1 and "tex.png" in warn[0], eng.delegate.warnings
        s, tt = expected_st(W, H)
        exp = lookup_cells(img.astype(np.float64) / 255.0, s, tt)
        got = eng.aovs["albedo"][..., :3].astype(np.float64)
        assert np.median(np.abs(got - exp)[interior(s, tt, 4)]) <= 0.01
    finally:
        eng.release()


# --- clearcoat ----------------------------------------------------------------------------


def _ggx_coat(theta_deg: float, rough: float) -> float:
    """The coat lobe (GGX, Smith height-correlated, Schlick F0 = 0.04) x NoL for a view
    along the normal and a light at ``theta_deg`` from it, written out here."""
    t = math.radians(theta_deg)
    nol, nov = math.cos(t), 1.0
    noh = voh = math.cos(t / 2)
    a = max(max(rough, 0.02) ** 2, 1e-3)
    a2 = a * a
    d = a2 / (math.pi * (noh * noh * (a2 - 1) + 1) ** 2)
    gv = nol * math.sqrt(nov * nov * (1 - a2) + a2)
    gl = nov * math.sqrt(nol * nol * (1 - a2) + a2)
    vis = 0.5 / (gv + gl)
    f = 0.04 + 0.96 * (1 - voh) ** 5
    return d * vis * f * nol, f


def _coat_scene(tmp_path, coat_inputs: str, base_rho: float, tilt: float, tex=None, nodes=""):
    inputs = LAMBERT.format(rho=base_rho) + coat_inputs
    light = (
        'def DistantLight "Sun"\n{\n    float inputs:intensity = 2\n'
        "    float inputs:angle = 0.01\n    bool inputs:normalize = 1\n"
        "    bool inputs:shadow:enable = 0\n"
        f"    float xformOp:rotateY = {tilt:g}\n"
        '    uniform token[] xformOpOrder = ["xformOp:rotateY"]\n}\n'
    )
    body = ortho_camera() + quad("Q", "M") + preview_material("M", inputs, tex, nodes) + light
    return write_stage(tmp_path, body, f"coat_{base_rho}_{tilt:g}.usda")


@pytest.mark.parametrize("lighting", ["reference", "stb"])
def test_clearcoat_lobe_closed_form(tmp_path, gl_ctx, lighting):
    """A black base under a clearcoat (weight 1, roughness 0.3): radiance = E x the GGX
    coat lobe; a grey Lambert base under a weight-0.5 coat: E (rho / pi (1 - Fc) cos +
    0.5 x lobe), Fc = 0.5 x Schlick(VoH)."""
    tilt = 20.0
    lobe, f = _ggx_coat(tilt, 0.3)
    coat = "        float inputs:clearcoat = {w}\n        float inputs:clearcoatRoughness = 0.3\n"
    out, _ = render_aovs(_coat_scene(tmp_path, coat.format(w=1), 0.0, tilt), (), lighting)
    got = np.median(out["color"][8:-8, 8:-8, 0])
    assert got == pytest.approx(2.0 * lobe, rel=0.03)
    out, _ = render_aovs(_coat_scene(tmp_path, coat.format(w=0.5), 0.5, tilt), (), lighting)
    got = np.median(out["color"][8:-8, 8:-8, 0])
    exp = 2.0 * (0.5 / math.pi * (1 - 0.5 * f) * math.cos(math.radians(tilt)) + 0.5 * lobe)
    assert got == pytest.approx(exp, rel=0.03)


def test_textured_clearcoat_and_no_coat_target_without_one(tmp_path, gl_ctx):
    """A clearcoat texture (left half 1, right half 0) coats the left half only; a scene
    without a coated material has no g_coat target."""
    img = np.zeros((8, 8, 1), np.uint8)
    img[:, :4] = 255
    write_image(tmp_path / "coat.png", img)
    nodes = uv_texture("C", "./coat.png", color_space="raw") + primvar_reader()
    path = _coat_scene(
        tmp_path,
        "        float inputs:clearcoatRoughness = 0.3\n",
        0.0,
        20.0,
        {"float inputs:clearcoat": "C.outputs:r"},
        nodes,
    )
    out, _ = render_aovs(path, (), "reference")
    lobe, _f = _ggx_coat(20.0, 0.3)
    col = out["color"][..., 0]
    s, _t = expected_st(W, H)
    assert np.median(col[(s < 0.4) & (s > 0.1)]) == pytest.approx(2.0 * lobe, rel=0.03)
    assert np.median(col[s > 0.6]) < 1e-4
    stage = Usd.Stage.Open(str(_coat_scene(tmp_path, "", 0.5, 20.0)))
    eng = Engine(stage, RenderSettings(width=16, height=16, lighting="reference"))
    try:
        eng.render(None)
        assert "g_coat" not in eng.buffers.textures
        assert not eng.delegate.has_clearcoat
    finally:
        eng.release()


def test_texture_headers_are_remembered_until_the_file_changes(tmp_path):
    """``read_info`` remembers a header per (file, mtime, size): a file rewritten with
    another size is read again, and a UDIM set keeps its own layers."""
    import os

    from stb_hydra.renderer.textures import read_info

    p = write_image(tmp_path / "t.png", cells(2, 4))
    a = read_info(str(p))
    assert (a.width, a.height, a.layers) == (8, 8, [(str(p), 0)])
    a.layers.append(("stray", 1))  # a caller's change does not reach the next caller
    assert read_info(str(p)).layers == [(str(p), 0)]
    st = os.stat(p)
    write_image(p, cells(4, 4))
    os.utime(p, ns=(st.st_atime_ns, st.st_mtime_ns + 1_000_000))
    b = read_info(str(p))
    assert (b.width, b.height) == (16, 16)
    for tile in (1001, 1002):
        write_image(tmp_path / f"u.{tile}.png", cells(2, 4))
    u = read_info(str(tmp_path / "u.<UDIM>.png"))
    assert [t for _p, t in u.layers] == [1001, 1002]
