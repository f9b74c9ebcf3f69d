"""stb_hydra: a USD-native, Hydra-style scene pipeline with Stochastic Tile-Based lighting.

The flat API (Mitsuba style)::

    import stb_hydra
    img = stb_hydra.render("scene.usda", width=256, height=144)   # (h, w, 3) float32, linear

Importing the package registers the codeless ``StbLightAPI``/``StbGeometryAPI`` schema
with USD; import it before opening stages.
"""

from __future__ import annotations

from ._plugins import register_schema

__version__ = "0.1.0"

register_schema()


def __getattr__(name: str):
    # Lazy so `import stb_hydra` stays cheap (no GL, no OCIO) for scene-only users:
    # `stb_hydra.render` is the plain function `stb_hydra.api.render`.
    if name in ("render", "Engine", "RenderSettings", "RenderError"):
        from . import api

        return getattr(api, name)
    raise AttributeError(f"module 'stb_hydra' has no attribute '{name}'")


__all__ = ["Engine", "RenderError", "RenderSettings", "__version__", "render"]
