"""Image-quality metrics (relMSE, FLIP, temporal instability) of the trade-off study."""

from .image import (
    RELMSE_EPS,
    accumulated_windows,
    display_referred,
    dropped_summary,
    flip_hdr,
    flip_ldr,
    relmse,
    relmse_map,
    temporal_excess,
    temporal_instability,
)

__all__ = [
    "RELMSE_EPS",
    "accumulated_windows",
    "display_referred",
    "dropped_summary",
    "flip_hdr",
    "flip_ldr",
    "relmse",
    "relmse_map",
    "temporal_excess",
    "temporal_instability",
]
