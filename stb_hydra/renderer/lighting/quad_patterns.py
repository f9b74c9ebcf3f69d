"""Interleaved small-tile quad patterns: which of the 4 small tiles of a 32x32 px
footprint owns each of its 16x16 quads, and in which slot.

* ``fixed``: the talk's single Gaussian-Poisson pattern (``data/quad_patterns.json``,
  ``tools/gen_quad_patterns.py``): dense near each tile's centre, no two quads of a
  tile side by side -- a blue-noise arrangement, so every frame's noise has a ring
  of energy at ~1/3 cycle per pixel that averaging frames keeps (structured noise ~6
  in a pure model, 3.7 on the default scene).
* ``random`` (:func:`pattern_bank`): a bank of balanced random patterns, one drawn per
  frame. Each tile still gets exactly 64 quads, drawn with a Gaussian preference for
  its own quadrant (Gumbel-perturbed log weights, greedy balanced assignment), so a
  tile's quads stay local while the arrangement is white from frame to frame.

Arrays: ``tile_of_quad`` and ``slot_of_quad`` (P, 16, 16) (row = quad y) and
``quad_of_slot`` (P, 4, 64, 2) (qx, qy); slots of a tile run by increasing distance
to its centre (slot 0 nearest).
"""

from __future__ import annotations

import functools
import json
from dataclasses import dataclass
from importlib import resources

import numpy as np

from ... import limits

Q = 16  #: quads per footprint side
TILES = 4
PER_TILE = Q * Q // TILES
#: Nominal centres of the 4 tiles (quad units, periodic footprint).
CENTRES = np.array([[3.5, 3.5], [11.5, 3.5], [3.5, 11.5], [11.5, 11.5]])


@dataclass(frozen=True)
class QuadPatterns:
    tile_of_quad: np.ndarray  # (P, 16, 16) int
    slot_of_quad: np.ndarray  # (P, 16, 16) int
    quad_of_slot: np.ndarray  # (P, 4, 64, 2) int

    @property
    def count(self) -> int:
        return len(self.tile_of_quad)


def _d2() -> np.ndarray:
    """(16, 16, 4) periodic squared distance (quads) from each quad to each centre."""
    qy, qx = np.mgrid[:Q, :Q]
    q = np.stack([qx, qy], -1).astype(np.float64)[:, :, None, :]
    d = np.abs(q - CENTRES[None, None])
    d = np.minimum(d, Q - d)
    return (d**2).sum(-1)


def _slots(tile: np.ndarray, d2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Slots by increasing distance to the owner's centre; the forward table."""
    slot = np.zeros((Q, Q), dtype=np.int64)
    fwd = np.zeros((TILES, PER_TILE, 2), dtype=np.int64)
    for t in range(TILES):
        ys, xs = np.nonzero(tile == t)
        order = np.lexsort((xs, ys, d2[ys, xs, t]))
        slot[ys[order], xs[order]] = np.arange(PER_TILE)
        fwd[t, :, 0], fwd[t, :, 1] = xs[order], ys[order]
    return slot, fwd


@functools.cache
def fixed_pattern() -> QuadPatterns:
    """The shipped Gaussian-Poisson pattern (one layer)."""
    data = json.loads(resources.files("stb_hydra").joinpath("data/quad_patterns.json").read_text())
    return QuadPatterns(
        np.array(data["tile_of_quad"], dtype=np.int64)[None],
        np.array(data["slot_of_quad"], dtype=np.int64)[None],
        np.array(data["quad_of_slot"], dtype=np.int64)[None],
    )


@functools.cache
def pattern_bank(
    count: int = limits.STB_PATTERN_BANK,
    sigma: float = limits.STB_PATTERN_SIGMA_QUADS,
    seed: int = 0,
) -> QuadPatterns:
    """``count`` balanced random patterns (deterministic for ``seed``)."""
    rng = np.random.default_rng(seed)
    d2 = _d2()
    tiles = np.zeros((count, Q, Q), dtype=np.int64)
    slots = np.zeros((count, Q, Q), dtype=np.int64)
    fwds = np.zeros((count, TILES, PER_TILE, 2), dtype=np.int64)
    for p in range(count):
        score = -d2 / (2.0 * sigma * sigma) + rng.gumbel(size=d2.shape)
        order = np.argsort(-score.ravel(), kind="stable")
        owner = np.full(Q * Q, -1, dtype=np.int64)
        filled = np.zeros(TILES, dtype=np.int64)
        for i in order.tolist():  # 1024 pairs, once per pattern at start-up
            q, t = divmod(i, TILES)
            if owner[q] < 0 and filled[t] < PER_TILE:
                owner[q] = t
                filled[t] += 1
        tiles[p] = owner.reshape(Q, Q)
        slots[p], fwds[p] = _slots(tiles[p], d2)
    return QuadPatterns(tiles, slots, fwds)
