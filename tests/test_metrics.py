"""Metrics on constructed cases: identical images -> 0, a known offset -> its
closed-form relMSE, known frame-to-frame changes -> their mean, windows -> means."""

from __future__ import annotations

import numpy as np
import pytest

from stb_hydra.metrics import (
    accumulated_windows,
    display_referred,
    dropped_summary,
    flip_hdr,
    flip_ldr,
    relmse,
    relmse_map,
    temporal_excess,
    temporal_instability,
)


def img(rng, h=36, w=48, scale=2.0):
    return (rng.random((h, w, 3)) * scale).astype(np.float32)


def test_identical_images_score_zero():
    rng = np.random.default_rng(0)
    a = img(rng)
    assert relmse(a, a) == 0.0
    d = display_referred(a)
    assert flip_ldr(d, d) == pytest.approx(0.0, abs=1e-7)
    assert flip_hdr(a, a) == pytest.approx(0.0, abs=1e-7)
    assert temporal_instability([a, a, a]) == 0.0
    assert temporal_excess([a, a], [a, a]) == 0.0


@pytest.mark.parametrize(("c", "d", "eps"), [(1.0, 0.1, 1e-2), (0.0, 0.5, 1e-2), (3.0, -0.2, 0.5)])
def test_constant_offset_has_closed_form_relmse(c, d, eps):
    ref = np.full((8, 10, 3), c, dtype=np.float32)
    test = ref + np.float32(d)
    expect = (np.float32(d) ** 2) / (c * c + eps)
    assert relmse(test, ref, eps) == pytest.approx(float(expect), rel=1e-5)
    assert np.allclose(relmse_map(test, ref, eps), expect, rtol=1e-5)


def test_relmse_mean_over_pixels_and_alpha_ignored():
    ref = np.zeros((2, 2, 4), np.float32)
    ref[..., :3] = [[[1, 1, 1], [2, 2, 2]], [[0, 0, 0], [4, 4, 4]]]
    test = ref.copy()
    test[0, 0, :3] += 1.0  # only one pixel off by 1, reference 1
    test[..., 3] = 7.0  # alpha differs: ignored
    eps = 1e-2
    assert relmse(test, ref, eps) == pytest.approx(1.0 / (1.0 + eps) / 4.0)
    with pytest.raises(ValueError):
        relmse(test[:1], ref)


def test_flip_grows_with_error():
    rng = np.random.default_rng(1)
    a = img(rng, scale=0.5)
    small = a * 1.02
    big = a * 1.5
    da = display_referred(a)
    assert 0 < flip_ldr(display_referred(small), da) < flip_ldr(display_referred(big), da)
    assert 0 < flip_hdr(small, a) < flip_hdr(big, a)


def test_display_referred_is_in_unit_range():
    grey = np.array([0.0, 0.18, 1e4], np.float32)[None, :, None] * np.ones(3, np.float32)
    d = display_referred(grey)
    assert d.shape == (1, 3, 3) and d.min() >= 0 and d.max() <= 1
    assert d[0, 0, 0] < d[0, 1, 0] < d[0, 2, 0]


def test_temporal_instability_of_a_known_flicker():
    base = np.full((4, 5, 3), 0.5)
    seq = [base, base + 0.2, base, base + 0.2]
    assert temporal_instability(seq) == pytest.approx(0.2)
    steady = [base] * 4
    assert temporal_excess(seq, steady) == pytest.approx(0.2)
    assert temporal_instability([base]) == 0.0


def test_accumulated_windows_are_sliding_means():
    f = np.arange(6, dtype=np.float64)[:, None, None, None] * np.ones((6, 2, 2, 3))
    w = accumulated_windows(f, 3)
    assert w.shape == (4, 2, 2, 3)
    assert np.allclose(w[:, 0, 0, 0], [1, 2, 3, 4])
    assert np.allclose(accumulated_windows(f, 1), f)
    # a window of the accumulation of frames with mean m has mean m
    assert temporal_instability(w) == pytest.approx(1.0)
    with pytest.raises(ValueError):
        accumulated_windows(f, 7)


def test_dropped_summary():
    s = dropped_summary([{"dropped_lights": 3}, {"dropped_lights": 5}, {}])
    assert s == {"dropped_median": 3.0, "dropped_max": 5.0}
    assert dropped_summary([]) == {"dropped_median": 0.0, "dropped_max": 0.0}


# -- what a person sees: structured noise, HDR-FLIP at mid grey ------------------------------


def test_white_noise_scores_one_by_the_closed_form():
    from stb_hydra.metrics import spectral_structure

    rng = np.random.default_rng(1)
    s = [spectral_structure(rng.normal(size=(180, 320))) for _ in range(8)]
    # |FFT|^2 of white noise is exponential: the top q holds q (1 - ln q) of the mass.
    assert 0.9 <= float(np.mean(s)) <= 1.1, s


def test_checkerboard_and_quad_noise_are_structured():
    from stb_hydra.metrics import spectral_structure

    rng = np.random.default_rng(2)
    y, x = np.mgrid[:180, :320]
    cb = ((x + y) % 2) * 2.0 - 1.0
    assert spectral_structure(cb) > 25.0  # one frequency bin holds all the energy
    assert spectral_structure(cb + rng.normal(size=cb.shape)) > 8.0
    quad = np.repeat(np.repeat(rng.normal(size=(90, 160)), 2, 0), 2, 1)
    assert 1.9 <= spectral_structure(quad) <= 2.8
    # low frequencies (< 1/16 cycle/px) do not count: smooth blotches are not "structure"
    wave = np.sin(2 * np.pi * x / 64.0) + 0.05 * rng.normal(size=(180, 320))
    assert spectral_structure(wave) < 1.5


def test_structured_noise_is_relative_and_scale_free():
    from stb_hydra.metrics import relative_error, structured_noise

    rng = np.random.default_rng(3)
    ref = np.broadcast_to(rng.uniform(0.5, 2.0, (90, 160, 1)), (90, 160, 3)).copy()
    test = ref * (1.0 + 0.1 * rng.normal(size=(90, 160, 1)))
    e = relative_error(test, ref)
    lum = ref[..., 0]
    np.testing.assert_allclose(e, (test[..., 0] - lum) / (lum + 0.05 * np.median(lum)), rtol=1e-9)
    a = structured_noise(test, ref)
    assert a == pytest.approx(structured_noise(test * 1e-3, ref * 1e-3), rel=1e-9)
    assert 0.8 <= a <= 1.25  # multiplicative white noise


def test_flip_midgrey_is_exposure_invariant():
    from stb_hydra.metrics import flip_hdr_midgrey

    rng = np.random.default_rng(4)
    ref = rng.uniform(0.1, 1.0, (48, 64, 3))
    test = ref * (1.0 + 0.2 * rng.normal(size=ref.shape))
    f = flip_hdr_midgrey(test, ref)
    assert f > 0.01
    assert flip_hdr_midgrey(test * 1000.0, ref * 1000.0) == pytest.approx(f, rel=1e-4)
    assert flip_hdr_midgrey(ref, ref) == 0.0
