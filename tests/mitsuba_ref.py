"""The Mitsuba 3 comparison (issue 20) lives in ``stb_hydra.metrics.mitsuba_truth`` (``stb
tradeoff`` uses it too); this name is kept for the tests and tools/area_lights.py.
Importing it without the ``mitsuba`` wheel raises ImportError."""

from stb_hydra.metrics.mitsuba_truth import *  # noqa: F403
from stb_hydra.metrics.mitsuba_truth import bsdf, compare, edge_mask, luminance  # noqa: F401
