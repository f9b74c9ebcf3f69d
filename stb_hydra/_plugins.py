"""Registration of stb_hydra's codeless USD schema (``StbLightAPI``, ``StbGeometryAPI``).

USD builds its schema registry once, the first time a stage or prim definition is
used. Our plugInfo.json must be registered before that, so ``stb_hydra`` registers
it on import and also exports ``PXR_PLUGINPATH_NAME`` for child processes.
When the registry was already built (USD used before ``import stb_hydra``),
the schema's fallbacks are unavailable; readers in ``scene.lights`` then read the
raw attributes and fall back to the same defaults, so behaviour is unchanged.
"""

from __future__ import annotations

import os
from importlib import resources
from pathlib import Path

#: The schema's plugInfo.json folder, package data read through importlib.resources (a
#: file-system path: USD's plugin registry reads real files).
SCHEMA_DIR = Path(str(resources.files("stb_hydra").joinpath("scene").joinpath("schema")))

_registered = False


def register_schema() -> bool:
    """Register the plugin once. Returns True when StbLightAPI is known to USD."""
    global _registered
    if not _registered:
        _registered = True
        paths = os.environ.get("PXR_PLUGINPATH_NAME", "")
        if str(SCHEMA_DIR) not in paths.split(os.pathsep):
            os.environ["PXR_PLUGINPATH_NAME"] = os.pathsep.join(
                p for p in (str(SCHEMA_DIR), paths) if p
            )
        from pxr import Plug

        Plug.Registry().RegisterPlugins(str(SCHEMA_DIR))
    return schema_available()


def schema_available() -> bool:
    from pxr import Usd

    return bool(Usd.SchemaRegistry().FindAppliedAPIPrimDefinition("StbLightAPI"))
