#!/usr/bin/env python3
"""Fit the linearly transformed cosines (LTC, Heitz, Dupuy, Hill & Neubelt 2016) of our
GGX specular lobe and write them as ``stb_hydra/data/ltc_ggx.npy`` (issue 20).

The lobe is exactly ``shaders/common/brdf.glsl``'s: GGX D x height-correlated Smith
visibility x cos, Fresnel 1 (Fresnel is split out below). For each table entry
(view angle, roughness) the fit finds the matrix M such that the clamped cosine
``D_o(w) = max(w.z, 0) / pi`` transformed by M,
``D(w) = D_o(Minv w / |Minv w|) |det Minv| / |Minv w|^3``, is closest to the
normalised lobe ``rho(w) / n``. Shading frame: N = +z, V = (sin t, 0, cos t).

* ``M = R [[a, 0, b], [0, c, 0], [d, 0, 1]]``: ``R`` the frame whose +z is the lobe's
  mean direction (in the plane of V and N), 4 free parameters -- all a matrix symmetric
  about the plane of incidence (isotropic BRDF) has, up to scale (3 parameters, d = 0,
  left 7-10x the error at roughness 0.7);
* error: ``E[|rho/n - D|^3 / (pdf_brdf + pdf_ltc)]`` over a stratified 32 x 32 set of
  samples drawn from each of the two distributions (multiple importance sampling of
  both, so neither the lobe's peak nor the fitted cosine's tails go unseen);
* minimised with Nelder-Mead, every table entry at once (numpy, batched), started from
  ``a = c = alpha`` (the GGX lobe at normal incidence is close to that), b = d = 0, in
  the frame of the mean direction.

Table (``float32``, shape ``(2, NT, NA, 4)``):
  [0, i, j] = Minv / Minv[1][1] as (m00, m02, m20, m22) (row, column), the matrix applied
              to directions in the shading frame (x towards V, z the normal);
  [1, i, j] = (n, f, 0, 0): n = the lobe's integral (directional albedo with F = 1),
              f = the integral of the lobe x (1 - V.H)^5, so Schlick's Fresnel gives
              ``f0 (n - f) + f``.
Rows i: ``sqrt(1 - cos t)`` = i / (NT - 1); columns j: ``sqrt(alpha)`` from
``sqrt(ALPHA_MIN)`` to 1 in NA equal steps (alpha = roughness^2, clamped as brdf.glsl
clamps it: ``limits.GGX_ALPHA_MIN``).

Usage: ``python tools/fit_ltc.py [--size 64] [--check]`` (deterministic; ``--check``
fits again and compares with the shipped file). ``--report`` prints the fit's accuracy
against the exact lobe: integrals of both over the spherical caps around the peak, and
the pointwise error at the peak direction.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

OUT = Path(__file__).resolve().parents[1] / "stb_hydra" / "data" / "ltc_ggx.npy"
ALPHA_MIN = 0.002  # brdf.glsl / gbuffer.glsl: alpha = max(roughness^2, 0.002)
COS_MIN = 1e-4  # brdf.glsl clamps N.V here


def _grid(n: int) -> tuple[np.ndarray, np.ndarray]:
    u = (np.arange(n) + 0.5) / n
    u1, u2 = np.meshgrid(u, u, indexing="ij")
    return u1.ravel(), u2.ravel()


def ggx_d(noh: np.ndarray, a2: np.ndarray) -> np.ndarray:
    """GGX normal distribution D(N.H) for alpha^2 ``a2``."""
    d = noh * noh * (a2 - 1.0) + 1.0
    return a2 / (math.pi * d * d)


def ggx_cos(noh: np.ndarray, nov: np.ndarray, nol: np.ndarray, a2: np.ndarray) -> np.ndarray:
    """brdf.glsl's GGX specular x cos with F = 1 from the cosines: D x height-correlated
    Smith visibility x N.L (0 below the horizon). ``nov`` already clamped to COS_MIN."""
    nl = np.maximum(nol, 0.0)
    gv = nl * np.sqrt(nov * nov * (1.0 - a2) + a2)
    gl = nov * np.sqrt(nl * nl * (1.0 - a2) + a2)
    return np.where(nol > 0.0, ggx_d(noh, a2) * 0.5 / np.maximum(gv + gl, 1e-8) * nl, 0.0)


def lobe(V: np.ndarray, L: np.ndarray, a: np.ndarray) -> np.ndarray:
    """brdf.glsl's GGX specular x cos with F = 1. V (B, 3), L (B, S, 3), a (B,)."""
    nov = np.maximum(V[:, None, 2], COS_MIN)
    H = V[:, None, :] + L
    H = H / np.maximum(np.linalg.norm(H, axis=-1, keepdims=True), 1e-20)
    noh = np.maximum(H[..., 2], 0.0)
    return ggx_cos(noh, nov, L[..., 2], (a * a)[:, None])


def sample_lobe(V: np.ndarray, a: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Directions L (B, n^2, 3) from GGX half vectors (stratified) and their pdf."""
    u1, u2 = _grid(n)
    a2 = (a * a)[:, None]
    ct = np.sqrt((1.0 - u1) / (1.0 + (a2 - 1.0) * u1))
    st = np.sqrt(np.maximum(1.0 - ct * ct, 0.0))
    ph = 2.0 * math.pi * u2
    H = np.stack([st * np.cos(ph), st * np.sin(ph), ct], -1)
    voh = (V[:, None, :] * H).sum(-1)
    L = 2.0 * voh[..., None] * H - V[:, None, :]
    pdf = ggx_d(ct, a2) * ct / np.maximum(4.0 * np.abs(voh), 1e-12)
    return L, pdf


def moments(V: np.ndarray, a: np.ndarray, n: int = 128) -> tuple[np.ndarray, ...]:
    """(n, f, mean direction (B, 3)) of each lobe, by lobe importance sampling."""
    out_n, out_f, out_d = [], [], []
    for i in range(0, len(a), 64):
        Vb, ab = V[i : i + 64], a[i : i + 64]
        L, pdf = sample_lobe(Vb, ab, n)
        w = np.where(pdf > 0, lobe(Vb, L, ab) / np.maximum(pdf, 1e-30), 0.0)
        H = Vb[:, None, :] + L
        H = H / np.maximum(np.linalg.norm(H, axis=-1, keepdims=True), 1e-20)
        voh = np.clip((Vb[:, None, :] * H).sum(-1), 0.0, 1.0)
        out_n.append(w.mean(-1))
        out_f.append((w * (1.0 - voh) ** 5).mean(-1))
        out_d.append((w[..., None] * L).mean(1))
    d = np.concatenate(out_d)
    d[:, 1] = 0.0
    d = d / np.linalg.norm(d, axis=-1, keepdims=True)
    return np.concatenate(out_n), np.concatenate(out_f), d


def frames(z: np.ndarray) -> np.ndarray:
    """R (B, 3, 3) with columns X, Y, Z: Z the mean direction (y = 0), Y = +y."""
    Y = np.broadcast_to(np.array([0.0, 1.0, 0.0]), z.shape)
    X = np.cross(Y, z)
    return np.stack([X, Y, z], -1)


def matrix(R: np.ndarray, p: np.ndarray) -> np.ndarray:
    """M (B, 3, 3) = R [[a, 0, b], [0, c, 0], [d, 0, 1]], p = (log a, log c, b, d)."""
    B = len(p)
    S = np.zeros((B, 3, 3))
    S[:, 0, 0] = np.exp(p[:, 0])
    S[:, 1, 1] = np.exp(p[:, 1])
    S[:, 0, 2] = p[:, 2]
    S[:, 2, 0] = p[:, 3]
    S[:, 2, 2] = 1.0
    return R @ S


def ltc_eval(Minv: np.ndarray, det_inv: np.ndarray, L: np.ndarray) -> np.ndarray:
    """The normalised LTC density (B, S) at directions L (B, S, 3)."""
    Lo = np.einsum("bij,bsj->bsi", Minv, L)
    ln = np.linalg.norm(Lo, axis=-1)
    return np.maximum(Lo[..., 2] / ln, 0.0) / math.pi * np.abs(det_inv)[:, None] / ln**3


def _ltc_xz(m: np.ndarray, x: np.ndarray, y: np.ndarray, z: np.ndarray) -> np.ndarray:
    """ltc_eval for matrices of the form [[m0, 0, m1], [0, m2, 0], [m3, 0, m4]] (m (B, 5)),
    directions as components (B, S) each."""
    m0, m1, m2, m3, m4 = (m[:, k : k + 1] for k in range(5))
    ox, oy, oz = m0 * x + m1 * z, m2 * y, m3 * x + m4 * z
    ln2 = ox * ox + oy * oy + oz * oz
    det = np.abs(m2 * (m0 * m4 - m1 * m3))
    return np.maximum(oz, 0.0) * det / (math.pi * ln2 * ln2)


def _lobe_xyz(V: np.ndarray, x: np.ndarray, y: np.ndarray, z: np.ndarray, a: np.ndarray):
    """(lobe (B, S), pdf of lobe sampling (B, S)) for directions as components."""
    vx, vz = V[:, 0:1], np.maximum(V[:, 2:3], COS_MIN)
    hx, hy, hz = vx + x, y, vz + z
    hn = np.sqrt(np.maximum(hx * hx + hy * hy + hz * hz, 1e-40))
    noh = np.maximum(hz / hn, 0.0)
    voh = np.abs((vx * hx + vz * hz) / hn)
    a2 = (a * a)[:, None]
    f = ggx_cos(noh, vz, z, a2)
    return f, ggx_d(noh, a2) * noh / np.maximum(4.0 * voh, 1e-12)


class Problem:
    """The fitting error of every table entry (rows of the batch)."""

    def __init__(self, V: np.ndarray, a: np.ndarray, nrm: np.ndarray, R: np.ndarray, n: int):
        self.V, self.a, self.nrm, self.R = V, a, nrm, R
        Lb, pb = sample_lobe(V, a, n)  # fixed: the lobe does not change
        self.Lb = (Lb[..., 0], Lb[..., 1], Lb[..., 2])
        self.pb = pb
        self.rb = lobe(V, Lb, a) / nrm[:, None]
        u1, u2 = _grid(n)
        r, ph = np.sqrt(u1), 2.0 * math.pi * u2
        self.cs = (r * np.cos(ph), r * np.sin(ph), np.sqrt(1.0 - u1))

    def error(self, p: np.ndarray, rows: np.ndarray) -> np.ndarray:
        M = matrix(self.R[rows], p)
        Minv = np.linalg.inv(M)
        mi = np.stack(
            [Minv[:, 0, 0], Minv[:, 0, 2], Minv[:, 1, 1], Minv[:, 2, 0], Minv[:, 2, 2]], -1
        )
        V, a, nrm = self.V[rows], self.a[rows], self.nrm[rows]
        # lobe samples
        x, y, z = (c[rows] for c in self.Lb)
        pb, rb = self.pb[rows], self.rb[rows]
        db = _ltc_xz(mi, x, y, z)
        e = np.abs(rb - db) ** 3 / np.maximum(pb + db, 1e-30)
        # LTC samples (cosine samples through M)
        cx, cy, cz = self.cs
        m = M
        lx = m[:, 0, 0:1] * cx + m[:, 0, 2:3] * cz
        ly = m[:, 1, 1:2] * cy
        lz = m[:, 2, 0:1] * cx + m[:, 2, 2:3] * cz
        ln = np.sqrt(lx * lx + ly * ly + lz * lz)
        lx, ly, lz = lx / ln, ly / ln, lz / ln
        dl = _ltc_xz(mi, lx, ly, lz)
        rl, pl = _lobe_xyz(V, lx, ly, lz, a)
        e2 = np.abs(rl / nrm[:, None] - dl) ** 3 / np.maximum(pl + dl, 1e-30)
        return (e.mean(-1) + e2.mean(-1)) / 2.0


def nelder_mead(prob: Problem, x0: np.ndarray, step: np.ndarray, iters: int) -> np.ndarray:
    """Batched Nelder-Mead (standard coefficients 1, 2, 0.5, 0.5): each row its own
    simplex; only the rows that need an expansion/contraction/shrink evaluate it."""
    B, d = x0.shape
    rows = np.arange(B)
    S = np.repeat(x0[:, None, :], d + 1, axis=1)
    for k in range(d):
        S[:, k + 1, k] += step[k]
    F = np.stack([prob.error(S[:, k], rows) for k in range(d + 1)], 1)
    for _ in range(iters):
        o = np.argsort(F, 1)
        S = np.take_along_axis(S, o[..., None], 1)
        F = np.take_along_axis(F, o, 1)
        c = S[:, :-1].mean(1)
        w = S[:, -1]
        xr = 2.0 * c - w
        fr = prob.error(xr, rows)
        new_x, new_f = xr.copy(), fr.copy()
        exp = fr < F[:, 0]
        if exp.any():
            r = rows[exp]
            xe = 3.0 * c[r] - 2.0 * w[r]
            fe = prob.error(xe, r)
            better = fe < fr[r]
            new_x[r[better]] = xe[better]
            new_f[r[better]] = fe[better]
        con = fr >= F[:, -2]
        shrink = np.zeros(B, dtype=bool)
        if con.any():
            r = rows[con]
            outside = fr[r] < F[r, -1]
            xc = np.where(outside[:, None], c[r] + 0.5 * (xr[r] - c[r]), c[r] + 0.5 * (w[r] - c[r]))
            fc = prob.error(xc, r)
            ok = fc < np.minimum(fr[r], F[r, -1])
            new_x[r[ok]] = xc[ok]
            new_f[r[ok]] = fc[ok]
            shrink[r[~ok]] = True
        keep = ~shrink
        S[keep, -1] = new_x[keep]
        F[keep, -1] = new_f[keep]
        if shrink.any():
            r = rows[shrink]
            S[r, 1:] = S[r, :1] + 0.5 * (S[r, 1:] - S[r, :1])
            for k in range(1, d + 1):
                F[r, k] = prob.error(S[r, k], r)
    return S[np.arange(B), np.argmin(F, 1)]


def entries(size: int) -> tuple[np.ndarray, np.ndarray]:
    """(V (NT*NA, 3), alpha (NT*NA,)) in table order (row = view angle)."""
    t = np.arange(size) / (size - 1)
    cos_t = np.maximum(1.0 - t * t, COS_MIN)
    sa = np.sqrt(ALPHA_MIN) + (1.0 - np.sqrt(ALPHA_MIN)) * np.arange(size) / (size - 1)
    CT, SA = np.meshgrid(cos_t, sa, indexing="ij")
    ct = CT.ravel()
    V = np.stack([np.sqrt(1.0 - ct * ct), np.zeros_like(ct), ct], -1)
    return V, (SA * SA).ravel()


def fit(size: int, samples: int = 32, iters: int = 400, verbose: bool = True) -> np.ndarray:
    V, a = entries(size)
    nrm, fres, mean_dir = moments(V, a)
    R = frames(mean_dir)
    out = np.zeros((2, size * size, 4))
    t0 = time.perf_counter()
    chunk = 256
    for i in range(0, len(a), chunk):
        s = slice(i, i + chunk)
        prob = Problem(V[s], a[s], nrm[s], R[s], samples)
        z = np.zeros(len(a[s]))
        x0 = np.stack([np.log(a[s]), np.log(a[s]), z, z], -1)
        p = nelder_mead(prob, x0, np.array([0.3, 0.3, 0.1, 0.1]), iters)
        Minv = np.linalg.inv(matrix(R[s], p))
        Minv = Minv / Minv[:, 1:2, 1:2]
        out[0, s] = np.stack([Minv[:, 0, 0], Minv[:, 0, 2], Minv[:, 2, 0], Minv[:, 2, 2]], -1)
        out[1, s, 0], out[1, s, 1] = nrm[s], fres[s]
        if verbose:
            print(f"  {i + len(a[s])}/{len(a)} entries ({time.perf_counter() - t0:.0f} s)")
            sys.stdout.flush()
    return out.reshape(2, size, size, 4).astype(np.float32)


def minv_of(table: np.ndarray) -> np.ndarray:
    """(NT*NA, 3, 3) matrices from the table's first layer."""
    t = table[0].reshape(-1, 4).astype(np.float64)
    M = np.zeros((len(t), 3, 3))
    M[:, 0, 0], M[:, 0, 2], M[:, 2, 0], M[:, 2, 2] = t[:, 0], t[:, 1], t[:, 2], t[:, 3]
    M[:, 1, 1] = 1.0
    return M


def report(table: np.ndarray) -> None:
    """Accuracy of the fit at every 8th entry: relative error of the lobe's integral over
    the cap of half angle 5 / 15 degrees around its peak (what a light of that size
    reflects), and at the peak direction (a tiny light)."""
    size = table.shape[1]
    V, a = entries(size)
    Minv = minv_of(table)
    det = np.linalg.det(Minv)
    nrm = table[1].reshape(-1, 4)[:, 0].astype(np.float64)
    sel = np.array(
        [
            i * size + j
            for i in range(0, size, max(1, size // 8))
            for j in range(0, size, max(1, size // 8))
        ]
    )
    L, _ = sample_lobe(V[sel], a[sel], 8)
    rho = lobe(V[sel], L, a[sel])
    peak = L[np.arange(len(sel)), np.argmax(rho, 1)]
    exact = lobe(V[sel], peak[:, None], a[sel])[:, 0]
    fitted = nrm[sel] * ltc_eval(Minv[sel], det[sel], peak[:, None])[:, 0]
    rel = fitted / np.maximum(exact, 1e-30) - 1.0
    print(
        f"peak direction, n D_ltc / rho - 1: median {np.median(np.abs(rel)):.3f}, "
        f"max |.| {np.abs(rel).max():.3f}"
    )
    for half in (5.0, 15.0):
        u1, u2 = _grid(48)
        ca = math.cos(math.radians(half))
        ct = 1.0 - u1 * (1.0 - ca)
        st = np.sqrt(1.0 - ct * ct)
        ph = 2 * math.pi * u2
        loc = np.stack([st * np.cos(ph), st * np.sin(ph), ct], -1)
        z = peak
        X = np.cross(np.array([0.0, 1.0, 0.0]), z)
        X /= np.linalg.norm(X, axis=-1, keepdims=True)
        Y = np.cross(z, X)
        W = (
            loc[None, :, 0:1] * X[:, None]
            + loc[None, :, 1:2] * Y[:, None]
            + loc[None, :, 2:3] * z[:, None]
        )
        omega = 2 * math.pi * (1.0 - ca)
        e = lobe(V[sel], W, a[sel]).mean(-1) * omega
        f = nrm[sel] * ltc_eval(Minv[sel], det[sel], W).mean(-1) * omega
        r = np.abs(f / np.maximum(e, 1e-30) - 1.0)
        print(
            f"cap {half:.0f} deg around the peak: median {np.median(r):.3f}, p95 "
            f"{np.percentile(r, 95):.3f}, max {r.max():.3f}"
        )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--out", default=str(OUT))
    ap.add_argument("--check", action="store_true", help="fit and compare with --out")
    ap.add_argument("--report", action="store_true", help="only report on --out's fit")
    args = ap.parse_args(argv)
    if args.report:
        report(np.load(args.out))
        return 0
    t = time.perf_counter()
    table = fit(args.size)
    print(f"fitted {args.size} x {args.size} in {time.perf_counter() - t:.0f} s")
    if args.check:
        old = np.load(args.out)
        diff = float(np.abs(old - table).max())
        print(f"max |difference| from {args.out}: {diff:.3g}")
        return 0 if diff < 1e-4 else 1
    np.save(args.out, table)
    report(table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
