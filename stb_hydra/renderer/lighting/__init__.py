"""Lighting methods, one module each. ``METHODS`` maps CLI names to classes."""

from __future__ import annotations

import importlib

_REGISTRY = {
    "reference": ("reference", "ReferenceLighting"),
    "sun": ("sun_only", "SunOnlyLighting"),
    "stb": ("stb", "StbLighting"),
    "tiled": ("tiled", "TiledLighting"),
    "clustered": ("clustered", "ClusteredLighting"),
    "lighttree": ("light_tree", "LightTreeLighting"),
}


def register(name: str, module: str, cls: str) -> None:
    _REGISTRY[name] = (module, cls)


def available() -> list[str]:
    out = []
    for name, (mod, _cls) in _REGISTRY.items():
        if importlib.util.find_spec(f"{__name__}.{mod}") is not None:
            out.append(name)
    return out


def method_class(name: str):
    if name not in _REGISTRY:
        raise ValueError(f"unknown lighting method '{name}' (choose from {', '.join(available())})")
    mod, cls = _REGISTRY[name]
    return getattr(importlib.import_module(f"{__name__}.{mod}"), cls)
