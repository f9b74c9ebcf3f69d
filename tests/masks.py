"""Boolean pixel masks for image tests."""

from __future__ import annotations

import numpy as np


def dilate(m: np.ndarray, r: int) -> np.ndarray:
    """``m`` (h, w bool) grown by ``r`` pixels through 4-neighbours (edges not wrapped)."""
    out = m.copy()
    for _ in range(r):
        o = out.copy()
        o[1:] |= out[:-1]
        o[:-1] |= out[1:]
        o[:, 1:] |= out[:, :-1]
        o[:, :-1] |= out[:, 1:]
        out = o
    return out
