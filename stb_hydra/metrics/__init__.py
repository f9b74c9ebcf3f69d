"""Image-quality metrics of the trade-off study: relMSE, FLIP, temporal instability,
and what a person sees of noise (structured noise, HDR-FLIP at mid grey); per-frame
metrics of moving sequences (``sequence``: per-frame HDR-FLIP, instability over the
reference's own, ghosting)."""

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
from .sequence import frames_to_settle, instability_ratio, per_frame_flip, region_error
from .structure import (
    flip_hdr_midgrey,
    relative_error,
    spectral_structure,
    structured_noise,
)

__all__ = [
    "RELMSE_EPS",
    "accumulated_windows",
    "display_referred",
    "dropped_summary",
    "flip_hdr",
    "flip_hdr_midgrey",
    "flip_ldr",
    "frames_to_settle",
    "instability_ratio",
    "per_frame_flip",
    "region_error",
    "relative_error",
    "relmse",
    "relmse_map",
    "spectral_structure",
    "structured_noise",
    "temporal_excess",
    "temporal_instability",
]
