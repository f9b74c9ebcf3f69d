"""Lighting-method option schemas: class-level data, validated in one place.

    class StbLighting(LightingMethod):
        options = Schema(Opt("N", int, 1, range=(1, 4), doc="samples per small tile"), ...)

``Schema.validate(method, given)`` returns the full option dict (defaults filled
in, values coerced: the CLI hands over strings or loosely parsed values) or raises
:class:`OptionError` with one line naming the method and the option, e.g.
``stb option N: expected an integer, got 'abc'``. Unknown keys list the valid ones.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

#: Words meaning "no value" for nullable options (caps, depth ranges).
NONE_WORDS = ("none", "off", "no", "inf", "")
_TRUE = ("1", "true", "yes", "on")
_FALSE = ("0", "false", "no", "off")


class OptionError(ValueError):
    """A lighting-method option is unknown, mistyped or out of range."""


@dataclass(frozen=True)
class Auto:
    """A default that depends on other options: ``pick(options)`` once the given options
    and the plain defaults are in (an Auto may read another Auto's value: they are
    resolved in dependency order). ``text`` is what the help shows as the default."""

    pick: Callable[[Mapping[str, Any]], Any]
    text: str

    def __repr__(self) -> str:
        return self.text


@dataclass(frozen=True)
class Opt:
    """One option: name, type (int, float, bool, str), default, allowed range
    (inclusive, numbers) or choices, whether None is allowed, and a one-line doc."""

    name: str
    type: type
    default: Any
    range: tuple[float, float] | None = None
    choices: Sequence[Any] | None = None
    nullable: bool = False
    doc: str = ""

    def describe(self) -> str:
        allowed = ""
        if self.choices is not None:
            allowed = " one of " + ", ".join(str(c) for c in self.choices)
        elif self.range is not None:
            allowed = f" {self.range[0]:g}..{self.range[1]:g}"
        null = " or none" if self.nullable else ""
        return (
            f"{self.name} ({self.type.__name__}{allowed}{null}; default {self.default!r}): "
            f"{self.doc}"
        )

    def coerce(self, method: str, value: Any) -> Any:
        """``value`` as this option's type, or OptionError (one line)."""
        where = f"{method} option {self.name}"
        if self.nullable and (
            value is None
            or value is False
            or (isinstance(value, str) and value.strip().lower() in NONE_WORDS)
        ):
            return None
        v = self._typed(where, value)
        if self.choices is not None and v not in self.choices:
            raise OptionError(
                f"{where}: expected one of {', '.join(str(c) for c in self.choices)}, got {value!r}"
            )
        if self.range is not None and not self.range[0] <= v <= self.range[1]:
            raise OptionError(
                f"{where}: expected {self.range[0]:g}..{self.range[1]:g}, got {value!r}"
            )
        return v

    def _typed(self, where: str, value: Any) -> Any:
        t = self.type
        if t is bool:
            if isinstance(value, bool):
                return value
            if isinstance(value, (int, float)) and value in (0, 1):
                return bool(value)
            if isinstance(value, str) and value.strip().lower() in _TRUE + _FALSE:
                return value.strip().lower() in _TRUE
            raise OptionError(f"{where}: expected true or false, got {value!r}")
        if t is int:
            if isinstance(value, bool):
                raise OptionError(f"{where}: expected an integer, got {value!r}")
            if isinstance(value, int):
                return value
            if isinstance(value, float) and value.is_integer():
                return int(value)
            if isinstance(value, str):
                try:
                    return int(value.strip())
                except ValueError:
                    pass
            raise OptionError(f"{where}: expected an integer, got {value!r}")
        if t is float:
            if isinstance(value, (int, float)) and not isinstance(value, bool):
                v = float(value)
            else:
                try:
                    v = float(str(value).strip())
                except ValueError:
                    raise OptionError(f"{where}: expected a number, got {value!r}") from None
            if not math.isfinite(v):
                raise OptionError(f"{where}: expected a finite number, got {value!r}")
            return v
        if t is str:
            if isinstance(value, bool):
                # The CLI reads on/off, true/false, yes/no as booleans; a text option
                # whose choices are such words takes the word back (-o reuse_temporal=on).
                words = _TRUE[1:] if value else _FALSE[1:]
                return next((c for c in self.choices or () if c in words), str(value).lower())
            if isinstance(value, str):
                return value.strip()
            raise OptionError(f"{where}: expected text, got {value!r}")
        raise TypeError(f"unsupported option type {t}")


class Schema:
    """An ordered set of :class:`Opt` (a method's class-level option schema)."""

    def __init__(self, *opts: Opt) -> None:
        self.opts: dict[str, Opt] = {o.name: o for o in opts}

    def __iter__(self) -> Iterator[Opt]:
        return iter(self.opts.values())

    def __contains__(self, name: object) -> bool:
        return name in self.opts

    def __add__(self, other: Schema) -> Schema:
        return Schema(*self, *other)

    def defaults(self) -> dict[str, Any]:
        """Every option's value when none is given (:class:`Auto` defaults resolved)."""
        return self.validate("", {})

    def validate(self, method: str, given: Mapping[str, Any]) -> dict[str, Any]:
        unknown = sorted(set(given) - set(self.opts))
        if unknown:
            valid = ", ".join(self.opts) or "none"
            raise OptionError(f"unknown {method} option(s): {', '.join(unknown)} (valid: {valid})")
        out = {o.name: o.default for o in self if not isinstance(o.default, Auto)}
        for k, v in given.items():
            out[k] = self.opts[k].coerce(method, v)
        todo = [o for o in self if isinstance(o.default, Auto) and o.name not in given]
        while todo:  # an Auto that reads one not yet resolved waits for the next round
            left = []
            for o in todo:
                try:
                    out[o.name] = o.coerce(method, o.default.pick(out))
                except KeyError:
                    left.append(o)
            if len(left) == len(todo):
                raise TypeError(f"{method} options: circular defaults {[o.name for o in left]}")
            todo = left
        return {name: out[name] for name in self.opts}

    def describe(self) -> str:
        return "\n".join(o.describe() for o in self)
