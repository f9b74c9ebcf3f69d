"""Generate the interleaved small-tile quad patterns (STB small-tile resampling).

Four small tiles share a 32x32 px footprint = 16x16 quads of 2x2 px. Each tile
owns 64 quads, spread with a Gaussian-Poisson distribution: denser near the
tile's nominal centre (the centre of its 16x16 px quadrant), and no two quads
of the same tile side by side (4-neighbourhood, periodic: the pattern repeats
over the image).

Method (deterministic for a seed):
1. Start from a valid partition: a 2x2 checkerboard of 4 colours, split so
   every tile has 64 quads and no same-tile 4-neighbours.
2. Simulated annealing with pair swaps between tiles: minimise the Gaussian
   energy sum_t sum_{q in t} |q - c_t|^2 / (2 sigma^2) (periodic distance),
   rejecting any swap that creates same-tile 4-neighbours.
3. Slots: each tile's quads are numbered by increasing distance to its centre
   (slot 0 nearest), so slots 0..3 are good PDF sample points too.

Output: ``stb_hydra/data/quad_patterns.json`` with
``tile_of_quad`` (16x16, row = quad y), ``slot_of_quad`` (16x16) -- together the
16x16 inverse LUT quad -> (tile, slot) -- and ``quad_of_slot`` (4 x 64 x 2,
(qx, qy)) the forward table, plus the parameters used.

Usage: python tools/gen_quad_patterns.py [--seed 1] [--sigma 4.0] [--iters 200000]
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

Q = 16  # quads per footprint side
TILES = 4
PER_TILE = Q * Q // TILES
CENTRES = np.array([[3.5, 3.5], [11.5, 3.5], [3.5, 11.5], [11.5, 11.5]])  # (qx, qy)


def periodic_d2(q: np.ndarray, c: np.ndarray) -> np.ndarray:
    d = np.abs(q - c)
    d = np.minimum(d, Q - d)
    return (d**2).sum(axis=-1)


def has_conflict(tiles: np.ndarray, y: int, x: int) -> bool:
    t = tiles[y, x]
    return (
        tiles[(y + 1) % Q, x] == t
        or tiles[(y - 1) % Q, x] == t
        or tiles[y, (x + 1) % Q] == t
        or tiles[y, (x - 1) % Q] == t
    )


def initial() -> np.ndarray:
    """Valid start: colour = 2*((x + y) & 1) + (parity of (x - y)/2 ...), 64 each."""
    y, x = np.mgrid[0:Q, 0:Q]
    a = (x + y) & 1
    b = ((x + y) // 2 + y) & 1  # splits each checkerboard colour in two
    tiles = (2 * a + b).astype(np.int64)
    # Assign the colours to tiles so each colour class sits nearest its tile centre.
    return tiles


def energy_of(tiles: np.ndarray, sigma: float) -> float:
    y, x = np.mgrid[0:Q, 0:Q]
    q = np.stack([x, y], axis=-1).astype(float)
    return float(periodic_d2(q, CENTRES[tiles]).sum() / (2 * sigma * sigma))


def anneal(seed: int, sigma: float, iters: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    tiles = initial()
    for y in range(Q):
        for x in range(Q):
            assert not has_conflict(tiles, y, x)
    assert all((tiles == t).sum() == PER_TILE for t in range(TILES))
    yy, xx = np.mgrid[0:Q, 0:Q]
    q = np.stack([xx, yy], axis=-1).astype(float)
    cost = periodic_d2(q[..., None, :], CENTRES[None, None]) / (2 * sigma * sigma)  # (Q,Q,4)
    temp0 = 2.0
    for i in range(iters):
        temp = temp0 * (1.0 - i / iters) + 1e-3
        y1, x1, y2, x2 = rng.integers(0, Q, 4)
        t1, t2 = tiles[y1, x1], tiles[y2, x2]
        if t1 == t2:
            continue
        delta = cost[y1, x1, t2] + cost[y2, x2, t1] - cost[y1, x1, t1] - cost[y2, x2, t2]
        if delta > 0 and rng.random() >= math.exp(-delta / temp):
            continue
        tiles[y1, x1], tiles[y2, x2] = t2, t1
        if has_conflict(tiles, y1, x1) or has_conflict(tiles, y2, x2):
            tiles[y1, x1], tiles[y2, x2] = t1, t2
    return tiles


def build(seed: int = 1, sigma: float = 4.0, iters: int = 200_000) -> dict:
    tiles = anneal(seed, sigma, iters)
    slot = np.zeros((Q, Q), dtype=np.int64)
    fwd = np.zeros((TILES, PER_TILE, 2), dtype=np.int64)
    for t in range(TILES):
        ys, xs = np.nonzero(tiles == t)
        d = periodic_d2(np.stack([xs, ys], axis=-1).astype(float), CENTRES[t])
        order = np.lexsort((xs, ys, d))
        for s, k in enumerate(order):
            slot[ys[k], xs[k]] = s
            fwd[t, s] = (xs[k], ys[k])
    return {
        "description": "STB interleaved small-tile quad patterns (tools/gen_quad_patterns.py)",
        "seed": seed,
        "sigma_quads": sigma,
        "iterations": iters,
        "footprint_px": 2 * Q,
        "energy": energy_of(tiles, sigma),
        "tile_of_quad": tiles.tolist(),
        "slot_of_quad": slot.tolist(),
        "quad_of_slot": fwd.tolist(),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--sigma", type=float, default=4.0, help="Gaussian sigma in quads")
    ap.add_argument("--iters", type=int, default=200_000)
    ap.add_argument(
        "--out",
        default=str(
            Path(__file__).resolve().parents[1] / "stb_hydra" / "data" / "quad_patterns.json"
        ),
    )
    a = ap.parse_args()
    data = build(a.seed, a.sigma, a.iters)
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    Path(a.out).write_text(json.dumps(data, indent=None, separators=(",", ":")) + "\n")
    print(f"wrote {a.out} (energy {data['energy']:.1f})")


if __name__ == "__main__":
    main()
