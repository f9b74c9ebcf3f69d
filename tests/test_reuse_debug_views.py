"""The reuse debug views (issue 31 item 6: ``reuse_m``, ``reuse_light``, ``reuse_reject``)
on real GL: each view's colours are what the reservoir textures hold (decoded here from
the raw render buffers, coloured by the numpy twins of the shaders' colour functions),
the rejection mask shows the disocclusion a sliding box causes, the views exist only
with the reuse (STB's default; not with ``-o reuse=off``), and the previewer offers and
drops them with the option."""

from __future__ import annotations

import numpy as np
import pytest
from stagegen import USDA_HEADER, camera_usda, ground_usda, usda_stage
from test_stb_reuse import SLIDER, depth, engine, reservoir_m

from stb_hydra import limits
from stb_hydra.io.debug_views import REUSE_REJECT_COLORS, hash_colors, reuse_m_colors
from stb_hydra.renderer.engine import Engine
from stb_hydra.renderer.frame import RenderSettings
from stb_hydra.renderer.lighting.stb import REUSE_DEBUG_AOVS

W, H = 128, 72
#: rgba8 quantisation of a colour written by a shader.
TOL = 1.5 / 255.0


def stored_reservoirs(eng: Engine) -> tuple[np.ndarray, np.ndarray]:
    """(light index, M) of the reservoirs the last frame stored, (h, w), top row first."""
    _cur, newest = eng.method.reuse.debug_inputs()  # type: ignore[attr-defined]
    tex = eng.buffers.textures[newest]
    raw = np.frombuffer(tex.read(), dtype=np.uint32).reshape(H, W, 4)[::-1]
    return raw[..., 0].astype(np.int64), raw[..., 2].copy().view(np.float32)


@pytest.fixture(scope="module")
def slider_stage():
    return usda_stage(USDA_HEADER + camera_usda((0, 8, 8), -45) + ground_usda(20) + SLIDER)


def _close(img: np.ndarray, rgb) -> np.ndarray:
    return np.all(np.abs(img - np.asarray(rgb, np.float32)) <= TOL, axis=-1)


def test_reject_view_shows_history_taken_rejected_and_none(gl_ctx, slider_stage):
    """First frame: every surface pixel blue (no history), background black. After the
    box slides: red exactly where the temporal pass started from the pixel's own
    candidates (M = 1: the disoccluded ground), green where it took the history."""
    eng = engine(slider_stage, W, H)
    try:
        eng.request_aovs({"reuse_reject"})
        eng.render(time=1.0)
        first, d0 = eng.aovs["reuse_reject"], depth(eng)
        for _ in range(5):
            eng.render(time=1.0)
        d1 = depth(eng)
        eng.render(time=2.0)
        after, d2, m = eng.aovs["reuse_reject"], depth(eng), reservoir_m(eng)
    finally:
        eng.release()
    assert _close(first[d0 > 0], REUSE_REJECT_COLORS["none"]).all()
    assert _close(first[d0 <= 0], (0, 0, 0)).all()
    surf = d2 > 0
    red = _close(after, REUSE_REJECT_COLORS["rejected"])
    green = _close(after, REUSE_REJECT_COLORS["taken"])
    assert np.array_equal(red, surf & (m == 1.0))
    assert np.array_equal(green, surf & (m > 1.0))
    disoccluded = surf & (d1 > 0) & (d2 > 1.2 * d1)
    assert disoccluded.sum() > 100 and red[disoccluded].all()
    assert green.sum() > 5 * red.sum()  # most of a still view keeps its history


def test_light_and_m_views_colour_the_stored_reservoirs(gl_ctx, slider_stage):
    """``reuse_light``: the hash colour of each pixel's stored light (black: empty);
    ``reuse_m``: its confidence M on the log2 heat ramp -- and M grows with the
    history (frame 1: the pixel's own and its neighbours' candidates; frame 6: more)."""
    eng = engine(slider_stage, W, H)
    try:
        eng.request_aovs({"reuse_light", "reuse_m"})
        eng.render(time=1.0)
        _, m_first = stored_reservoirs(eng)
        for _ in range(5):
            eng.render(time=1.0)
        y, m = stored_reservoirs(eng)
        light, mview = eng.aovs["reuse_light"], eng.aovs["reuse_m"]
    finally:
        eng.release()
    empty = y == limits.EMPTY_LIGHT_INDEX
    assert (~empty).sum() > 1000 and empty.sum() > 0  # the sky above the horizon
    want = np.where(empty[..., None], 0.0, hash_colors(np.where(empty, 0, y)))
    assert np.abs(light - want).max() <= TOL
    assert np.abs(mview - reuse_m_colors(m)).max() <= 2 * TOL  # log2 in fp32 on both sides
    surf = m > 0
    assert np.median(m[surf]) > 2.0 * np.median(m_first[surf])


def test_reuse_views_need_reuse_on(gl_ctx, slider_stage):
    """With ``-o reuse=off`` (the talk's pipeline) asking for a reuse view is a one-line
    error naming the option; switching reuse off on a live engine drops the view and
    keeps rendering."""
    settings = RenderSettings(width=32, height=18, lighting="stb", method_options={"reuse": False})
    eng = Engine(slider_stage, settings)
    try:
        assert not set(REUSE_DEBUG_AOVS) & set(eng.method.debug_aovs)
        with pytest.raises(ValueError, match="reuse_m need -o reuse=on"):
            eng.request_aovs({"reuse_m"})
        eng.set_lighting("stb")  # the default: the reuse
        eng.request_aovs({"reuse_m"})
        eng.render()
        assert eng.aovs["reuse_m"].shape == (18, 32, 3)
        eng.set_lighting("stb", reuse=False)
        eng.render()
        assert "reuse_m" not in eng.aovs and np.isfinite(eng.aovs["color"]).all()
    finally:
        eng.release()


def test_previewer_offers_reuse_views_with_the_option(gl_ctx, tmp_path):
    """The previewer's view list follows the live toggle: the reuse views appear with
    ``reuse=on``, render, and the view falls back to colour when reuse goes off."""
    from stb_hydra.preview.session import PreviewSession

    scene = tmp_path / "slider.usda"
    scene.write_text(USDA_HEADER + camera_usda((0, 8, 8), -45) + ground_usda(20) + SLIDER)
    settings = RenderSettings(width=48, height=27, lighting="stb", method_options={"reuse": False})
    s = PreviewSession(scene, settings, ctx=gl_ctx)
    try:
        assert s.error is None, s.error
        assert "reuse_m" not in s.views()
        assert s.set_options(reuse=True)
        assert set(REUSE_DEBUG_AOVS) <= set(s.views())
        assert s.set_view("reuse_reject")
        for _ in range(3):
            s.step()
        img = s.view_image()
        assert img is not None and img.shape == (27, 48, 3) and img.max() > 0
        assert s.set_options(reuse=False)
        assert s.view == "color" and "reuse_m" not in s.views()
        s.step()
        assert s.message is None, s.message
    finally:
        s.release()


def test_cli_refuses_reuse_views_without_reuse_in_one_line(tmp_path):
    """``stb render --aov reuse_m -o reuse=off``: exit 2 and one line naming
    the option, no traceback (the check needs the method's options, so it is the
    engine's; the CLI turns it into its error)."""
    from stb_hydra.apps.cli import main
    from stb_hydra.apps.common import EXIT_ERROR

    scene = tmp_path / "s.usda"
    scene.write_text(USDA_HEADER + camera_usda((0, 8, 8), -45) + ground_usda(20) + SLIDER)
    err = tmp_path / "err.txt"
    import contextlib

    with open(err, "w") as f, contextlib.redirect_stderr(f):
        code = main(
            [
                "render",
                str(scene),
                str(tmp_path / "o.png"),
                "--width",
                "32",
                "--height",
                "18",
                "--lighting",
                "stb",
                "-o",
                "reuse=off",
                "--aov",
                "reuse_m",
                "--quiet",
            ]
        )
    lines = err.read_text().strip().splitlines()
    assert code == EXIT_ERROR and len(lines) == 1, lines
    assert "reuse_m need -o reuse=on" in lines[0] and not (tmp_path / "o.png").exists()


@pytest.mark.parametrize(
    "opts",
    [
        # nothing reused (k = 0, no history): the fused single pass
        {"reuse_candidates": 32, "reuse_k": 0, "big_tile": 32, "reuse_temporal": "off"},
        {"reuse_candidates": 32, "reuse_res": "quad", "big_tile": 32},  # quad reservoirs
    ],
)
def test_views_with_per_pixel_candidates(gl_ctx, slider_stage, opts):
    """The reuse's other layouts (issue 31's per-pixel big-tile candidates: no small-tile
    or term pass; quad-resolution reservoirs) draw the reuse views and the big-tile view,
    and no longer offer the views of passes that do not run."""
    eng = engine(slider_stage, 64, 36, **opts)
    try:
        views = set(eng.method.debug_aovs)
        assert "shadowterms" not in views and "smalltile" not in views
        eng.request_aovs({"bigtile", *REUSE_DEBUG_AOVS})
        for _ in range(3):
            eng.render(time=1.0)
        for name in ("bigtile", *REUSE_DEBUG_AOVS):
            a = eng.aovs[name]
            assert a.shape == (36, 64, 3) and np.isfinite(a).all() and a.max() > 0.05, name
        reject = eng.aovs["reuse_reject"]
        fused = opts.get("reuse_temporal") == "off"  # no temporal pass at all
        want = REUSE_REJECT_COLORS["none" if fused else "taken"]
        assert _close(reject, want).mean() > 0.9
    finally:
        eng.release()
