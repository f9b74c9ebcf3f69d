"""Shadow atlas: allocator, resolution policy and update scheduler (GL-free).

Capture parameters and the map record layout are here too (``capture``); the GL
capture / sampling code (``renderer/shadow_capture.py``, render task
``renderer/tasks/shadow_atlas.py``) works against this API; see ``atlas`` for the
rect conventions (texel offsets from the texture origin, border included in the rect).
"""

from stb_hydra.shadows.atlas import AllocResult, AtlasRect, AtlasStats, ShadowAtlas
from stb_hydra.shadows.policy import (
    apply_hysteresis,
    choose_resolutions,
    light_priorities,
    sizes_from_target,
    target_texels,
)
from stb_hydra.shadows.scheduler import (
    SchedulerStats,
    ShadowScheduler,
    ShadowUpdate,
    WaitStats,
    same_transform,
)

__all__ = [
    "AllocResult",
    "AtlasRect",
    "AtlasStats",
    "SchedulerStats",
    "ShadowAtlas",
    "ShadowScheduler",
    "ShadowUpdate",
    "WaitStats",
    "apply_hysteresis",
    "choose_resolutions",
    "light_priorities",
    "same_transform",
    "sizes_from_target",
    "target_texels",
]
