"""Image files through real OpenImageIO: round trips, metadata, atomic writes, paths."""

from __future__ import annotations

import json
import os
import shutil
import stat
from pathlib import Path

import numpy as np
import OpenImageIO as oiio
import pytest

from stb_hydra.color.ocio import ColorPipeline
from stb_hydra.io import images
from stb_hydra.io.images import (
    ImageReadError,
    ImageWriteError,
    aov_path,
    check_output_path,
    frame_path,
    has_frame_placeholder,
    read_image,
    write_aov,
    write_image,
)

W, H = 64, 36


@pytest.fixture(autouse=True)
def _no_ocio_env(monkeypatch):
    monkeypatch.delenv("OCIO", raising=False)


@pytest.fixture(scope="module")
def pipeline() -> ColorPipeline:
    return ColorPipeline()


def half_exact_rgba(seed: int = 0) -> np.ndarray:
    """(H, W, 4) float32 values that are exact in half float, incl. 0, negatives, big."""
    rng = np.random.default_rng(seed)
    x = (rng.standard_normal((H, W, 4)) * 10.0 ** rng.integers(-4, 4, (H, W, 4))).astype(np.float16)
    x[0, 0] = [0.0, 65504.0, -2.0, 1.0]
    x[0, 1] = [6.1e-5, 0.18, 1e4, 0.5]
    return x.astype(np.float32)


def listing(folder: Path) -> list[str]:
    return sorted(os.listdir(folder))


# --- EXR -------------------------------------------------------------------------------


def test_exr_half_roundtrip_exact_with_metadata(tmp_path: Path, pipeline):
    pixels = half_exact_rgba()
    meta = {
        "stb:camera": "/World/Cameras/main",
        "stb:frame": 12.5,
        "stb:spp": 16,
        "stb:settings": {"method": "stb", "tiles": [16, 64], "taa": True},
        "stb:flag": False,
        "stb:bigint": 2**40,
    }
    path = write_image(tmp_path / "img.exr", pixels, metadata=meta, color_pipeline=pipeline)
    assert path == tmp_path / "img.exr" and listing(tmp_path) == ["img.exr"]
    got, info = read_image(path)
    assert got.dtype == np.float32 and got.shape == (H, W, 4)
    np.testing.assert_array_equal(got, pixels)
    for key, value in meta.items():
        assert info[key] == value, key
    assert isinstance(info["stb:spp"], int) and isinstance(info["stb:flag"], bool)
    assert images.JSON_KEYS_ATTR not in info
    # OIIO canonicalises the name; it must still resolve to the pipeline's input space.
    assert pipeline.config.getColorSpace(info["oiio:ColorSpace"]).getName() == (
        pipeline.input_space
    )
    assert info["stb:ocio:view"] == pipeline.view

    spec = oiio.ImageInput.open(str(path)).spec()
    assert spec.format == oiio.TypeDesc("half")
    assert tuple(spec.channelnames) == ("R", "G", "B", "A")
    assert spec.getattribute("stb:frame") == 12.5  # a real float attribute, not a string
    native, _ = read_image(path, pixel_type="native")
    assert native.dtype == np.float16


def test_exr_rgb_default_colorspace_and_half_clamp(tmp_path: Path):
    pixels = np.full((H, W, 3), 0.25, np.float32)
    pixels[0, 0] = [1e6, -1e6, np.nan]
    got, info = read_image(write_image(tmp_path / "rgb.exr", pixels))
    assert got.shape == (H, W, 3)
    assert got[0, 0, 0] == 65504.0 and got[0, 0, 1] == -65504.0  # clamped, not inf
    assert np.isnan(got[0, 0, 2])
    assert np.all(got[1:] == 0.25)
    assert info["oiio:ColorSpace"] == "lin_rec709_scene"
    assert info["Software"].startswith("stb_hydra")


def test_exr_float_attribute_is_32_bit(tmp_path: Path):
    _, info = read_image(write_image(tmp_path / "f.exr", np.zeros((2, 2, 3)), metadata={"x": 0.1}))
    assert info["x"] == float(np.float32(0.1))


def test_aov_files(tmp_path: Path):
    depth = np.linspace(0.1, 1e30, H * W, dtype=np.float32).reshape(H, W)
    depth[0, 0] = np.inf
    path = write_aov(tmp_path / "img.png", "depth", depth, metadata={"stb:frame": 3})
    assert path == tmp_path / "img.depth.exr"
    got, info = read_image(path)
    assert got.shape == (H, W, 1)
    np.testing.assert_array_equal(got[..., 0], depth)  # 32-bit float, exact
    spec = oiio.ImageInput.open(str(path)).spec()
    assert tuple(spec.channelnames) == ("Z",) and spec.format == oiio.TypeDesc("float")
    assert info["stb:aov"] == "depth" and info["stb:frame"] == 3
    assert info["oiio:ColorSpace"] == "data"

    normal = np.zeros((H, W, 3), np.float32)
    normal[..., 2] = 1.0
    npath = write_aov(tmp_path / "img.png", "normal", normal)
    spec = oiio.ImageInput.open(str(npath)).spec()
    assert spec.format == oiio.TypeDesc("half") and spec.nchannels == 3
    albedo = write_aov(tmp_path / "img.png", "albedo", normal)
    assert read_image(albedo)[1]["oiio:ColorSpace"] == "lin_rec709_scene"
    with pytest.raises(ValueError, match="1 channel"):
        write_aov(tmp_path / "img.png", "depth", normal)
    assert listing(tmp_path) == ["img.albedo.exr", "img.depth.exr", "img.normal.exr"]


# --- display-referred formats ------------------------------------------------------------


def test_png8_roundtrip_exact_with_alpha_and_metadata(tmp_path: Path):
    rng = np.random.default_rng(1)
    codes = rng.integers(0, 256, (H, W, 4), dtype=np.uint8)
    codes[0, :4, 3] = [0, 1, 128, 255]  # premultiplication would destroy alpha-0 colour
    codes[0, 0, :3] = [200, 100, 50]
    meta = {"stb:camera": "/cam", "stb:frame": 7.25, "stb:n": 3, "stb:nested": {"a": [1, 2]}}
    path = write_image(tmp_path / "d.png", codes, display_referred=True, metadata=meta)
    got, info = read_image(path, pixel_type="native")
    assert got.dtype == np.uint8
    np.testing.assert_array_equal(got, codes)
    asfloat, _ = read_image(path)
    np.testing.assert_array_equal(np.rint(asfloat * 255).astype(np.uint8), codes)
    for key, value in meta.items():
        assert info[key] == value, key
    assert "ImageDescription" not in info  # our JSON carrier is unpacked
    assert info["oiio:UnassociatedAlpha"] == 1


def test_png_through_pipeline_equals_cpu_path(tmp_path: Path, pipeline):
    rng = np.random.default_rng(2)
    scene = rng.uniform(0.0, 20.0, (H, W, 4)).astype(np.float32)
    scene[..., 3] = rng.uniform(0.0, 1.0, (H, W))
    path = write_image(tmp_path / "s.png", scene, color_pipeline=pipeline)
    got, info = read_image(path, pixel_type="native")
    np.testing.assert_array_equal(got, pipeline.to_uint8(scene))
    assert info["stb:ocio:display"] == pipeline.display
    assert info["stb:ocio:view"] == pipeline.view
    assert info["oiio:ColorSpace"] == "srgb_rec709_scene"  # OIIO's name for sRGB - Display
    # Default pipeline (no $OCIO): identical result.
    got2, _ = read_image(write_image(tmp_path / "t.png", scene), pixel_type="native")
    np.testing.assert_array_equal(got2, got)


def test_16_bit_png_and_tiff_exact(tmp_path: Path, pipeline):
    rng = np.random.default_rng(3)
    codes = rng.integers(0, 65536, (H, W, 4), dtype=np.uint16)
    png = write_image(tmp_path / "a.png", codes, display_referred=True, bits=16)
    np.testing.assert_array_equal(read_image(png, pixel_type="native")[0], codes)
    tif = write_image(tmp_path / "a.tif", codes, display_referred=True, metadata={"k": 1.5})
    got, info = read_image(tif, pixel_type="native")
    assert got.dtype == np.uint16
    np.testing.assert_array_equal(got, codes)
    assert info["k"] == 1.5  # TIFF drops custom attributes; the JSON carrier keeps them
    scene = rng.uniform(0.0, 5.0, (H, W, 3)).astype(np.float32)
    tif2 = write_image(tmp_path / "b.tiff", scene, color_pipeline=pipeline)
    np.testing.assert_array_equal(
        read_image(tif2, pixel_type="native")[0], pipeline.to_uint16(scene)
    )


def test_display_referred_float_and_jpeg(tmp_path: Path, pipeline):
    disp = np.linspace(0.0, 1.0, H * W * 4, dtype=np.float32).reshape(H, W, 4)
    png = write_image(tmp_path / "f.png", disp, display_referred=True, color_pipeline=pipeline)
    got, info = read_image(png, pixel_type="native")
    np.testing.assert_array_equal(got, np.rint(disp * 255).astype(np.uint8))
    assert info["stb:ocio:view"] == pipeline.view  # pipeline named, not applied again
    jpg = write_image(tmp_path / "f.jpg", disp, display_referred=True, metadata={"a:b": "c:d"})
    got, info = read_image(jpg, pixel_type="native")
    assert got.shape == (H, W, 3)  # no alpha in JPEG
    assert np.abs(got.astype(int) - np.rint(disp[..., :3] * 255)).mean() < 3
    assert info["a:b"] == "c:d"
    assert not any(k.startswith("{") for k in info)  # no mangled JSON comment
    with pytest.raises(ValueError, match="16-bit"):
        write_image(tmp_path / "g.jpg", disp, display_referred=True, bits=16)
    with pytest.raises(ValueError, match="scene-linear"):
        write_image(tmp_path / "g.exr", disp, display_referred=True)


# --- atomic writes and errors --------------------------------------------------------------


def test_missing_directory(tmp_path: Path):
    target = tmp_path / "nope" / "img.exr"
    with pytest.raises(ImageWriteError, match="directory does not exist") as err:
        write_image(target, np.zeros((4, 4, 3)))
    assert str(target) in str(err.value) and "\n" not in str(err.value)
    assert listing(tmp_path) == []


def _write_as(uid: int | None, target: Path) -> str:
    """``write_image(target)`` in this process, or in a forked child that first drops
    to ``uid`` (root ignores directory permissions). Returns the error text ("" when
    the write succeeded)."""
    if uid is None:
        try:
            write_image(target, np.zeros((4, 4, 3)))
        except ImageWriteError as exc:
            return str(exc)
        return ""
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:  # child: no exec (the interpreter under /root is not readable by uid)
        code = 1
        try:
            os.close(r)
            os.setgid(uid)
            os.setuid(uid)
            os.write(w, _write_as(None, target).encode())
            code = 0
        finally:
            os._exit(code)
    os.close(w)
    with os.fdopen(r) as f:
        msg = f.read()
    _, status = os.waitpid(pid, 0)
    assert os.waitstatus_to_exitcode(status) == 0
    return msg


def test_read_only_directory():
    import tempfile

    base = Path(tempfile.mkdtemp(prefix="stb_ro_"))  # /tmp: traversable after chmod
    base.chmod(0o755)
    ro = base / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        uid = 65534 if os.geteuid() == 0 else None  # nobody: no CAP_DAC_OVERRIDE
        msg = _write_as(uid, ro / "img.png")
        assert "not writable" in msg and str(ro / "img.png") in msg, msg
        assert "\n" not in msg
        assert listing(ro) == []
    finally:
        ro.chmod(0o755)
        shutil.rmtree(base)


def test_unwritable_filesystem_even_for_root():
    # sysfs refuses new files for everyone: the error must come from the real write,
    # be clear, and leave nothing behind.
    sys_dir = Path("/sys")
    if not sys_dir.is_dir():
        pytest.skip("no /sys")
    before = set(os.listdir(sys_dir))
    with pytest.raises(ImageWriteError) as err:
        write_image(sys_dir / "stb_test.exr", np.zeros((4, 4, 3)))
    msg = str(err.value)
    assert "/sys/stb_test.exr" in msg and "\n" not in msg
    assert ("denied" in msg.lower()) or ("not writable" in msg)
    assert set(os.listdir(sys_dir)) == before


def test_check_output_path(tmp_path: Path):
    for bad in ("img.bmp", "img", "img.EXRX"):
        with pytest.raises(ImageWriteError, match="unsupported extension") as err:
            check_output_path(tmp_path / bad)
        assert ".exr" in str(err.value) and ".png" in str(err.value)
    check_output_path(tmp_path / "img.EXR")  # case-insensitive
    check_output_path(tmp_path / "img.####.png")  # a frame pattern is fine
    (tmp_path / "dir.png").mkdir()
    with pytest.raises(ImageWriteError, match="is a directory"):
        check_output_path(tmp_path / "dir.png")
    (tmp_path / "file").write_text("x")
    with pytest.raises(ImageWriteError, match="not a directory"):
        check_output_path(tmp_path / "file" / "img.png")
    with pytest.raises(ImageWriteError, match="unsupported extension"):
        write_image(tmp_path / "img.bmp", np.zeros((4, 4, 3)))


# Failure injection goes through OIIO's own API: ``ImageOutput.write_image`` is the one
# pixel write of ``write_image``; tests replace it and call the real one through this.
_REAL_WRITE_IMAGE = oiio.ImageOutput.write_image


def fail_midway(out: oiio.ImageOutput, pixels: np.ndarray) -> bool:
    """Write half the scanlines for real, then fail like a full disk would."""
    half = pixels.shape[0] // 2
    assert out.write_scanlines(0, half, 0, pixels[:half])
    raise RuntimeError("simulated: no space left on device")


@pytest.mark.parametrize("name", ["img.exr", "img.png", "img.tif"])
def test_failure_mid_write_leaves_nothing(tmp_path: Path, monkeypatch, name):
    monkeypatch.setattr(oiio.ImageOutput, "write_image", fail_midway)
    target = tmp_path / name
    with pytest.raises(ImageWriteError, match="simulated") as err:
        write_image(target, np.ones((H, W, 3), np.float32))
    assert str(target) in str(err.value)
    assert listing(tmp_path) == []


def test_failure_keeps_existing_target(tmp_path: Path, monkeypatch):
    target = tmp_path / "img.exr"
    write_image(target, np.full((4, 4, 3), 0.5, np.float32))
    original = target.read_bytes()
    monkeypatch.setattr(oiio.ImageOutput, "write_image", fail_midway)
    with pytest.raises(ImageWriteError):
        write_image(target, np.full((H, W, 3), 2.0, np.float32))
    assert target.read_bytes() == original and listing(tmp_path) == ["img.exr"]

    monkeypatch.setattr(oiio.ImageOutput, "write_image", lambda out, px: False)  # OIIO says no
    with pytest.raises(ImageWriteError, match="cannot write"):
        write_image(target, np.full((4, 4, 3), 2.0, np.float32))
    assert target.read_bytes() == original and listing(tmp_path) == ["img.exr"]

    monkeypatch.undo()

    def no_replace(src, dst):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(images.os, "replace", no_replace)
    with pytest.raises(ImageWriteError, match="No space left"):
        write_image(target, np.full((4, 4, 3), 2.0, np.float32))
    assert target.read_bytes() == original and listing(tmp_path) == ["img.exr"]


def test_interrupt_cleans_up_and_propagates(tmp_path: Path, monkeypatch):
    def interrupted(out, pixels):
        raise KeyboardInterrupt

    monkeypatch.setattr(oiio.ImageOutput, "write_image", interrupted)
    with pytest.raises(KeyboardInterrupt):
        write_image(tmp_path / "img.png", np.zeros((4, 4, 3), np.float32))
    assert listing(tmp_path) == []


def test_temp_file_is_a_hidden_sibling_with_the_real_extension(tmp_path: Path, monkeypatch):
    seen: list[str] = []

    def spy(out, pixels):
        seen.extend(listing(tmp_path))
        return _REAL_WRITE_IMAGE(out, pixels)

    monkeypatch.setattr(oiio.ImageOutput, "write_image", spy)
    write_image(tmp_path / "shot.exr", np.zeros((4, 4, 3), np.float32))
    assert len(seen) == 1 and seen[0].startswith(".shot.tmp-") and seen[0].endswith(".exr")
    assert listing(tmp_path) == ["shot.exr"]


def test_file_modes(tmp_path: Path):
    umask = os.umask(0o022)
    os.umask(umask)
    new = write_image(tmp_path / "new.png", np.zeros((4, 4, 3), np.uint8), display_referred=True)
    assert stat.S_IMODE(new.stat().st_mode) == 0o666 & ~umask  # not mkstemp's 0600
    new.chmod(0o640)
    write_image(new, np.ones((4, 4, 3), np.uint8), display_referred=True)
    assert stat.S_IMODE(new.stat().st_mode) == 0o640  # an overwritten file keeps its mode


def test_read_errors(tmp_path: Path):
    with pytest.raises(ImageReadError, match="no such file"):
        read_image(tmp_path / "missing.exr")
    junk = tmp_path / "junk.exr"
    junk.write_bytes(b"not an image")
    with pytest.raises(ImageReadError) as err:
        read_image(junk)
    assert str(junk) in str(err.value)


# --- paths -------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("pattern", "frame", "expected"),
    [
        ("out/img.####.exr", 1, "out/img.0001.exr"),
        ("out/img.####.exr", 12345, "out/img.12345.exr"),  # minimum width, not maximum
        ("out/img.####.exr", -3, "out/img.-003.exr"),  # sign takes a digit (usdrecord)
        ("out/img.####.exr", 7.0, "out/img.0007.exr"),
        ("out/img.####.exr", -0.0, "out/img.0000.exr"),
        ("img.#.png", 5, "img.5.png"),  # a single '#' is a valid placeholder
        ("img.#.png", 42, "img.42.png"),
        ("img.###.##.exr", 1.5, "img.001.50.exr"),  # width counts the dot
        ("img.###.##.exr", -2.25, "img.-02.25.exr"),
        ("img.#.#.exr", 3.5, "img.3.5.exr"),
        ("img_####_beauty.exr", 101, "img_0101_beauty.exr"),
    ],
)
def test_frame_path(pattern, frame, expected):
    assert frame_path(pattern, frame) == expected
    assert has_frame_placeholder(pattern)


def test_frame_path_errors_and_timecodes():
    from pxr import Usd

    assert frame_path("a.####.exr", Usd.TimeCode(24)) == "a.0024.exr"
    assert frame_path(Path("a.####.exr"), np.float32(3)) == "a.0003.exr"
    with pytest.raises(ValueError, match="no frame placeholders"):
        frame_path("a.exr", 1)
    with pytest.raises(ValueError, match="2 frame placeholders"):
        frame_path("a.##.b.##.exr", 1)
    with pytest.raises(ValueError, match="decimal place"):
        frame_path("a.####.exr", 1.5)  # would collide with frame 2
    with pytest.raises(ValueError, match="decimal place"):
        frame_path("a.###.#.exr", 1.25)
    with pytest.raises(ValueError, match="finite"):
        frame_path("a.####.exr", Usd.TimeCode.Default())  # NaN
    assert not has_frame_placeholder("a.exr") and not has_frame_placeholder("a.#.#.#.exr")


def test_aov_path():
    assert aov_path("out/img.exr", "depth") == Path("out/img.depth.exr")
    assert aov_path("out/img.png", "normal") == Path("out/img.normal.exr")
    assert aov_path("out/img.####.png", "albedo") == Path("out/img.####.albedo.exr")
    assert aov_path("out/img.png", "color") == Path("out/img.png")
    with pytest.raises(ValueError, match="AOV name"):
        aov_path("out/img.png", "../evil")


def test_metadata_json_values_readable_by_other_tools(tmp_path: Path):
    path = write_image(tmp_path / "m.exr", np.zeros((2, 2, 3)), metadata={"s": {"k": [1]}})
    spec = oiio.ImageInput.open(str(path)).spec()
    assert json.loads(spec.get_string_attribute("s")) == {"k": [1]}
