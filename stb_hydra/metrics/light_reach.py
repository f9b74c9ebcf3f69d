"""How much of the view each local light reaches (issue 34 item C's "lights reach <= 10 %
of the view each", measured instead of assumed).

Two fractions per light, both over every pixel of the view (background included):

* ``reach``: pixels whose visible surface point lies strictly inside the light's range
  sphere -- the light-pixel pairs an exact method shades (``light_reaches`` of the
  shaders: ``|pos - P| < range``, here in float64).
* ``cover``: pixels whose view ray meets the range sphere -- its projected footprint,
  what a screen-space culling cell can at best bound (tiled / clustered lists are built
  from it, trimmed by depth).

Pure numpy (no GL): the caller hands world-space surface points, the view rays and the
lights. ``stb_hydra/tools``' ``tools/light_reach.py`` reads them from a rendered frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Lights per chunk of the (lights x pixels) distance tests: bounds the temporary
#: arrays to CHUNK x pixels float64 (64 x 268k px = 137 MB at 745x360).
CHUNK = 64


@dataclass
class ReachStats:
    """Per-light fractions of the view (0..1) and per-pixel reached-light counts."""

    reach: np.ndarray  # (n,) fraction of the view's pixels each light reaches
    cover: np.ndarray  # (n,) fraction of the view's pixels whose ray meets its sphere
    per_pixel: np.ndarray  # (pixels,) lights reaching each pixel's surface point

    def summary(self, limit: float = 0.10) -> dict[str, float]:
        """Median / p95 / max / mean of both fractions (as fractions), how many lights
        exceed ``limit``, and the reached lights per pixel (mean / p95 / max)."""
        out: dict[str, float] = {"lights": len(self.reach)}
        for name, v in (("reach", self.reach), ("cover", self.cover)):
            if len(v) == 0:
                continue
            out[f"{name}_median"] = float(np.median(v))
            out[f"{name}_p95"] = float(np.percentile(v, 95))
            out[f"{name}_max"] = float(v.max())
            out[f"{name}_mean"] = float(v.mean())
            out[f"{name}_over_limit"] = int((v > limit).sum())
        if self.per_pixel.size:
            out["reached_per_pixel_mean"] = float(self.per_pixel.mean())
            out["reached_per_pixel_p95"] = float(np.percentile(self.per_pixel, 95))
            out["reached_per_pixel_max"] = int(self.per_pixel.max())
        return out


def light_reach(
    points: np.ndarray,
    valid: np.ndarray,
    ray_origin: np.ndarray,
    ray_dir: np.ndarray,
    light_pos: np.ndarray,
    light_range: np.ndarray,
) -> ReachStats:
    """Reach and cover of each light over one view.

    ``points``: (N, 3) world-space surface point per pixel (m), ``valid``: (N,) True
    where the pixel has a surface; ``ray_origin`` (N, 3) or (3,) and ``ray_dir`` (N, 3)
    unit world-space view rays (m); ``light_pos`` (n, 3) world positions (m),
    ``light_range`` (n,) influence radii (m). Fractions are over all N pixels.
    """
    P = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    ok = np.asarray(valid, dtype=bool).reshape(-1)
    N = len(P)
    O = np.broadcast_to(np.asarray(ray_origin, dtype=np.float64), P.shape)
    D = np.asarray(ray_dir, dtype=np.float64).reshape(-1, 3)
    L = np.asarray(light_pos, dtype=np.float64).reshape(-1, 3)
    R = np.asarray(light_range, dtype=np.float64).reshape(-1)
    n = len(L)
    reach = np.zeros(n, dtype=np.int64)
    cover = np.zeros(n, dtype=np.int64)
    per_pixel = np.zeros(N, dtype=np.int64)
    Pv = P[ok]
    for a in range(0, n, CHUNK):
        lc, rc = L[a : a + CHUNK], R[a : a + CHUNK]
        d2 = ((Pv[None, :, :] - lc[:, None, :]) ** 2).sum(axis=-1)
        hit = d2 < (rc * rc)[:, None]
        reach[a : a + CHUNK] = hit.sum(axis=1)
        per_pixel[ok] += hit.sum(axis=0)
        oc = lc[:, None, :] - O[None, :, :]  # ray origin -> centre
        t = (oc * D[None, :, :]).sum(axis=-1)
        oc2 = (oc * oc).sum(axis=-1)
        r2 = (rc * rc)[:, None]
        perp2 = oc2 - np.maximum(t, 0.0) ** 2  # distance^2 from the ray (a half-line)
        cover[a : a + CHUNK] = (perp2 < r2).sum(axis=1)
    scale = 1.0 / max(N, 1)
    return ReachStats(reach * scale, cover * scale, per_pixel)
