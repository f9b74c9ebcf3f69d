"""Lighting methods, one module each. ``METHODS`` maps CLI names to classes: a plain
literal registry (adding a method = one module + one line here)."""

from __future__ import annotations

from typing import Any

from .bare_loop import BareLoopLighting
from .base import LightingMethod
from .clustered import ClusteredLighting
from .light_tree import LightTreeLighting
from .options import OptionError, Schema
from .reference import ReferenceLighting
from .stb import StbLighting
from .sun_only import SunOnlyLighting
from .tiled import TiledLighting

METHODS: dict[str, type[LightingMethod]] = {
    "reference": ReferenceLighting,
    "sun": SunOnlyLighting,
    "stb": StbLighting,
    "tiled": TiledLighting,
    "clustered": ClusteredLighting,
    "lighttree": LightTreeLighting,
    "bare": BareLoopLighting,
}


def available() -> list[str]:
    """Names of the registered lighting methods (CLI order)."""
    return list(METHODS)


def method_class(name: str) -> type[LightingMethod]:
    """The class registered as ``name`` (ValueError naming the choices)."""
    cls = METHODS.get(name)
    if cls is None:
        raise ValueError(f"unknown lighting method '{name}' (choose from {', '.join(METHODS)})")
    return cls


def validate_options(name: str, options: dict[str, Any]) -> dict[str, Any]:
    """``options`` of method ``name`` validated and completed with defaults."""
    return method_class(name).validate_options(options)


def debug_aov_names() -> tuple[str, ...]:
    """Every debug AOV any method declares (in registry order, no duplicates)."""
    return tuple(dict.fromkeys(a for cls in METHODS.values() for a in cls.debug_aovs))


__all__ = [
    "METHODS",
    "LightingMethod",
    "OptionError",
    "Schema",
    "available",
    "debug_aov_names",
    "method_class",
    "validate_options",
]
