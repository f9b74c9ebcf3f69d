"""Light clusters of STB's big-tile pass for many lights (issue 16, ``-o bigtile``).

The FoV lights are sorted along a Morton (Z-order) curve of their positions and cut
into runs of :data:`~stb_hydra.limits.BIG_TILE_CLUSTER_LIGHTS`: clusters; runs of
:data:`~stb_hydra.limits.BIG_TILE_CLUSTER_FANOUT` clusters are super-clusters. Each
has the bounding box of its lights' positions (world, m), their summed flux (lm) and
their largest influence range (m). ``stb_bigtile_clusters.comp`` scores the
super-clusters per big tile, then per slot the clusters of the drawn super-cluster,
then streams the drawn cluster's lights. Built with numpy, once per change of the
light table or of the FoV set (a still scene rebuilds nothing).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ... import limits

#: Bits per axis of the Morton code (3 x 10 = 30 bits).
MORTON_BITS = 10


def _spread_bits(v: np.ndarray) -> np.ndarray:
    """Insert two zero bits after each of the low 10 bits of ``v`` (uint64)."""
    v = v & 0x3FF
    v = (v | (v << 16)) & 0x030000FF
    v = (v | (v << 8)) & 0x0300F00F
    v = (v | (v << 4)) & 0x030C30C3
    v = (v | (v << 2)) & 0x09249249
    return v


def morton_order(positions: np.ndarray) -> np.ndarray:
    """Indices that sort ``positions`` (n, 3) along a Z-order curve of their bounding
    box (stable: equal codes keep their order)."""
    p = np.asarray(positions, dtype=np.float64)
    if len(p) == 0:
        return np.zeros(0, dtype=np.int64)
    lo = p.min(axis=0)
    ext = np.maximum(p.max(axis=0) - lo, 1e-12)
    q = np.clip((p - lo) / ext * ((1 << MORTON_BITS) - 1), 0, (1 << MORTON_BITS) - 1)
    q = q.astype(np.uint64)
    code = _spread_bits(q[:, 0]) | (_spread_bits(q[:, 1]) << 1) | (_spread_bits(q[:, 2]) << 2)
    return np.argsort(code, kind="stable")


@dataclass
class LightClusters:
    """``order``: FoV light index per clustered position (uint32, Morton order);
    ``clusters`` and ``supers``: (count, 8) float32 -- min xyz, flux sum, max xyz, max
    range. Cluster c holds ``order[c * G : (c + 1) * G]``, super-cluster s the clusters
    ``s * F ... (s + 1) * F - 1``. ``cdf``: per clustered light, the inclusive CDF of
    its cluster's flux (float32; each cluster's last light holds exactly 1, a cluster
    without flux is uniform): ``-o cluster_pick=flux`` draws a light of a cluster from
    it."""

    order: np.ndarray
    clusters: np.ndarray
    supers: np.ndarray
    cdf: np.ndarray

    @property
    def count(self) -> int:
        return len(self.clusters)

    def records(self) -> np.ndarray:
        """The GPU array: super-clusters first, then clusters."""
        return np.ascontiguousarray(np.concatenate([self.supers, self.clusters]))


def cluster_cdf(flux: np.ndarray, group: int) -> np.ndarray:
    """Inclusive CDF of ``flux`` (n,) >= 0 within each run of ``group`` (the last run
    may be short), float32: each run's last entry is exactly 1, a run summing to 0 is
    uniform."""
    n = len(flux)
    if n == 0:
        return np.zeros(0, np.float32)
    pad = -n % group
    runs = np.concatenate([np.asarray(flux, np.float64), np.zeros(pad)]).reshape(-1, group)
    size = np.full(len(runs), group)
    size[-1] = group - pad
    prefix = np.cumsum(runs, axis=1)
    total = prefix[:, -1:]
    uniform = np.arange(1, group + 1) / size[:, None]
    cdf = np.where(total > 0, prefix / np.where(total > 0, total, 1.0), uniform)
    cdf = np.minimum(cdf, 1.0)
    cdf[np.arange(len(runs)), size - 1] = 1.0
    return cdf.ravel()[:n].astype(np.float32)


def _merge(rec: np.ndarray, size: int) -> np.ndarray:
    """Records (min xyz, flux, max xyz, range) of runs of ``size`` consecutive records:
    the box around their boxes, their summed flux, their largest range."""
    starts = np.arange(0, len(rec), size)
    out = np.empty((len(starts), 8), dtype=np.float64)
    out[:, 0:3] = np.minimum.reduceat(rec[:, 0:3], starts, axis=0)
    out[:, 3] = np.add.reduceat(rec[:, 3], starts)
    out[:, 4:7] = np.maximum.reduceat(rec[:, 4:7], starts, axis=0)
    out[:, 7] = np.maximum.reduceat(rec[:, 7], starts)
    return out


def build_clusters(
    positions: np.ndarray,
    ranges: np.ndarray,
    flux: np.ndarray,
    group: int = limits.BIG_TILE_CLUSTER_LIGHTS,
    fanout: int = limits.BIG_TILE_CLUSTER_FANOUT,
) -> LightClusters:
    """Clusters of ``group`` consecutive lights along the Morton curve and
    super-clusters of ``fanout`` consecutive clusters.

    positions (n, 3) world m; ranges (n,) m; flux (n,) lm (negative counts as 0)."""
    n = len(positions)
    order = morton_order(positions)
    if n == 0:
        empty = np.zeros((0, 8), np.float32)
        return LightClusters(np.zeros(0, np.uint32), empty, empty, np.zeros(0, np.float32))
    # One record per light (a point box), then the two levels of merged runs.
    lights = np.empty((n, 8), dtype=np.float64)
    lights[:, 0:3] = lights[:, 4:7] = np.asarray(positions, dtype=np.float64)[order]
    lights[:, 3] = np.maximum(np.asarray(flux, dtype=np.float64)[order], 0.0)
    lights[:, 7] = np.asarray(ranges, dtype=np.float64)[order]
    cl = _merge(lights, group)
    sup = _merge(cl, fanout)
    return LightClusters(
        order.astype(np.uint32),
        cl.astype(np.float32),
        sup.astype(np.float32),
        cluster_cdf(lights[:, 3], group),
    )
