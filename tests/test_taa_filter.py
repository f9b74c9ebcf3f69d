"""The taa spatial filter (``RenderSettings.taa_filter``, ``shaders/taa_filter.frag``)
against an independent numpy a-trous of the same textures, and its invariants."""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Usd

from stb_hydra.renderer.engine import Engine
from stb_hydra.renderer.frame import RenderSettings
from stb_hydra.renderer.tasks.temporal import ALBEDO
from stb_hydra.scenegen.orbit import orbit_camera

pytestmark = pytest.mark.usefixtures("gl_ctx")

LUM = np.array([0.2126, 0.7152, 0.0722])
B3 = np.array([1, 4, 6, 4, 1]) / 16.0


def _read(tex, dtype="f4") -> np.ndarray:
    w, h = tex.size
    return np.frombuffer(tex.read(), dtype=dtype).reshape(h, w, tex.components).astype(np.float64)


def _oct_decode(e: np.ndarray) -> np.ndarray:
    n = np.dstack([e[..., 0], e[..., 1], 1.0 - np.abs(e[..., 0]) - np.abs(e[..., 1])])
    t = np.clip(-n[..., 2], 0.0, 1.0)
    n[..., 0] += np.where(n[..., 0] >= 0, -t, t)
    n[..., 1] += np.where(n[..., 1] >= 0, -t, t)
    return n / np.linalg.norm(n, axis=-1, keepdims=True)


def _at(a: np.ndarray, dy: int, dx: int) -> np.ndarray:
    """a[y + dy, x + dx], clamped at the border."""
    h, w = a.shape[:2]
    return a[np.clip(np.arange(h) + dy, 0, h - 1)][:, np.clip(np.arange(w) + dx, 0, w - 1)]


def _atrous(hist, geo, alb, emis, levels: int, sigma_l: float) -> np.ndarray:
    """The filter as the SVGF paper writes it (whole-image numpy, GL row order)."""
    light = hist[..., :3]
    ed = np.minimum(emis / alb, light)
    z, nrm = geo[..., 0], _oct_decode(geo[..., 1:3].copy())
    var = np.maximum(geo[..., 3] - (light @ LUM) ** 2, 0.0)
    var = sum(_g3(dy, dx) * _at(var, dy, dx) for dy in (-1, 0, 1) for dx in (-1, 0, 1))
    gx = np.minimum(abs(z - _at(z, 0, 1)), abs(z - _at(z, 0, -1)))
    gy = np.minimum(abs(z - _at(z, 1, 0)), abs(z - _at(z, -1, 0)))
    c = light - ed
    for lev in range(levels):
        s = 1 << lev
        lp = c @ LUM
        acc, wsum, vacc = np.zeros_like(c), np.zeros_like(z), np.zeros_like(z)
        for j in range(-2, 3):
            for i in range(-2, 3):
                k = B3[i + 2] * B3[j + 2]
                cq, vq = _at(c, j * s, i * s), _at(var, j * s, i * s)
                if i or j:
                    zq, nq = _at(z, j * s, i * s), _at(nrm, j * s, i * s)
                    wz = np.exp(
                        -abs(z - zq) / (abs(i * s) * gx + abs(j * s) * gy + 1e-3 * z + 1e-6)
                    )
                    wn = np.maximum(np.sum(nrm * nq, -1), 0.0) ** 128
                    wl = np.exp(-abs(lp - cq @ LUM) / (sigma_l * np.sqrt(var + vq) + 1e-6))
                    w = np.where(zq > 0, k * wz * wn * wl, 0.0)
                else:
                    w = np.full_like(z, k)
                acc += w[..., None] * cq
                wsum += w
                vacc += w * w * vq
        sky = (z <= 0)[..., None]
        c = np.where(sky, c, acc / wsum[..., None])
        var = np.where(z <= 0, var, vacc / wsum**2)
    return np.maximum(c + ed, 0.0) * alb


def _g3(dy: int, dx: int) -> float:
    return (0.5 if dx == 0 else 0.25) * (0.5 if dy == 0 else 0.25)


@pytest.fixture(scope="module")
def orbit_frame(repo):
    """Textures and colour of frame 10 of a courtyard orbit, taa with a 2-level filter."""
    stage = Usd.Stage.Open(str(repo / "usd_scenes" / "default.usda"))
    stage.SetEditTarget(stage.GetSessionLayer())
    orbit_camera(stage, 10, 1.0)
    eng = Engine(stage, RenderSettings(width=96, height=54, temporal="taa", taa_filter=2))
    try:
        for i in range(10):
            eng.render(time=1 + i)
        tex = eng.buffers.textures
        hist_name, geo_name = eng.temporal.latest
        out = {
            "hist": _read(tex[hist_name]),
            "geo": _read(tex[geo_name]),
            "alb": _read(tex[ALBEDO])[..., :3],
            "emis": _read(tex["g_emission"], "f2")[..., :3],
            "color": np.flipud(np.array(eng.aovs["color"][..., :3], np.float64)),
        }
    finally:
        eng.release()
    return out


def test_filter_matches_numpy_atrous(orbit_frame):
    """The GPU pass equals an independent numpy a-trous of the same history (half-float
    output: 0.2 % relative), has no NaN/Inf, leaves the sky as it was and keeps the
    image mean within 1 % (symmetric luminance stop)."""
    from stb_hydra import limits

    f = orbit_frame
    want = _atrous(f["hist"], f["geo"], f["alb"], f["emis"], 2, limits.TAA_FILTER_SIGMA_L)
    got = f["color"]
    assert np.isfinite(got).all()
    rel = np.abs(got - want) / (np.abs(want) + 1e-2)
    assert np.percentile(rel, 99.9) < 2e-3, np.percentile(rel, 99.9)
    unfiltered = f["hist"][..., :3] * f["alb"]
    sky = f["geo"][..., 0] <= 0
    assert sky.any() and np.allclose(got[sky], unfiltered[sky], rtol=2e-3, atol=1e-4)
    assert abs(got.mean() / unfiltered.mean() - 1.0) < 0.01
    # and it did filter: the lit surfaces changed
    assert np.median(np.abs(got - unfiltered)[~sky] / (unfiltered[~sky] + 1e-2)) > 0.01


def test_filter_removes_noise_on_a_plane():
    """On a plane of constant depth and normal with a huge variance estimate (every
    weight but the kernel's ~1), one level removes white noise like the B3 kernel:
    variance x sum(k^2) = (35/128)^2 = 0.0748 -- the closed form, checked here on the
    numpy model the GPU pass is compared with above."""
    rng = np.random.default_rng(1)
    h, w = 64, 64
    light = 1.0 + 0.1 * rng.standard_normal((h, w, 1)).repeat(3, -1)
    hist = np.dstack([light, np.ones((h, w))])
    geo = np.zeros((h, w, 4))
    geo[..., 0] = 5.0
    geo[..., 3] = 1e6  # temporal spread >> the noise: the luminance stop is off
    out = _atrous(hist, geo, np.ones((h, w, 3)), np.zeros((h, w, 3)), 1, 4.0)
    inner = out[2:-2, 2:-2, 0]
    assert abs(inner.var() / 0.01 - (35 / 128) ** 2) < 0.012
    assert abs(inner.mean() - light[2:-2, 2:-2, 0].mean()) < 2e-3


def test_taa_filter_setting_is_checked():
    with pytest.raises(ValueError, match="taa_filter"):
        RenderSettings(taa_filter=9)


def test_render_cli_taa_filter(tmp_path, repo):
    """``stb render --taa-filter LEVELS`` renders a taa sequence through the filter; an
    out-of-range count is a one-line error (exit 2), not a traceback."""
    import json
    import subprocess
    import sys

    from stb_hydra.apps import cli

    scene = str(repo / "usd_scenes" / "default.usda")
    stats = tmp_path / "s.json"
    argv = ["render", scene, str(tmp_path / "f.####.exr"), "--frames", "1:2", "--width", "48"]
    argv += ["--lighting", "stb", "--temporal", "taa", "--stats", str(stats)]
    assert cli.main([*argv, "--taa-filter", "2"]) == 0
    assert json.loads(stats.read_text())["settings"]["taa_filter"] == 2
    bad = [sys.executable, "-m", "stb_hydra.apps.cli", *argv, "--taa-filter", "9"]
    r = subprocess.run(bad, capture_output=True, text=True, timeout=300)
    assert r.returncode == 2
    assert "taa_filter must be 0..5" in r.stderr and "Traceback" not in r.stderr


def test_render_cli_says_taa_filter_without_taa(tmp_path, repo, capsys):
    """``--taa-filter`` on a still camera (``--temporal auto`` resolves to accumulate)
    or with an explicit non-taa mode is one warning, not a silently ignored option;
    with a moving camera it applies and nothing is said."""
    from stb_hydra.apps import cli

    scene = str(repo / "usd_scenes" / "default.usda")
    argv = ["render", scene, str(tmp_path / "f.exr"), "--width", "32", "--taa-filter", "2"]
    assert cli.main([*argv, "--lighting", "sun"]) == 0
    err = capsys.readouterr()
    text = err.out + err.err
    assert "--taa-filter 2" in text and "does not move" in text and "not applied" in text
    assert cli.main([*argv, "--lighting", "sun", "--temporal", "off"]) == 0
    err = capsys.readouterr()
    assert "--temporal is off" in err.out + err.err
    assert cli.main([*argv, "--lighting", "sun", "--temporal", "taa"]) == 0
    err = capsys.readouterr()
    assert "--taa-filter" not in err.out + err.err
