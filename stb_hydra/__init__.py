"""stb_hydra: a USD-native, Hydra-style scene pipeline with Stochastic Tile-Based lighting.

The flat API (Mitsuba style), run from a checkout::

    import stb_hydra
    img = stb_hydra.render("usd_scenes/default.usda", width=256, height=144)
    # (144, 256, 3) float32: scene-linear radiance (nits), linear Rec.709, top row first

``render`` (:func:`stb_hydra.api.render`: a plain function, see its signature),
``render_progressive`` (the accumulated image after several frame counts, from one
accumulation), ``Engine`` (a live engine: set_lighting, describe, AOVs), ``RenderSettings`` and
``RenderError`` are imported on first use (no GL, no OCIO for scene-only users).
The ``stb`` command (``stb --help``) renders, inspects, validates and benchmarks.

Importing the package registers the codeless ``StbLightAPI``/``StbGeometryAPI`` schema
with USD; import it before opening stages.
"""

from __future__ import annotations

from ._plugins import register_schema

__version__ = "0.1.0"

register_schema()


_LAZY = ("render", "render_progressive", "Engine", "RenderSettings", "RenderError")


def __getattr__(name: str):
    # Lazy so `import stb_hydra` stays cheap (no GL, no OCIO) for scene-only users:
    # `stb_hydra.render` is the plain function `stb_hydra.api.render`.
    if name in _LAZY:
        from . import api

        return getattr(api, name)
    raise AttributeError(f"module 'stb_hydra' has no attribute '{name}'")


def __dir__() -> list[str]:
    # help(stb_hydra) / dir() list the lazy names too (pydoc documents what dir() shows).
    return sorted({*globals(), *_LAZY})


__all__ = ["Engine", "RenderError", "RenderSettings", "__version__", "render", "render_progressive"]
