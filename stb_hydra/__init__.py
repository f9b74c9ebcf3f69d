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
    # Lazy so `import stb_hydra` stays cheap (no GL, no OCIO) for scene-only users.
    # `stb_hydra.render` resolves to the render package, which is callable and
    # forwards to `stb_hydra.api.render` (see stb_hydra/render/__init__.py).
    if name == "render":
        import importlib

        return importlib.import_module(".render", __name__)
    raise AttributeError(name)


__all__ = ["__version__", "render"]
