"""``StbNoiseRisk`` (stage validator): how many lights can reach one surface point.

STB keeps K = 16 reservoir slots per 128x128 px big tile; where more lights reach
the same surface each slot resamples several of them and the image gets noisier.
We sample VALIDATE_OVERLAP_SAMPLES points over the asset's visible meshes,
area-weighted (every instance of instanced geometry included), and count at each
point the enabled local lights that

* have the point inside their influence sphere (``LightPrim.range``, metres), and
* face it: some of the light is in front of the surface (both sides for double-sided
  meshes) -- area lights (issue 20) reach a point while any of their area is above its
  horizon: the centre may be up to the light's half extent below it -- and the point
  is inside the light's emission (cone half-angle for shaped lights, front
  hemisphere for disk/rect emitters).

A count above VALIDATE_STB_OVERLAP_MAX gives one warning per mesh, at its worst
point (stage coordinates). Sampling is seeded: the result is deterministic.
"""

from __future__ import annotations

import math

import numpy as np
from pxr import Usd

from .. import limits
from ..scene import prims
from ..scene.lights import area_half_extent
from .analysis import StageAnalysis, analysis_for
from .common import finding
from .findings import Finding

_CHUNK = 512
#: Axis cosine limit of a light without a cone: below any cosine, so every direction passes.
_NO_CONE_COS = -2.0


def sample_surface(ana: StageAnalysis, n: int, seed: int = 0):
    """(points (n,3), normals (n,3), double_sided (n,), mesh index (n,)) in the render
    frame (metres), area-weighted over every mesh instance."""
    rng = np.random.default_rng(seed)
    parts = []  # (mesh index, local tris (m,3,3), local areas (m,), world matrices (k,4,4))
    weights = []
    for mi, m in enumerate(ana.meshes):
        pts = np.asarray(m.points, dtype=np.float64)
        idx = np.asarray(m.indices, dtype=np.int64)
        if len(pts) == 0 or len(idx) == 0:
            continue
        tri = pts[idx]
        cr = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        area = 0.5 * np.linalg.norm(cr, axis=1)
        total = float(area.sum())
        if not (total > 0 and math.isfinite(total)):
            continue
        mats = m.world_transforms()
        det = np.abs(np.linalg.det(mats[:, :3, :3]))
        for k in range(len(mats)):
            parts.append((mi, tri, area, mats[k], bool(m.double_sided)))
            weights.append(total * float(det[k]) ** (2.0 / 3.0))
    if not parts:
        return None
    w = np.asarray(weights)
    counts = rng.multinomial(n, w / w.sum())
    P, N, D, M = [], [], [], []
    for (mi, tri, area, mat, ds), c in zip(parts, counts):
        if c == 0:
            continue
        t = rng.choice(len(tri), size=c, p=area / area.sum())
        u, v = rng.random(c), rng.random(c)
        flip = u + v > 1.0
        u, v = np.where(flip, 1.0 - u, u), np.where(flip, 1.0 - v, v)
        a, b, cc = tri[t, 0], tri[t, 1], tri[t, 2]
        p = a + (b - a) * u[:, None] + (cc - a) * v[:, None]
        nrm = np.cross(b - a, cc - a)
        m3 = mat[:3, :3]
        P.append(p @ m3 + mat[3, :3])
        try:
            nw = nrm @ np.linalg.inv(m3).T
        except np.linalg.LinAlgError:
            nw = nrm @ m3
        N.append(nw / np.maximum(np.linalg.norm(nw, axis=1, keepdims=True), 1e-30))
        D.append(np.full(c, ds))
        M.append(np.full(c, mi))
    return np.concatenate(P), np.concatenate(N), np.concatenate(D), np.concatenate(M)


def overlap_counts(
    points: np.ndarray,
    normals: np.ndarray,
    double_sided: np.ndarray,
    lights: list[prims.LightPrim],
) -> np.ndarray:
    """Number of lights reaching each point (see module docstring)."""
    pos = np.array([lp.position for lp in lights], dtype=np.float64)
    axis = np.array([lp.direction for lp in lights], dtype=np.float64)
    rng2 = np.array([lp.range for lp in lights], dtype=np.float64) ** 2
    cone_cos = np.array(
        [
            math.cos(math.radians(min(lp.cone_angle, prims.NO_CONE_ANGLE_DEG)))
            if lp.has_cone
            else _NO_CONE_COS
            for lp in lights
        ]
    )
    front = np.array([lp.emission == prims.EMIT_COSINE for lp in lights])
    ext = np.array([area_half_extent(lp) for lp in lights], dtype=np.float64)
    out = np.zeros(len(points), dtype=np.int64)
    for s in range(0, len(points), _CHUNK):
        p = points[s : s + _CHUNK, None, :]
        d = p - pos[None]  # light -> point
        dist2 = np.einsum("nlk,nlk->nl", d, d)
        ok = dist2 < rng2[None]
        inv = 1.0 / np.sqrt(np.maximum(dist2, 1e-18))
        cos_axis = np.einsum("nlk,lk->nl", d, axis) * inv
        ok &= cos_axis >= cone_cos[None]
        ok &= ~front[None] | (cos_axis > 0.0)
        facing = -np.einsum("nlk,nk->nl", d, normals[s : s + _CHUNK])
        ok &= np.where(
            double_sided[s : s + _CHUNK, None],
            (facing != 0.0) | (ext[None] > 0.0),
            facing > -ext[None],
        )
        out[s : s + _CHUNK] = ok.sum(axis=1)
    return out


def check_overlap(stage: Usd.Stage) -> list[Finding]:
    ana = analysis_for(stage)
    lights = [r.light for r in ana.local_lights() if r.light.enabled]
    limit = limits.VALIDATE_STB_OVERLAP_MAX
    if len(lights) <= limit:
        return []
    smp = sample_surface(ana, limits.VALIDATE_OVERLAP_SAMPLES)
    if smp is None:
        return []
    pts, nrm, ds, mesh_of = smp
    counts = overlap_counts(pts, nrm, ds, lights)
    stage_from_render = np.linalg.inv(ana.render_from_stage)
    out: list[Finding] = []
    for mi in np.unique(mesh_of[counts > limit]):
        sel = np.nonzero(mesh_of == mi)[0]
        j = sel[np.argmax(counts[sel])]
        frac = float(np.mean(counts[sel] > limit))
        p = np.r_[pts[j], 1.0] @ stage_from_render
        out.append(
            finding(
                "stb_overlap",
                ana.meshes[mi].path,
                f"up to {int(counts[j])} lights overlap at ({p[0]:.3g}, {p[1]:.3g}, {p[2]:.3g}) "
                f"(stage units) on this mesh; {frac:.0%} of its sampled surface exceeds the "
                f"{limit}-slot big tile",
            )
        )
    return out
