"""Shadow-capture cost model: milliseconds from texels, render passes and triangles (no GL).

A capture's cost is predicted as ``c_texel * texels + c_pass * passes + c_tri * triangles``
(``ShadowCostModel.predict``; coefficients in ms per Mtexel, ms per pass and ms per
Mtriangle, see ``COEFF_UNITS``), where *texels* are the depth texels rendered (6 faces of
an omni map), *passes* the render passes (faces + the copy) and *triangles* the
triangles submitted after culling (each face counts its own).

Two modes:

* **fixed** (``ShadowCostModel(coeffs, fixed=True)``): the coefficients never change and
  nothing reads a clock -- deterministic scheduling for tests and reproducible runs.
* **measured** (default): the coefficients start at a prior (``limits`` defaults, or a
  start-up calibration of the GL capturer) and are re-fitted from wall-clock samples
  (``observe``: the summed features of one frame's captures and the milliseconds they
  took, measured with ``ctx.finish()`` around them). The fit is a ridge regression
  toward the prior over the last ``SHADOW_COST_FIT_WINDOW`` frames (so a window of
  frames that all look alike cannot send a coefficient anywhere), coefficients >= 0.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from stb_hydra.limits import (
    SHADOW_COST_COEFFS_DEFAULT,
    SHADOW_COST_FIT_WINDOW,
    SHADOW_COST_PRIOR_WEIGHT,
)

__all__ = ["COEFF_UNITS", "ShadowCostModel", "features"]

#: Feature scales: coefficients are ms per (Mtexel, pass, Mtriangle).
_SCALE = np.array([1.0e-6, 1.0, 1.0e-6])
COEFF_UNITS = ("ms/Mtexel", "ms/pass", "ms/Mtriangle")


def features(texels: float, passes: float, triangles: float) -> np.ndarray:
    """Scaled feature vector (Mtexel, passes, Mtriangles) of one capture or a sum."""
    return np.array([texels, passes, triangles], dtype=np.float64) * _SCALE


class ShadowCostModel:
    """Linear capture-time model (module doc)."""

    def __init__(
        self,
        coeffs: tuple[float, float, float] | None = None,
        *,
        fixed: bool = False,
        window: int = SHADOW_COST_FIT_WINDOW,
        prior_weight: float = SHADOW_COST_PRIOR_WEIGHT,
    ) -> None:
        c = np.asarray(SHADOW_COST_COEFFS_DEFAULT if coeffs is None else coeffs, np.float64)
        if c.shape != (3,) or not np.all(np.isfinite(c)) or np.any(c < 0):
            raise ValueError(
                f"shadow cost coefficients must be 3 finite numbers >= 0, got {coeffs}"
            )
        self.fixed = bool(fixed)
        self.prior = c.copy()
        self.coeffs = c.copy()
        self.prior_weight = float(prior_weight)
        self._samples: deque[tuple[np.ndarray, float]] = deque(maxlen=int(window))
        self.observed = 0

    def predict(self, texels: float, passes: float, triangles: float) -> float:
        """Predicted milliseconds of one capture (or of a sum of captures)."""
        return float(features(texels, passes, triangles) @ self.coeffs)

    def set_prior(self, coeffs: np.ndarray | tuple[float, float, float]) -> None:
        """Replace the prior (start-up calibration) and restart the fit from it."""
        c = np.maximum(np.asarray(coeffs, np.float64), 0.0)
        if c.shape != (3,) or not np.all(np.isfinite(c)):
            raise ValueError(f"bad calibration {coeffs}")
        self.prior = c.copy()
        if not self.fixed:
            self.coeffs = c.copy()
            self._samples.clear()

    def observe(self, texels: float, passes: float, triangles: float, ms: float) -> None:
        """One frame's captures (summed features) took ``ms`` wall-clock milliseconds:
        re-fit (a no-op in fixed mode, or for an empty / non-finite sample)."""
        if self.fixed or passes <= 0 or not (ms >= 0.0 and np.isfinite(ms)):
            return
        self._samples.append((features(texels, passes, triangles), float(ms)))
        self.observed += 1
        self._refit()

    def _refit(self) -> None:
        a = np.array([s[0] for s in self._samples])
        t = np.array([s[1] for s in self._samples])
        # Ridge toward the prior, each coefficient's penalty scaled by the prior's
        # typical contribution (so units do not matter): the weight is what one frame's
        # sample counts against the prior.
        typical = np.maximum(np.median(np.abs(a), axis=0), 1e-9)
        lam = self.prior_weight * np.diag(typical**2)
        c = np.linalg.solve(a.T @ a + lam, a.T @ t + lam @ self.prior)
        if np.all(np.isfinite(c)):
            self.coeffs = np.maximum(c, 0.0)
