"""Static lighting baked into lightmaps (``stb bake``; docs/BAKE.md).

:mod:`.unwrap` (xatlas charts per mesh, cached by content), :mod:`.gpu` (the bake as
one engine frame with a lightmap-space pass), :mod:`.baker` (orchestration, EXR and
USD output). The runtime side is ``renderer/tasks/lightmap.py``.
"""

from __future__ import annotations

from .baker import BakeReport, bake_stage, light_fingerprint

__all__ = ["BakeReport", "bake_stage", "light_fingerprint"]
