"""What a person sees of stochastic noise: structure in the error, and HDR-FLIP with
the reference exposed to mid grey.

Means converge while a person still sees a 2x2 checkerboard; these two figures
measure what the eye picks up.

* :func:`relative_error` -- per-pixel luminance error relative to the local reference
  level: ``(Y_t - Y_r) / (Y_r + RELATIVE_FLOOR * median(Y_r))`` (Rec.709 luminance;
  the floor keeps black pixels from dominating and makes the figure independent of
  the images' unit scale).
* :func:`spectral_structure` -- of an error image: clip at its 99th percentile of |e|
  (fireflies have a flat spectrum), remove the mean, take the power spectrum; the
  share of the energy in the strongest ``q`` (0.5 %) of spatial frequencies at or
  above ``fmin`` (1/16 cycle per pixel), divided by white noise's expected share
  ``q (1 - ln q)`` (the power of white noise is exponentially distributed; the top
  q of an exponential holds q (1 - ln q) of its mass). 1 = unstructured noise; a
  2x2 checkerboard scores ~16-30; noise constant over 2x2 quads ~2.3.
* :func:`structured_noise` -- ``spectral_structure(relative_error(test, ref))``.
* :func:`flip_hdr_midgrey` -- HDR-FLIP with both images scaled so the reference's
  median is 0.18 (mid grey): comparable across scenes of any brightness.
"""

from __future__ import annotations

import numpy as np

from ..color import LUMINANCE_REC709
from .image import _check, flip_hdr

#: Share of the spatial frequencies examined: the strongest 0.5 %.
STRUCTURE_Q = 0.005
#: Lowest spatial frequency counted (cycles per pixel): coarser error is bias or
#: low-frequency blotches, not the pattern this figure is about.
STRUCTURE_FMIN = 1.0 / 16.0
#: Percentile of |error| where the error is clipped before the spectrum.
STRUCTURE_CLIP_PERCENTILE = 99.0
#: Floor of the relative error's denominator, as a fraction of the reference's
#: median luminance.
RELATIVE_FLOOR = 0.05
#: Mid grey: the reference's median is exposed to this for HDR-FLIP.
MID_GREY = 0.18


def luminance(img: np.ndarray) -> np.ndarray:
    """Rec.709 luminance of (h, w, 3|4) scene-linear RGB (alpha ignored)."""
    return np.asarray(img, dtype=np.float64)[..., :3] @ np.asarray(LUMINANCE_REC709)


def relative_error(test: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """(h, w) luminance error of ``test`` relative to the local reference level."""
    t, r = _check(test, ref)
    yt, yr = luminance(t), luminance(r)
    floor = RELATIVE_FLOOR * float(np.median(yr))
    return (yt - yr) / (np.abs(yr) + floor + 1e-12)


def spectral_structure(
    err: np.ndarray, q: float = STRUCTURE_Q, fmin: float = STRUCTURE_FMIN
) -> float:
    """Structure of an (h, w) error image relative to white noise (1 = white)."""
    if not 0.0 < q < 1.0:
        raise ValueError("q must be in (0, 1)")
    e = np.asarray(err, dtype=np.float64)
    if e.ndim != 2:
        raise ValueError(f"need an (h, w) error image, got shape {e.shape}")
    e = np.nan_to_num(e)
    c = float(np.percentile(np.abs(e), STRUCTURE_CLIP_PERCENTILE))
    e = np.clip(e, -c, c)
    e = e - e.mean()
    power = np.abs(np.fft.fft2(e)) ** 2
    fy = np.fft.fftfreq(e.shape[0])[:, None]
    fx = np.fft.fftfreq(e.shape[1])[None, :]
    v = power[np.hypot(fy, fx) >= fmin]
    total = float(v.sum())
    if total <= 0.0:
        return 0.0
    k = max(1, round(q * v.size))
    top = float(np.partition(v, v.size - k)[v.size - k :].sum())
    return top / total / (q * (1.0 - np.log(q)))


def structured_noise(test: np.ndarray, ref: np.ndarray) -> float:
    """Structure of ``test``'s error against ``ref`` (1 = white noise, >= 2 visible)."""
    return spectral_structure(relative_error(test, ref))


def flip_hdr_midgrey(test: np.ndarray, ref: np.ndarray) -> float:
    """Mean HDR-FLIP with the reference's median exposed to mid grey (0.18)."""
    t, r = _check(test, ref)
    k = MID_GREY / max(float(np.median(r.mean(axis=-1))), 1e-12)
    return flip_hdr(t * k, r * k)
