"""Which lights changed between two frames, and where: the light-change test shared by
the temporal passes that keep a history of lighting (taa, ``tasks/temporal.py``; STB's
reservoir reuse, ``lighting/stb_reuse.py``).

A light that changed a lot shortens the history inside its influence sphere (centre:
its position now, radius: its range before or after, the larger, plus how far it
moved), by the first of the caller's rules it meets: ``(cap, relative intensity change
above, move above this fraction of its range, cosine of its turn below)``. A light
switched on or off, or whose ``exact`` columns changed (type, emission, IES profile),
meets the first rule. Rows rewritten with the same values are no change. Render frame,
metres.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .light_table import LightTable

#: Light-table columns :func:`light_snapshot` copies.
SNAPSHOT_COLUMNS = (
    "enabled",
    "live",
    "type",
    "emission",
    "ies_layer",
    "intensity",
    "range",
    "position",
    "direction",
)

#: A change rule: (history cap, relative intensity change above, move above this
#: fraction of the range, cosine of the turn below).
Rule = tuple[float, float, float, float]


def light_snapshot(table: LightTable) -> dict[str, np.ndarray]:
    """Copies of the light-table columns :func:`light_changes` compares."""
    n = int(table.n_rows)
    return {k: np.array(table.cols[k][:n]) for k in SNAPSHOT_COLUMNS}


def light_changes(
    before: dict[str, np.ndarray],
    now: dict[str, np.ndarray],
    rules: tuple[Rule, ...],
    exact: tuple[str, ...],
) -> tuple[np.ndarray, np.ndarray]:
    """Lights that changed between two snapshots of the same row count: (spheres (k, 4):
    centre xyz m + radius m, history caps (k,)). ``rules``: first match wins;
    ``exact``: columns whose change counts as a switch (the first rule)."""
    on0 = before["enabled"] & before["live"]
    on1 = now["enabled"] & now["live"]
    n = len(on0)
    switched = (on0 != on1).copy()
    for k in exact:
        a, b = before[k], now[k]
        switched |= (a != b) if a.ndim == 1 else np.any(a != b, axis=1)
    i0 = np.linalg.norm(np.asarray(before["intensity"], np.float64).reshape(n, -1), axis=1)
    i1 = np.linalg.norm(np.asarray(now["intensity"], np.float64).reshape(n, -1), axis=1)
    rel = np.abs(i1 - i0) / np.maximum(np.maximum(i0, i1), 1e-30)
    rng = np.maximum(np.asarray(now["range"], np.float64), np.asarray(before["range"], np.float64))
    moved = np.linalg.norm(
        np.asarray(now["position"], np.float64) - np.asarray(before["position"], np.float64), axis=1
    )
    move = moved / np.maximum(rng, 1e-3)
    d0 = np.asarray(before["direction"], np.float64)
    d1 = np.asarray(now["direction"], np.float64)
    norms = np.linalg.norm(d0, axis=1) * np.linalg.norm(d1, axis=1)
    cos = np.where(norms > 0, np.sum(d0 * d1, axis=1) / np.maximum(norms, 1e-30), 1.0)
    cap = np.full(n, np.inf)
    for c, di, dm, dc in reversed(rules):
        cap[(rel > di) | (move > dm) | (cos < dc)] = c
    cap[switched] = rules[0][0]
    cap[~(on0 | on1)] = np.inf  # off before and after: nothing to see
    rows = np.nonzero(np.isfinite(cap))[0]
    centre = np.asarray(now["position"], np.float64)[rows]
    radius = np.minimum(rng[rows] + moved[rows], 1e30)
    return np.column_stack([centre, radius]).reshape(-1, 4), cap[rows]


def change_uniforms(
    spheres: np.ndarray, caps: np.ndarray, size: int
) -> tuple[np.ndarray, np.ndarray, float | None]:
    """The shader's fixed-size arrays of changed lights: (spheres (size, 4) float32,
    caps (size,) float32, cap everywhere). More changes than ``size`` are not tested per
    pixel: the arrays come back empty-padded and the third value is the strictest cap,
    for the caller to apply everywhere (None otherwise)."""
    sph = np.zeros((size, 4), np.float32)
    cap = np.zeros(size, np.float32)
    if len(caps) > size:
        return sph, cap, float(caps.min())
    sph[: len(caps)] = np.minimum(spheres, 1e30)
    cap[: len(caps)] = caps
    return sph, cap, None
