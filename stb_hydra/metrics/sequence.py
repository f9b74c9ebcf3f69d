"""Metrics of image sequences against per-frame references (moving cameras and
animated scenes: temporal reuse, ``stb_hydra.renderer.tasks.temporal``).

* :func:`per_frame_flip` -- HDR-FLIP at mid grey of every frame against its own
  reference frame (the reference is rendered at the same time and camera).
* :func:`instability_ratio` -- frame-to-frame change of the display image over the
  reference's own change (1 = as steady as the reference; a moving camera changes
  the reference too, so the plain instability is not an error).
* :func:`region_error` / :func:`frames_to_settle` -- ghosting: the error left in a
  region (e.g. floor an object has just uncovered) frame by frame, and how many
  frames it takes to fall back to a still-camera level.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from .image import display_referred, temporal_instability
from .structure import flip_hdr_midgrey


def _frames(a: Sequence[np.ndarray] | np.ndarray) -> np.ndarray:
    f = np.asarray(a, dtype=np.float64)
    if f.ndim != 4:
        raise ValueError(f"expected (frames, h, w, c) images, got shape {f.shape}")
    return f[..., :3]


def per_frame_flip(
    frames: Sequence[np.ndarray] | np.ndarray, refs: Sequence[np.ndarray] | np.ndarray
) -> np.ndarray:
    """(T,) HDR-FLIP at mid grey of frame t against reference frame t."""
    f, r = _frames(frames), _frames(refs)
    if f.shape != r.shape:
        raise ValueError(f"sequence shapes differ: {f.shape} vs {r.shape}")
    return np.array([flip_hdr_midgrey(f[i], r[i]) for i in range(len(f))])


def instability_ratio(
    frames: Sequence[np.ndarray] | np.ndarray,
    refs: Sequence[np.ndarray] | np.ndarray,
    display: bool = True,
) -> float:
    """Temporal instability of ``frames`` over the reference sequence's own (of the
    display-referred images by default: what a viewer sees change)."""
    f, r = _frames(frames), _frames(refs)
    if display:
        f = np.array([display_referred(x) for x in f])
        r = np.array([display_referred(x) for x in r])
    own = temporal_instability(r)
    return float(temporal_instability(f) / max(own, 1e-12))


def region_error(
    frames: Sequence[np.ndarray] | np.ndarray,
    refs: Sequence[np.ndarray] | np.ndarray,
    mask: np.ndarray,
    eps: float = 1e-2,
) -> np.ndarray:
    """(T,) mean relative luminance error |f - r| / (r + eps) over ``mask`` (h, w)
    of every frame against its reference."""
    f, r = _frames(frames), _frames(refs)
    w = np.array([0.2126, 0.7152, 0.0722])
    lf, lr = f @ w, r @ w
    m = np.asarray(mask, dtype=bool)
    if not m.any():
        raise ValueError("region_error: empty mask")
    err = np.abs(lf - lr) / (np.abs(lr) + eps)
    return err[:, m].mean(axis=1)


def frames_to_settle(errors: Sequence[float] | np.ndarray, level: float) -> int:
    """Frames until ``errors`` is at or below ``level`` and stays there (len(errors)
    + 1 if it never settles): the ghosting delay after an uncovering."""
    e = np.asarray(errors, dtype=np.float64)
    above = np.nonzero(e > level)[0]
    if not len(above):
        return 0
    last = int(above[-1]) + 1
    return last if last < len(e) else len(e) + 1


__all__ = ["frames_to_settle", "instability_ratio", "per_frame_flip", "region_error"]
