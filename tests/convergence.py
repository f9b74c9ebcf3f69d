"""Unbiasedness of a Monte Carlo render, told apart from its noise (issue 32).

The mean of M frames against the truth t has relMSE = B + V / M: B, the squared
relative bias (what an unbiasedness test is after) and V / M, the noise. A test that
bounds the relMSE alone must render frames until V / M is small beside the bias it
wants to see. Split the M frames in halves instead: their means A and B' carry the
same bias and independent noise (each frame has its own seeds), so

    bias2 = mean over pixels of (A - t)(B' - t) / (t^2 + eps)

has expectation B exactly, with no V / M term; its own spread falls as V / M over
the square root of the image's independent tiles. So a few times fewer frames bound
the bias as tightly as the relMSE did (docs/TESTING.md, "Convergence tests").

The halves come from one accumulation: ``render_progressive`` snapshots of M / 2
and M frames give A = mean(M / 2) and B' = 2 mean(M) - mean(M / 2).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def snapshot_counts(frames: int) -> tuple[int, int, int]:
    """The ``render_progressive`` counts :func:`convergence` reads: M / 8, M / 2, M."""
    assert frames % 8 == 0, frames
    return frames // 8, frames // 2, frames


@dataclass(frozen=True)
class Convergence:
    """Statistics of the M-frame mean against the truth (relative, epsilon ``eps``)."""

    frames: int
    relmse: float  #: relMSE of the M-frame mean (bias + noise)
    relmse_early: float  #: relMSE of the first M / 8 frames' mean
    bias2: float  #: split-half estimate of the squared relative bias (noise-free in expectation)
    mean_ratio: float  #: image mean over the truth's image mean
    finite: bool  #: no NaN / Inf in any snapshot


def convergence(imgs: dict[int, np.ndarray], truth: np.ndarray, eps: float = 1e-2) -> Convergence:
    """:class:`Convergence` of ``imgs`` (``render_progressive`` snapshots at
    :func:`snapshot_counts`) against ``truth`` (same shape as each snapshot)."""
    m = max(imgs)
    early, half = m // 8, m // 2
    truth = np.asarray(truth, dtype=np.float64)
    w = 1.0 / (truth**2 + eps)
    full = np.asarray(imgs[m], dtype=np.float64)
    a = np.asarray(imgs[half], dtype=np.float64)
    b = 2.0 * full - a  # the second half's mean
    return Convergence(
        frames=m,
        relmse=float(np.mean((full - truth) ** 2 * w)),
        relmse_early=float(np.mean((np.asarray(imgs[early], np.float64) - truth) ** 2 * w)),
        bias2=float(np.mean((a - truth) * (b - truth) * w)),
        mean_ratio=float(full.mean() / truth.mean()),
        finite=all(bool(np.isfinite(v).all()) for v in imgs.values()),
    )
