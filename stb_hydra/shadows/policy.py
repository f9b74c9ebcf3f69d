"""Shadow-map resolution policy: projected size -> power-of-two side, with hysteresis.

Vectorised over lights (numpy arrays in, arrays out; no per-light Python loop).

Heuristic: the light's influence sphere (radius ``range_m``) seen from the camera at
``distance_m`` covers a diameter of ``viewport_height_px * r / (d * tan(fov_y / 2))``
pixels (small-angle projection; d is floored at r, i.e. a camera inside the sphere
sees it fill the screen). The continuous target side is that diameter times
``SHADOW_TEXELS_PER_PIXEL`` times ``sqrt(flux / SHADOW_REFERENCE_FLUX_LM)`` (clamped
to ``SHADOW_FLUX_SCALE_RANGE``), in texels. The renderer passes the flux times the
camera's exposure scale (the flux as the camera sees it), so sizes are scale-free.

Sizes: nearest power of two in log2 (``2^floor(log2 t + 0.5)``) clamped to
[min_size, max_size]; a light keeps its current size while log2(target) stays within
``0.5 + hysteresis`` octaves of log2(current).

Footprint rule (issue 33 item 5, ``combine_targets``): the renderer can also measure,
on the G-buffer, the side each light's receivers need on screen
(``renderer/tasks/shadow_footprint.py``, in texels per texel/px) and size maps from
that ("footprint") or from the larger of the two ("max"); lights it did not measure
(NaN) keep the flux rule.

Lift rule (``"lift"``, ``DEFAULT_RESOLUTION``): the flux rule's sides, except
for the lights whose measured footprint asks for more than ``SHADOW_LIFT_MIN_RATIO``
times the flux target (the flux rule under-sizes them for what the camera sees: a
small light beside the camera whose shadow falls at the viewer's feet); those get the
footprint side. Lifts are granted highest ratio first while the atlas texels of the
resulting power-of-two sides stay within ``SHADOW_LIFT_ATLAS_FRACTION`` of the atlas
(``lift_targets``), so a lift never pushes the atlas past its budget; the flux
rule's own sides are never reduced.

Out-of-view lights (influence sphere outside the frustum, caller's test): keep their
current size (no re-render churn when the camera turns; a light with no map yet gets
``min_size``) and get their priority scaled by ``SHADOW_OUT_OF_VIEW_PRIORITY_SCALE``,
so the allocator downgrades them first and the scheduler refreshes them last.
"""

from __future__ import annotations

import numpy as np

from stb_hydra import limits
from stb_hydra.limits import (
    SHADOW_FLUX_SCALE_RANGE,
    SHADOW_FOOTPRINT_TEXELS_PER_PIXEL,
    SHADOW_MAP_MAX_SIZE,
    SHADOW_MAP_MIN_SIZE,
    SHADOW_OUT_OF_VIEW_PRIORITY_SCALE,
    SHADOW_REFERENCE_FLUX_LM,
    SHADOW_RES_HYSTERESIS_OCTAVES,
    SHADOW_TEXELS_PER_PIXEL,
)

__all__ = [
    "DEFAULT_RESOLUTION",
    "RESOLUTION_MODES",
    "apply_hysteresis",
    "choose_resolutions",
    "combine_targets",
    "footprint_texels",
    "lift_targets",
    "light_priorities",
    "sizes_from_target",
    "target_texels",
]

#: Floor (texels) of the continuous target so log2 stays finite.
_TARGET_FLOOR = 1.0e-3
#: ``RenderSettings.shadow_resolution`` values.
RESOLUTION_MODES = ("lift", "flux", "footprint", "max")
#: The default of ``RenderSettings.shadow_resolution``, the atlas task, the scheduler and
#: ``stb bench --shadow-resolution``: "lift" (issue 33 item 5; it changed 12 of the stored
#: regression images, lights64 and ies12, whose under-sized lights it lifts:
#: docs/PERFORMANCE.md, "lift").
DEFAULT_RESOLUTION = "lift"


def target_texels(
    distance_m: np.ndarray,
    flux_lm: np.ndarray,
    range_m: np.ndarray,
    viewport_height_px: float,
    fov_y_rad: float,
    texels_per_pixel: float = SHADOW_TEXELS_PER_PIXEL,
) -> np.ndarray:
    """Continuous (unclamped) map side each light deserves, in texels (float64).
    ``texels_per_pixel`` is the global density knob (e.g. lower it under atlas pressure)."""
    d = np.asarray(distance_m, dtype=np.float64)
    r = np.maximum(np.asarray(range_m, dtype=np.float64), 0.0)
    flux = np.maximum(np.asarray(flux_lm, dtype=np.float64), 0.0)
    d_eff = np.maximum(d, np.maximum(r, 1.0e-6))
    diameter_px = viewport_height_px * r / (d_eff * np.tan(0.5 * fov_y_rad))
    lo, hi = SHADOW_FLUX_SCALE_RANGE
    flux_scale = np.clip(np.sqrt(flux / SHADOW_REFERENCE_FLUX_LM), lo, hi)
    return np.maximum(diameter_px * texels_per_pixel * flux_scale, _TARGET_FLOOR)


def footprint_texels(
    need: np.ndarray, texels_per_pixel: float = SHADOW_FOOTPRINT_TEXELS_PER_PIXEL
) -> np.ndarray:
    """Continuous map side (texels) from the footprint pass's measure ``need`` (the
    side at 1 texel per screen pixel where the light's receivers are seen; NaN: not
    measured, kept NaN)."""
    return np.asarray(need, dtype=np.float64) * texels_per_pixel


def combine_targets(
    flux_target: np.ndarray,
    footprint: np.ndarray | None,
    mode: str,
    budget_texels: float | None = None,
    min_size: int = SHADOW_MAP_MIN_SIZE,
    max_size: int = SHADOW_MAP_MAX_SIZE,
    current_sizes: np.ndarray | None = None,
) -> np.ndarray:
    """The target side (texels) per light under ``mode`` (``RESOLUTION_MODES``): the
    flux rule, the footprint (NaN where not measured: the flux rule), the larger of
    both, or ``lift_targets`` (``budget_texels``: the atlas's texels, None: no cap;
    ``current_sizes``: the sides now, for the lift's hysteresis)."""
    if mode not in RESOLUTION_MODES:
        raise ValueError(f"resolution mode {mode!r} not in {RESOLUTION_MODES}")
    ft = np.asarray(flux_target, dtype=np.float64)
    if mode == "flux" or footprint is None:
        return ft
    fp = np.asarray(footprint, dtype=np.float64)
    if mode == "lift":
        return lift_targets(
            ft,
            fp,
            budget_texels,
            min_size=min_size,
            max_size=max_size,
            current_sizes=current_sizes,
        )
    got = np.where(np.isnan(fp), ft, fp)
    out = got if mode == "footprint" else np.maximum(ft, got)
    return np.maximum(out, _TARGET_FLOOR)


def lift_targets(
    flux_target: np.ndarray,
    footprint: np.ndarray,
    budget_texels: float | None,
    *,
    min_ratio: float | None = None,
    atlas_fraction: float | None = None,
    min_size: int = SHADOW_MAP_MIN_SIZE,
    max_size: int = SHADOW_MAP_MAX_SIZE,
    current_sizes: np.ndarray | None = None,
) -> np.ndarray:
    """Continuous sides (texels): ``flux_target``, except where the measured
    ``footprint`` (texels; NaN: not measured) exceeds ``min_ratio`` x the flux target,
    which get the footprint. Lifts are granted in decreasing footprint / flux ratio
    while the texels of all nominal power-of-two sides (``sizes_from_target`` without
    history, clamped to [min_size, max_size]) stay <= ``atlas_fraction`` x
    ``budget_texels``; a lift that would pass it is dropped (the flux target kept),
    so the lifts never take the atlas past the budget (the flux sides alone may).
    None: ``limits.SHADOW_LIFT_MIN_RATIO`` / ``SHADOW_LIFT_ATLAS_FRACTION`` (read at
    call time, so tools can vary them). Hysteresis: a light whose ``current_sizes``
    side is more than one octave above its flux side (lifted now) stays lifted while
    the ratio exceeds ``min_ratio / 2^(0.5 + SHADOW_RES_HYSTERESIS_OCTAVES)``, so a
    ratio that wanders around ``min_ratio`` does not flip the map by 2+ octaves at
    every measurement."""
    min_ratio = limits.SHADOW_LIFT_MIN_RATIO if min_ratio is None else min_ratio
    if atlas_fraction is None:
        atlas_fraction = limits.SHADOW_LIFT_ATLAS_FRACTION
    ft = np.asarray(flux_target, dtype=np.float64)
    fp = np.asarray(footprint, dtype=np.float64)
    ratio = np.where(np.isnan(fp), 0.0, fp) / np.maximum(ft, _TARGET_FLOOR)
    zero = np.zeros(len(ft), dtype=np.int64)
    flux_side = apply_hysteresis(ft, zero, min_size, max_size)
    threshold = np.full(len(ft), float(min_ratio))
    if current_sizes is not None:
        lifted_now = np.asarray(current_sizes, dtype=np.int64) > 2 * flux_side
        keep = float(min_ratio) / 2.0 ** (0.5 + SHADOW_RES_HYSTERESIS_OCTAVES)
        threshold = np.where(lifted_now, keep, threshold)
    want = ratio > threshold
    if not want.any():
        return ft
    lifted = np.where(want, fp, ft)
    if budget_texels is None:
        return lifted
    base = flux_side.astype(np.float64) ** 2
    up = apply_hysteresis(lifted, zero, min_size, max_size).astype(np.float64) ** 2
    order = np.argsort(-np.where(want, ratio, -np.inf), kind="stable")
    extra = np.where(want, up - base, 0.0)[order]
    room = atlas_fraction * float(budget_texels) - float(base.sum())
    granted = np.zeros(len(ft), dtype=bool)
    granted[order] = want[order] & (np.cumsum(extra) <= room)
    return np.where(granted, lifted, ft)


def apply_hysteresis(
    target: np.ndarray,
    current_sizes: np.ndarray,
    min_size: int = SHADOW_MAP_MIN_SIZE,
    max_size: int = SHADOW_MAP_MAX_SIZE,
    hysteresis_octaves: float = SHADOW_RES_HYSTERESIS_OCTAVES,
) -> np.ndarray:
    """Power-of-two sides (int64) for continuous ``target`` texels.

    ``current_sizes`` 0 = no map yet. A current size in [min, max] is kept while
    |log2(clamped target) - log2(current)| <= 0.5 + hysteresis_octaves.
    """
    t = np.clip(np.asarray(target, dtype=np.float64), min_size, max_size)
    lt = np.log2(t)
    lo_e, hi_e = int(np.log2(min_size)), int(np.log2(max_size))
    nominal = np.left_shift(1, np.clip(np.floor(lt + 0.5), lo_e, hi_e).astype(np.int64))
    cur = np.asarray(current_sizes, dtype=np.int64)
    valid = (cur >= min_size) & (cur <= max_size) & ((cur & (cur - 1)) == 0)
    lc = np.log2(np.where(valid, cur, 1).astype(np.float64))
    keep = valid & (np.abs(lt - lc) <= 0.5 + hysteresis_octaves)
    return np.where(keep, cur, nominal)


def choose_resolutions(
    distance_m: np.ndarray,
    flux_lm: np.ndarray,
    range_m: np.ndarray,
    viewport_height_px: float,
    fov_y_rad: float,
    current_sizes: np.ndarray,
    in_view: np.ndarray | None = None,
    *,
    min_size: int = SHADOW_MAP_MIN_SIZE,
    max_size: int = SHADOW_MAP_MAX_SIZE,
    hysteresis_octaves: float = SHADOW_RES_HYSTERESIS_OCTAVES,
    texels_per_pixel: float = SHADOW_TEXELS_PER_PIXEL,
) -> np.ndarray:
    """Map side (texels, int64 power of two) per light; see module doc."""
    target = target_texels(
        distance_m, flux_lm, range_m, viewport_height_px, fov_y_rad, texels_per_pixel
    )
    return sizes_from_target(target, current_sizes, in_view, min_size, max_size, hysteresis_octaves)


def sizes_from_target(
    target: np.ndarray,
    current_sizes: np.ndarray,
    in_view: np.ndarray | None = None,
    min_size: int = SHADOW_MAP_MIN_SIZE,
    max_size: int = SHADOW_MAP_MAX_SIZE,
    hysteresis_octaves: float = SHADOW_RES_HYSTERESIS_OCTAVES,
) -> np.ndarray:
    """``apply_hysteresis`` plus the out-of-view rule: hold the current size (a light
    with no map yet, current 0, gets ``min_size``)."""
    sizes = apply_hysteresis(target, current_sizes, min_size, max_size, hysteresis_octaves)
    if in_view is None:
        return sizes
    cur = np.asarray(current_sizes, dtype=np.int64)
    hold = np.where(cur > 0, np.clip(cur, min_size, max_size), min_size)
    return np.where(np.asarray(in_view, dtype=bool), sizes, hold)


def light_priorities(target: np.ndarray, in_view: np.ndarray | None = None) -> np.ndarray:
    """Allocation / update priority per light: ``1 + log2(1 + target)`` (target = the
    continuous side in texels, not clamped, so lights past the max size still order),
    times ``SHADOW_OUT_OF_VIEW_PRIORITY_SCALE`` out of view.

    The allocator only uses the order; the scheduler serves dynamic maps at a rate
    proportional to priority, so the log keeps a light 1000x smaller on screen at
    ~1/10 of the refresh rate of the biggest instead of 1/1000 (no practical starvation).
    """
    p = 1.0 + np.log2(1.0 + np.maximum(np.asarray(target, dtype=np.float64), 0.0))
    if in_view is None:
        return p
    return np.where(np.asarray(in_view, dtype=bool), p, p * SHADOW_OUT_OF_VIEW_PRIORITY_SCALE)
