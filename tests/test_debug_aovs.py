"""Debug AOVs (bigtile, smalltile, shadowterms, lightcount) on real GL: sizes,
finiteness, light counts against a numpy brute force, CPU reconstructions of
the STB views, and refusal of the STB views for other methods."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from stagegen import BOX_USDA, USDA_HEADER, camera_usda, ground_usda, usda_stage

from stb_hydra.io.debug_views import (
    LEGEND_ROWS,
    hash_colors,
    lightcount_heatmap,
    write_debug_aov,
    write_lightcount_legend,
)
from stb_hydra.io.images import read_image
from stb_hydra.renderer.engine import Engine
from stb_hydra.renderer.frame import RenderSettings
from stb_hydra.renderer.lighting.stb import REUSE_DEBUG_AOVS, SLOT_BLOCKS, decode_samples
from stb_hydra.renderer.records import InViewLights
from stb_hydra.renderer.tasks.aov_output import DEBUG_AOVS, STB_DEBUG_AOVS, check_debug_aovs

#: The views of the talk's STB pipeline, ``-o reuse=off`` (the reuse views, STB's default:
#: tests/test_reuse_debug_views.py).
PLAIN_VIEWS = tuple(a for a in DEBUG_AOVS if a not in REUSE_DEBUG_AOVS)
PLAIN_STB_VIEWS = tuple(a for a in STB_DEBUG_AOVS if a not in REUSE_DEBUG_AOVS)

pytestmark = pytest.mark.gl

W, H = 160, 96


def scene_text(n: int = 14, seed: int = 3) -> str:
    """Ground + box, ``n`` sphere lights with authored ranges 1.5-5 m (so counts vary
    over the image), camera looking down at 45 degrees."""
    rng = np.random.default_rng(seed)
    s = [USDA_HEADER + camera_usda((0, 7, 7), -45) + ground_usda(20) + BOX_USDA]
    for i in range(n):
        p = rng.uniform([-6, 0.4, -6], [6, 2.5, 4])
        s.append(
            f'def SphereLight "L{i}"\n{{\n'
            f"    float inputs:intensity = {rng.uniform(3000, 20000):.1f}\n"
            f"    float inputs:radius = 0.05\n"
            f"    float stb:range = {rng.uniform(1.5, 5.0):.3f}\n"
            f"    double3 xformOp:translate = ({p[0]:.3f}, {p[1]:.3f}, {p[2]:.3f})\n"
            '    uniform token[] xformOpOrder = ["xformOp:translate"]\n}\n'
        )
    return "".join(s)


@pytest.fixture(scope="module")
def stage():
    return usda_stage(scene_text())


def render(stage, lighting: str, aovs, **opts):
    """(engine results, frame, engine) of one final frame; the caller releases. STB: the
    talk's pipeline (``reuse=False``) unless ``opts`` says otherwise."""
    if lighting == "stb":
        opts = {"reuse": False, **opts}
    eng = Engine(stage, RenderSettings(width=W, height=H, lighting=lighting, method_options=opts))
    eng.request_aovs(set(aovs))
    frame = eng.render_frame()
    return eng.aovs, frame, eng


@pytest.fixture(scope="module")
def stb_run(gl_ctx, stage):
    eng = None
    try:
        res, frame, eng = render(stage, "stb", [*PLAIN_VIEWS, "depth"])
        tex = {k: _read_raw(frame, k) for k in ("stb_bigtile", "stb_smalltile", "stb_terms")}
        yield res, frame, eng, tex
    finally:
        if eng is not None:
            eng.release()


def _read_raw(frame, name: str) -> np.ndarray:
    """An STB buffer as stored (GL rows bottom-up)."""
    t = frame.buffers.textures[name]
    w, h = t.size
    dt = np.uint8 if t.dtype == "f1" else np.uint32
    return np.frombuffer(t.read(), dtype=dt).reshape(h, w, t.components)


def world_positions(depth: np.ndarray, view) -> np.ndarray:
    """(h, w, 3) world positions of the pixel centres from the linear depth AOV
    (top row first), as ``world_pos_from_depth`` in ``shaders/common/frame.glsl``."""
    h, w = depth.shape
    gy = (h - 1 - np.arange(h))[:, None] + 0.5  # GL row of each AOV row
    gx = np.arange(w)[None, :] + 0.5
    ndc_x = gx / w * 2.0 - 1.0
    ndc_y = gy / h * 2.0 - 1.0
    tx, ty = view.tan_half
    ox, oy = view.offset
    vx = (ndc_x * tx + ox) * depth
    vy = (ndc_y * ty + oy) * depth
    vp = np.stack([vx, vy, -depth, np.ones_like(depth)], axis=-1)
    return (vp @ view.inv_view)[..., :3]


# --- sizes and values ----------------------------------------------------------------------


def test_every_debug_aov_has_the_image_size_and_is_finite(stb_run):
    res, _frame, _eng, _tex = stb_run
    for name in PLAIN_VIEWS:
        a = res[name]
        assert a.shape[:2] == (H, W), name
        assert np.all(np.isfinite(a)), name
        if name in STB_DEBUG_AOVS:
            assert a.shape == (H, W, 3)
            assert a.min() >= 0.0 and a.max() <= 1.0
            assert a.max() > 0.05, f"{name} is black"


def test_lightcount_matches_numpy_brute_force(stb_run):
    res, frame, eng, _tex = stb_run
    d = eng.delegate
    rows = frame.get(InViewLights).rows
    assert frame.light_count == len(rows) > 0
    pos = d.light_table.position[rows].astype(np.float64)
    rng = d.light_table.range[rows].astype(np.float64)
    depth = res["depth"].astype(np.float64)
    P = world_positions(depth, frame.view)
    d2 = ((P[:, :, None, :] - pos[None, None]) ** 2).sum(-1)
    expect = (d2 < rng**2).sum(-1)
    expect[depth <= 0] = 0
    got = res["lightcount"]
    assert np.all(got == np.rint(got))
    same = np.mean(got == expect)
    assert same > 0.995, f"only {same:.4f} of pixels agree"
    assert np.abs(got - expect).max() <= 1  # float rounding exactly at a range boundary
    assert len(np.unique(expect)) >= 3, "test scene too uniform to mean anything"


def test_bigtile_view_matches_the_reservoir_texture(stb_run):
    res, _frame, eng, tex = stb_run
    K = eng.method.o["K"]
    bw, bh = SLOT_BLOCKS[K]
    bt = eng.method.big_px  # the last frame's
    raw = tex["stb_bigtile"][..., 0]  # (rows, cols) GL bottom-up
    idx, wgt = decode_samples(raw)
    gy, gx = np.mgrid[0:H, 0:W]
    gy = H - 1 - gy  # AOV row -> GL row
    ty, tx = gy // bt, gx // bt
    cy = np.minimum((gy - ty * bt) // (bt // bh), bh - 1)
    cx = np.minimum((gx - tx * bt) // (bt // bw), bw - 1)
    li = idx[ty * bh + cy, tx * bw + cx]
    inner = ((gx - tx * bt) % (bt // bw) != 0) & ((gy - ty * bt) % (bt // bh) != 0)
    full = inner & (wgt[ty * bh + cy, tx * bw + cx] > 0)
    # hue of the light's hash colour (brightness scales it): compare chromaticity
    got = res["bigtile"][full]
    want = hash_colors(li[full])
    gn = got / np.maximum(got.sum(-1, keepdims=True), 1e-6)
    wn = want / want.sum(-1, keepdims=True)
    bright = got.sum(-1) > 0.3  # 8-bit quantisation dominates very dark cells
    assert bright.mean() > 0.5
    assert np.abs(gn - wn)[bright].max() < 0.03


def test_smalltile_colours_are_lights_of_the_small_tile_texture(stb_run):
    res, _frame, _eng, tex = stb_run
    idx, _w = decode_samples(tex["stb_smalltile"].reshape(-1))
    from stb_hydra import limits

    lights = np.unique(idx[idx != limits.EMPTY_LIGHT_INDEX])
    palette = np.vstack([hash_colors(lights), np.zeros((1, 3), np.float32)])
    px = res["smalltile"].reshape(-1, 3)
    dist = np.abs(px[:, None, :] - palette[None]).max(-1).min(-1)
    assert dist.max() < 1.5 / 255.0


def test_shadowterm_values_come_from_the_term_texture(stb_run):
    res, _frame, _eng, tex = stb_run
    st = res["shadowterms"]
    np.testing.assert_array_equal(st[..., 0], st[..., 1])
    terms = np.unique(tex["stb_terms"][..., 0])  # N = 1: sample 0 only
    codes = np.unique(np.rint(st[..., 0] * 255.0).astype(np.int64))
    assert set(codes) <= set(terms.tolist()) | {0}
    assert codes.max() > 0


@pytest.mark.parametrize(
    "opts",
    [{"N": 4}, {"shadow_res": "pixel"}, {"interleave": False, "small_tile": 8, "K": 64}],
    ids=["N4", "pixel-terms", "plain-tiles-K64"],
)
def test_views_for_other_stb_layouts(gl_ctx, stage, opts):
    eng = None
    try:
        res, _frame, eng = render(stage, "stb", PLAIN_STB_VIEWS, **opts)
        for name in PLAIN_STB_VIEWS:
            a = res[name]
            assert a.shape == (H, W, 3) and np.all(np.isfinite(a)), name
            assert a.max() > 0.05, f"{name} is black"
        if opts.get("N") == 4:  # the 2x2 mosaic shows different samples within quads
            q = res["smalltile"][: H // 2 * 2, : W // 2 * 2].reshape(H // 2, 2, W // 2, 2, 3)
            differs = np.abs(q[:, 0, :, 0] - q[:, 1, :, 1]).max(-1) > 0.01
            assert differs.mean() > 0.1
    finally:
        if eng is not None:
            eng.release()


@pytest.mark.parametrize("method", ["reference", "sun"])
def test_lightcount_works_for_other_methods(gl_ctx, stage, method):
    eng = None
    try:
        res, frame, eng = render(stage, method, ["lightcount"])
        lc = res["lightcount"]
        assert lc.shape == (H, W) and np.all(np.isfinite(lc))
        assert 0 < lc.max() <= frame.light_count
    finally:
        if eng is not None:
            eng.release()


# --- refusal ------------------------------------------------------------------------------


@pytest.mark.parametrize("aov", STB_DEBUG_AOVS)
def test_stb_views_refused_for_other_methods(gl_ctx, stage, aov):
    with pytest.raises(ValueError, match="need --lighting stb"):
        check_debug_aovs([aov], "reference")
    eng = Engine(stage, RenderSettings(width=W, height=H, lighting="sun"))
    try:
        with pytest.raises(ValueError, match="need --lighting stb"):
            eng.request_aovs({aov})
    finally:
        eng.release()
    check_debug_aovs([aov, "lightcount"], "stb")  # fine


def test_cli_refuses_stb_views_with_one_line(tmp_path, stage):
    scene = tmp_path / "s.usda"
    scene.write_text(scene_text(4))
    out = tmp_path / "img.png"
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "stb_hydra.apps.cli",
            "render",
            str(scene),
            str(out),
            "--width",
            "64",
            "--lighting",
            "reference",
            "--aov",
            "bigtile,lightcount",
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert r.returncode == 2
    assert r.stderr.strip().count("\n") == 0
    assert "bigtile need --lighting stb" in r.stderr
    assert not out.exists()


def test_talk_views_under_the_reuse_name_the_option():
    """STB's default (the reuse) draws neither small tiles nor terms: asking for their
    views says which option does, in one line."""
    from stb_hydra.renderer.lighting.stb import StbLighting

    with pytest.raises(ValueError, match="shadowterms need -o reuse=off"):
        check_debug_aovs(["shadowterms"], "stb", StbLighting(None))
    with pytest.raises(ValueError, match="smalltile need -o reuse=off or -o reuse_candidates=0"):
        check_debug_aovs(["smalltile"], "stb", StbLighting(None))
    check_debug_aovs(["smalltile"], "stb", StbLighting(None, reuse_candidates=0))


def test_cli_writes_debug_aovs_beside_the_image(tmp_path):
    scene = tmp_path / "s.usda"
    scene.write_text(scene_text(6))
    out = tmp_path / "img.exr"
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "stb_hydra.apps.cli",
            "render",
            str(scene),
            str(out),
            "--width",
            "96",
            "--height",
            "54",
            "--lighting",
            "stb",
            "-o",
            "reuse=off",
            "--aov",
            ",".join(PLAIN_VIEWS),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert r.returncode == 0, r.stderr
    for name in PLAIN_VIEWS:
        png, meta = read_image(tmp_path / f"img.{name}.png")
        # the view, then its colour scale (io.debug_views.legend_strip)
        assert png.shape[:2] == (54 + LEGEND_ROWS, 96), name
        assert meta["stb:aov"] == name and meta["stb:legendRows"] == LEGEND_ROWS
    counts, _ = read_image(tmp_path / "img.lightcount.exr")
    assert counts.shape == (54, 96, 1) and counts.max() >= 1


# --- colouring helpers (no GL) ---------------------------------------------------------------


def test_heatmap_and_legend(tmp_path):
    hm = lightcount_heatmap(np.array([[0.0, 1.0, 16.0, 256.0, 5000.0]]))
    assert hm.shape == (1, 5, 3)
    assert np.all(hm[0, 0] == 0) and np.all(hm[0, 1:].max(-1) > 0)
    np.testing.assert_array_equal(hm[0, 3], hm[0, 4])  # saturates
    assert not np.allclose(hm[0, 1], hm[0, 2])
    p = write_lightcount_legend(tmp_path / "legend.png")
    assert p.stat().st_size > 1000
    paths = write_debug_aov(tmp_path / "x.png", "lightcount", np.full((4, 6), 3.0, np.float32))
    assert [q.name for q in paths] == ["x.lightcount.png", "x.lightcount.exr"]


def test_hash_colors_distinct_and_bounded():
    c = hash_colors(np.arange(1000))
    assert c.shape == (1000, 3) and c.min() >= 0 and c.max() <= 1
    assert len({tuple(np.round(x, 3)) for x in c}) > 900
