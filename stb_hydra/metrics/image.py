"""Image-quality metrics of the trade-off study (numpy; FLIP via ``flip-evaluator``).

* :func:`relmse` -- relative MSE against the reference in scene-linear radiance:
  ``mean over pixels and RGB of (x - r)^2 / (r^2 + eps)``, ``eps`` = 1e-2 by default
  (the usual denoising-literature form; eps keeps black pixels from dominating). A
  constant offset d on a constant reference c gives exactly ``d^2 / (c^2 + eps)``.
* :func:`flip_ldr` -- mean FLIP (Andersson et al. 2020) of display-referred images
  (sRGB-encoded values in [0, 1], e.g. through :func:`display_referred`).
* :func:`flip_hdr` -- mean HDR-FLIP of scene-linear (linear Rec.709) images: FLIP's
  own exposure bracketing instead of our display transform.
* :func:`temporal_instability` -- mean absolute frame-to-frame difference over a
  sequence of a static camera; :func:`temporal_excess` subtracts the reference's
  (zero for a deterministic reference, measured anyway).
* :func:`accumulated_windows` -- the displayed images of an A-frame accumulation
  (sliding means over A consecutive frames), the temporal model of the study.
* :func:`dropped_summary` -- per-frame dropped-light counts from ``frame.stats``.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence

import numpy as np

#: Default eps of relMSE (scene-linear, nits x camera exposure).
RELMSE_EPS = 1.0e-2


def _rgb(a: np.ndarray) -> np.ndarray:
    a = np.asarray(a, dtype=np.float64)
    if a.ndim >= 3 and a.shape[-1] == 4:
        a = a[..., :3]
    return a


def _check(test: np.ndarray, ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    t, r = _rgb(test), _rgb(ref)
    if t.shape != r.shape:
        raise ValueError(f"image shapes differ: {t.shape} vs {r.shape}")
    return t, r


def relmse(test: np.ndarray, ref: np.ndarray, eps: float = RELMSE_EPS) -> float:
    """Relative MSE of ``test`` against ``ref`` (scene-linear, alpha ignored)."""
    if eps <= 0:
        raise ValueError("relmse eps must be > 0")
    t, r = _check(test, ref)
    return float(np.mean((t - r) ** 2 / (r * r + eps)))


def relmse_map(test: np.ndarray, ref: np.ndarray, eps: float = RELMSE_EPS) -> np.ndarray:
    """Per-pixel relMSE (mean over RGB), for error images."""
    t, r = _check(test, ref)
    return np.mean((t - r) ** 2 / (r * r + eps), axis=-1)


def display_referred(linear: np.ndarray, pipeline=None) -> np.ndarray:
    """Scene-linear -> display-referred [0, 1] through the OCIO pipeline (default:
    the renderer's, i.e. the config's default display and view)."""
    if pipeline is None:
        pipeline = _default_pipeline()
    return pipeline.apply_cpu(np.ascontiguousarray(_rgb(linear), dtype=np.float32))


_PIPELINE = None


def _default_pipeline():
    global _PIPELINE
    if _PIPELINE is None:
        from ..color.ocio import ColorPipeline

        _PIPELINE = ColorPipeline()
    return _PIPELINE


def _flip():
    try:
        import flip_evaluator
    except ImportError as exc:  # pragma: no cover - dependency of the 'reference' extra
        raise RuntimeError(
            "FLIP needs the flip-evaluator package (pip install 'stb_hydra[reference]')"
        ) from exc
    return flip_evaluator


def flip_ldr(test_display: np.ndarray, ref_display: np.ndarray, ppd: float | None = None) -> float:
    """Mean LDR-FLIP of display-referred (sRGB-encoded, [0, 1]) images."""
    t, r = _check(test_display, ref_display)
    t = np.clip(t, 0.0, 1.0).astype(np.float32)
    r = np.clip(r, 0.0, 1.0).astype(np.float32)
    params = {} if ppd is None else {"ppd": float(ppd)}
    _m, mean, _p = _flip().evaluate(r, t, "LDR", applyMagma=False, parameters=params)
    return float(mean)


def flip_hdr(test_linear: np.ndarray, ref_linear: np.ndarray, ppd: float | None = None) -> float:
    """Mean HDR-FLIP of scene-linear images (negatives clipped, as FLIP requires)."""
    t, r = _check(test_linear, ref_linear)
    t = np.nan_to_num(np.maximum(t, 0.0)).astype(np.float32)
    r = np.nan_to_num(np.maximum(r, 0.0)).astype(np.float32)
    params = {} if ppd is None else {"ppd": float(ppd)}
    _m, mean, _p = _flip().evaluate(r, t, "HDR", applyMagma=False, parameters=params)
    return float(mean)


def temporal_instability(frames: Sequence[np.ndarray] | np.ndarray) -> float:
    """Mean |f_t - f_(t-1)| over consecutive frames, pixels and RGB (0 for < 2 frames)."""
    if len(frames) < 2:
        return 0.0
    total, count = 0.0, 0
    prev = _rgb(frames[0])
    for f in frames[1:]:
        cur = _rgb(f)
        if cur.shape != prev.shape:
            raise ValueError("frames differ in shape")
        total += float(np.abs(cur - prev).mean())
        count += 1
        prev = cur
    return total / count


def temporal_excess(frames, ref_frames) -> float:
    """Instability of ``frames`` minus the reference's (same static camera)."""
    return temporal_instability(frames) - temporal_instability(ref_frames)


def accumulated_windows(frames: Sequence[np.ndarray] | np.ndarray, a: int) -> np.ndarray:
    """(T - a + 1, ...) means of every a consecutive frames (a sliding accumulation)."""
    if a < 1:
        raise ValueError("accumulation must be >= 1")
    f = np.asarray(frames, dtype=np.float64)
    if len(f) < a:
        raise ValueError(f"need at least {a} frames, got {len(f)}")
    c = np.cumsum(f, axis=0)
    c = np.concatenate([np.zeros((1, *f.shape[1:])), c], axis=0)
    return (c[a:] - c[:-a]) / a


def dropped_summary(stats: Iterable[Mapping]) -> dict[str, float]:
    """Median / max of ``dropped_lights`` over frames (0 when never reported)."""
    v = [float(s.get("dropped_lights", 0)) for s in stats]
    if not v:
        return {"dropped_median": 0.0, "dropped_max": 0.0}
    return {"dropped_median": float(np.median(v)), "dropped_max": float(np.max(v))}
