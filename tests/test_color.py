"""OCIO colour correction: real OCIO (built-in studio config), real GL (EGL llvmpipe)."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest

from stb_hydra.color.ocio import (
    ColorCorrectionPass,
    ColorPipeline,
    find_linear_rec709,
    quantize,
    resolve_config,
)

W, H = 64, 36
ACES_VIEW = "ACES 2.0 - SDR 100 nits (Rec.709)"
SRGB_DISPLAY = "sRGB - Display"
ONE_CODE = 1.0 / 255.0


def srgb_oetf(x: float) -> float:
    """sRGB (IEC 61966-2-1) encoding of linear ``x`` in [0, 1]."""
    return 12.92 * x if x <= 0.0031308 else 1.055 * x ** (1.0 / 2.4) - 0.055


@pytest.fixture(autouse=True)
def _no_ocio_env(monkeypatch):
    monkeypatch.delenv("OCIO", raising=False)


def ramp_image() -> np.ndarray:
    """(H, W, 4) scene-linear test image, exactly representable in half float.

    A log ramp 1e-4..1e4 with 0 and values past the view's range (2e4, 6e4), small
    negatives (out of gamut), per-channel phase shifts so hues vary, grey pixels, and an
    alpha ramp.
    """
    n = W * H
    ramp = np.concatenate([[0.0, 2e4, 6e4, -1e-3, -0.05], np.logspace(-4, 4, n - 5)]).astype(
        np.float32
    )
    rgb = np.stack([ramp, np.roll(ramp, n // 3), np.roll(ramp, 2 * n // 3)], axis=-1)
    rgb[::7] = ramp[::7, None]  # grey pixels
    alpha = np.linspace(0.0, 1.0, n, dtype=np.float32)[:, None]
    img = np.concatenate([rgb, alpha], axis=-1).reshape(H, W, 4)
    return img.astype(np.float16).astype(np.float32)


def upload(ctx, img: np.ndarray):
    h, w, _ = img.shape
    return ctx.texture((w, h), 4, img.astype(np.float16).tobytes(), dtype="f2")


# --- names and errors -------------------------------------------------------------------


def test_defaults_resolve_to_studio_config():
    p = ColorPipeline()
    assert p.config_source == "ocio://studio-config-latest"
    assert p.display == SRGB_DISPLAY
    assert p.view == ACES_VIEW
    # scene_linear is ACEScg in the studio config: the input must not be taken from it.
    assert p.config.getColorSpace("scene_linear").getName() == "ACEScg"
    assert p.input_space == "Linear Rec.709 (sRGB)"
    assert p.exposure == 0.0
    assert "Un-tone-mapped" in p.views()


def test_bad_display_lists_valid_names():
    with pytest.raises(ValueError, match="unknown OCIO display 'nope'") as err:
        ColorPipeline(display="nope")
    msg = str(err.value)
    assert "\n" not in msg and f"'{SRGB_DISPLAY}'" in msg and "valid:" in msg


def test_bad_view_lists_valid_names():
    with pytest.raises(ValueError, match="unknown OCIO view 'Filmic'") as err:
        ColorPipeline(view="Filmic")
    msg = str(err.value)
    assert "\n" not in msg and "'Un-tone-mapped'" in msg and f"'{ACES_VIEW}'" in msg


def test_bad_input_space_and_exposure():
    with pytest.raises(ValueError, match="unknown OCIO colour space 'rec9999'"):
        ColorPipeline(input_space="rec9999")
    with pytest.raises(ValueError, match="finite"):
        ColorPipeline(exposure=float("nan"))
    # An alias resolves to the canonical name.
    assert ColorPipeline(input_space="lin_srgb").input_space == "Linear Rec.709 (sRGB)"


def test_missing_and_broken_config_files(tmp_path: Path):
    missing = tmp_path / "missing.ocio"
    with pytest.raises(ValueError, match="not found") as err:
        ColorPipeline(config_path=missing)
    assert str(missing) in str(err.value)
    broken = tmp_path / "broken.ocio"
    broken.write_text("ocio_profile_version: 2\ncolorspaces: [this is not: valid\n")
    with pytest.raises(ValueError, match="cannot load OCIO config") as err:
        ColorPipeline(config_path=broken)
    assert "\n" not in str(err.value)


LUT_CONFIG = """ocio_profile_version: 2
search_path: "."
roles:
  default: {linear}
  scene_linear: {linear}
file_rules:
  - !<Rule> {{name: Default, colorspace: default}}
displays:
  Test:
    - !<View> {{name: tetra, colorspace: lut_tetra}}
    - !<View> {{name: trilinear, colorspace: lut_linear}}
active_displays: []
active_views: []
colorspaces:
  - !<ColorSpace>
    name: {linear}
    aliases: [{aliases}]
  - !<ColorSpace>
    name: lut_tetra
    from_scene_reference: !<GroupTransform>
      children:
        - !<RangeTransform> {{min_in_value: 0, max_in_value: 1, min_out_value: 0, max_out_value: 1}}
        - !<FileTransform> {{src: curve.spi1d, interpolation: linear}}
        - !<FileTransform> {{src: look.cube, interpolation: tetrahedral}}
  - !<ColorSpace>
    name: lut_linear
    from_scene_reference: !<GroupTransform>
      children:
        - !<RangeTransform> {{min_in_value: 0, max_in_value: 1, min_out_value: 0, max_out_value: 1}}
        - !<FileTransform> {{src: curve.spi1d, interpolation: linear}}
        - !<FileTransform> {{src: look.cube, interpolation: linear}}
"""


def write_lut_config(folder: Path, linear: str = "linear", aliases: str = "lin_rec709_srgb"):
    """A config whose views need a 3D LUT (9^3) and a 1D LUT (1024, a 2D texture)."""
    g = np.linspace(0.0, 1.0, 9)
    lines = ["LUT_3D_SIZE 9"]
    for b in g:  # .cube: red varies fastest
        for gg in g:
            for r in g:
                out = (0.9 * r**0.7 + 0.05 * gg, gg**1.3, 0.5 * b + 0.5 * r * b)
                lines.append(" ".join(f"{v:.6f}" for v in out))
    (folder / "look.cube").write_text("\n".join(lines) + "\n")
    xs = np.linspace(0.0, 1.0, 1024)
    body = "\n".join(f" {x ** (1 / 2.2):.7f}" for x in xs)
    (folder / "curve.spi1d").write_text(
        f"Version 1\nFrom 0 1\nLength 1024\nComponents 1\n{{\n{body}\n}}\n"
    )
    path = folder / "config.ocio"
    path.write_text(LUT_CONFIG.format(linear=linear, aliases=aliases))
    return path


def test_ocio_env_and_linear_lookup(tmp_path: Path, monkeypatch):
    cfg = write_lut_config(tmp_path)
    monkeypatch.setenv("OCIO", str(cfg))
    p = ColorPipeline()
    assert p.config_source == str(cfg.resolve())
    assert (p.display, p.view, p.input_space) == ("Test", "tetra", "linear")
    # An explicit path wins over $OCIO.
    assert ColorPipeline(config_path="ocio://studio-config-latest").display == SRGB_DISPLAY


def test_no_linear_rec709_is_a_clear_error(tmp_path: Path):
    cfg = write_lut_config(tmp_path, linear="mystery_linear", aliases="something_else")
    config, _ = resolve_config(cfg)
    with pytest.raises(ValueError, match=r"no linear Rec\.709") as err:
        find_linear_rec709(config)
    assert "input_space" in str(err.value)
    with pytest.raises(ValueError, match=r"no linear Rec\.709"):
        ColorPipeline(config_path=cfg)
    assert ColorPipeline(config_path=cfg, input_space="mystery_linear").view == "tetra"


# --- CPU path ---------------------------------------------------------------------------


def test_untonemapped_is_srgb_oetf_and_exposure_doubles():
    p = ColorPipeline(view="Un-tone-mapped")
    grey = np.full((2, 3, 3), 0.18, np.float32)
    expected = srgb_oetf(0.18)
    assert abs(expected - 0.4614) < 1e-4
    np.testing.assert_allclose(p.apply_cpu(grey), expected, atol=ONE_CODE)
    assert np.all(p.to_uint8(grey) == round(expected * 255))

    p.exposure = 1.0
    once = p.apply_cpu(grey)
    p.exposure = 0.0
    fed = p.apply_cpu(np.full_like(grey, 0.36))
    np.testing.assert_allclose(once, fed, atol=1e-6)
    np.testing.assert_allclose(once, srgb_oetf(0.36), atol=ONE_CODE)


def test_cpu_output_range_alpha_and_shapes():
    p = ColorPipeline()
    img = ramp_image()
    img[0, 0, :3] = np.nan
    img[0, 1, :3] = np.inf
    out = p.apply_cpu(img)
    assert out.shape == img.shape and out.dtype == np.float32
    assert np.all(np.isfinite(out)) and out.min() >= 0.0 and out.max() <= 1.0
    np.testing.assert_array_equal(out[..., 3], np.clip(img[..., 3], 0, 1))
    assert np.all(out[0, 0, :3] == 0.0)  # NaN -> 0
    half_max = p.apply_cpu(np.full((1, 1, 3), 65504.0, np.float32))
    np.testing.assert_array_equal(out[0, 1, :3], half_max[0, 0])  # inf -> 65504
    # Monotone tone curve on the grey pixels.
    grey = p.apply_cpu(np.linspace(0, 100, 50, dtype=np.float32)[:, None].repeat(3, 1))
    assert np.all(np.diff(grey[:, 0]) >= 0)
    assert p.to_uint16(img).dtype == np.uint16
    with pytest.raises(ValueError, match=r"\(\.\.\., 3\)"):
        p.apply_cpu(np.zeros((4, 4, 2), np.float32))
    assert quantize(np.array([0.0, 0.5, 1.0, 2.0]), 8).tolist() == [0, 128, 255, 255]


def test_pipelines_sharing_a_processor_keep_their_own_exposure():
    # OCIO caches the processor (and its exposure property) per config: a second pipeline
    # with other exposure must not change the first one's result.
    a, b = ColorPipeline(exposure=0.0), ColorPipeline(exposure=3.0)
    assert a.cache_key == b.cache_key
    x = np.full((1, 1, 3), 0.18, np.float32)
    ref = a.apply_cpu(x)
    b.apply_cpu(x)
    np.testing.assert_array_equal(a.apply_cpu(x), ref)


# --- GPU path ---------------------------------------------------------------------------


@pytest.mark.gl
@pytest.mark.parametrize("view", [ACES_VIEW, "Un-tone-mapped"])
def test_gpu_matches_cpu(gl_ctx, view):
    img = ramp_image()
    src = upload(gl_ctx, img)
    pipeline = ColorPipeline(view=view)
    t0 = time.perf_counter()
    cc = ColorCorrectionPass(gl_ctx, pipeline)
    worst = 0.0
    for exposure in (0.0, 2.0):
        pipeline.exposure = exposure
        gpu8 = cc.run_to_array(src, "f1")
        cpu8 = pipeline.to_uint8(img)
        diff8 = np.abs(gpu8.astype(int) - cpu8.astype(int))
        assert diff8.max() <= 1, f"{view} @ {exposure:+} EV: {diff8.max()} codes"
        gpuf = cc.run_to_array(src, "f4")
        cpuf = pipeline.apply_cpu(img)
        worst = max(worst, float(np.abs(gpuf - cpuf).max()))
        assert np.abs(gpuf - cpuf).max() < 1e-3
        # Alpha passes through exactly (rgba8 rounding only).
        np.testing.assert_array_equal(gpu8[..., 3], np.rint(img[..., 3] * 255))
    elapsed = time.perf_counter() - t0
    print(f"{view}: GPU vs CPU max |diff| {worst:.2e} (float), compile+4 runs {elapsed:.3f}s")
    # The exposure must actually change the picture.
    pipeline.exposure = 0.0
    dark = cc.run_to_array(src)
    pipeline.exposure = 2.0
    assert cc.run_to_array(src)[..., :3].astype(int).sum() > dark[..., :3].astype(int).sum()
    src.release()


@pytest.mark.gl
def test_gpu_untonemapped_grey_and_exposure(gl_ctx):
    pipeline = ColorPipeline(view="Un-tone-mapped")
    cc = ColorCorrectionPass(gl_ctx, pipeline)
    grey = np.full((4, 8, 4), 0.18, np.float32)
    grey[..., 3] = 1.0
    src = upload(gl_ctx, grey)
    out = cc.run_to_array(src, "f4")
    np.testing.assert_allclose(out[..., :3], srgb_oetf(0.18), atol=ONE_CODE)
    pipeline.exposure = 1.0
    once = cc.run_to_array(src, "f4")
    pipeline.exposure = 0.0
    src36 = upload(gl_ctx, np.where(grey == 0.18, np.float32(0.36), grey))
    np.testing.assert_allclose(once, cc.run_to_array(src36, "f4"), atol=1e-5)
    src.release()
    src36.release()


@pytest.mark.gl
def test_program_compiled_once_per_view(gl_ctx):
    a = ColorCorrectionPass(gl_ctx, ColorPipeline(exposure=0.0))
    b = ColorCorrectionPass(gl_ctx, ColorPipeline(exposure=1.5))
    c = ColorCorrectionPass(gl_ctx, ColorPipeline(view="Un-tone-mapped"))
    assert a.program is b.program  # exposure is a uniform, not a new program
    assert a.program is not c.program
    assert "ocio_exposure_contrast_exposureVal" in a.fragment_source
    assert a.fragment_source.startswith("#version 430")


@pytest.mark.gl
def test_gpu_non_finite_and_targets(gl_ctx):
    pipeline = ColorPipeline()
    cc = ColorCorrectionPass(gl_ctx, pipeline)
    img = ramp_image()[:8, :8].copy()
    img[0, 0, :3] = np.nan
    img[0, 1, :3] = np.inf
    img[0, 2, :3] = -np.inf
    src = gl_ctx.texture((8, 8), 4, img.tobytes(), dtype="f4")  # rgba32f source
    gpu = cc.run_to_array(src, "f4")
    assert np.all(np.isfinite(gpu))
    np.testing.assert_allclose(gpu, pipeline.apply_cpu(img), atol=1e-4)
    src.release()


@pytest.mark.gl
def test_gpu_targets_and_resampling(gl_ctx):
    # Un-tone-mapped keeps the llvmpipe shader variants (per target format/sampler) cheap.
    pipeline = ColorPipeline(view="Un-tone-mapped")
    cc = ColorCorrectionPass(gl_ctx, pipeline)
    img = ramp_image()[:8, :8].copy()
    src = gl_ctx.texture((8, 8), 4, img.tobytes(), dtype="f4")
    gpu = cc.run_to_array(src, "f4")
    # A caller-owned framebuffer with a 16-bit float target (for 16-bit PNG / TIFF).
    dst = gl_ctx.texture((8, 8), 4, dtype="f2")
    fbo = gl_ctx.framebuffer(color_attachments=[dst])
    cc.run(src, fbo)
    half = np.frombuffer(dst.read(), np.float16).reshape(8, 8, 4).astype(np.float32)
    np.testing.assert_allclose(half, gpu, atol=1e-3)
    # A smaller target resamples (bilinear); a flat image stays flat.
    flat = np.full((8, 8, 4), 0.5, np.float32)
    src_flat = gl_ctx.texture((8, 8), 4, flat.tobytes(), dtype="f4")
    small = gl_ctx.texture((4, 4), 4, dtype="f4")
    cc.run(src_flat, small)
    got = np.frombuffer(small.read(), np.float32).reshape(4, 4, 4)
    np.testing.assert_allclose(got, pipeline.apply_cpu(flat)[:4, :4], atol=1e-5)
    assert gl_ctx.error == "GL_NO_ERROR"
    for obj in (fbo, dst, src, src_flat, small):
        obj.release()
    cc.release()


@pytest.mark.gl
@pytest.mark.parametrize("view", ["tetra", "trilinear"])
def test_gpu_matches_cpu_with_3d_and_1d_luts(gl_ctx, tmp_path: Path, view):
    pipeline = ColorPipeline(config_path=write_lut_config(tmp_path), view=view)
    cc = ColorCorrectionPass(gl_ctx, pipeline)
    kinds = sorted(type(t).__name__ for t in cc.lut_textures)
    assert kinds == ["Texture", "Texture3D"]  # the 1D LUT comes as a 2D texture
    rng = np.random.default_rng(7)
    img = rng.uniform(-0.1, 1.2, (H, W, 4)).astype(np.float32)
    src = gl_ctx.texture((W, H), 4, img.tobytes(), dtype="f4")
    np.testing.assert_allclose(cc.run_to_array(src, "f4"), pipeline.apply_cpu(img), atol=1e-4)
    diff = cc.run_to_array(src).astype(int) - pipeline.to_uint8(img).astype(int)
    assert np.abs(diff).max() <= 1
    src.release()
