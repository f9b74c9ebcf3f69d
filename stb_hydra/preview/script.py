"""``stb preview --script EVENTS.json``: scripted input for tests and automation.

The file holds a JSON list of events (or ``{"events": [...]}``), run in order, one
object each; an event with a count (``wait``) spans that many frames, every other
event takes effect before the next frame is rendered:

=================================================  ======================================
``{"wait": N}``                                    render N frames
``{"wait": "converged"}``                          render until ``--max-samples`` is reached
``{"sleep": S}``                                   wait S seconds (the window stays open)
``{"wait_file": PATH}``                            wait until PATH exists (the window open,
                                                   taking input; at most
                                                   ``limits.PREVIEW_WAIT_FILE_MAX_S``): an
                                                   outside driver's "go on" (e.g. after
                                                   xdotool input), instead of a race
``{"orbit": [dx, dy]}``                            tumble by a drag of (dx, dy) pixels
``{"track": [dx, dy]}``                            track (pan) by (dx, dy) pixels
``{"dolly": px}``                                  dolly by a drag of px pixels (+ = closer)
``{"wheel": steps}``                               mouse-wheel steps (+ = closer)
``{"key": "F"}``                                   a key press (the window's bindings)
``{"method": "sun", "options": {...}}``            switch the lighting method
``{"options": {"N": 4}}``                          change the current method's options
``{"temporal": "auto"}``                           auto / accumulate / taa / off
``{"light": PATH, "enabled": false, ...}``         light edit (``intensity``, ``exposure``,
                                                   ``color``) on the session layer
``{"camera": PATH or null}``                       look through a stage camera / the free one
``{"time": T}`` / ``{"play": true}``               set the time code / play or pause
``{"view": "lightcount"}``                         show an AOV or debug view (``color``: back)
``{"exposure": stops}`` / ``{"ocio_view": NAME}``  display exposure / OCIO view
``{"select": PATH}``                               select a prim (F frames it)
``{"pick": [x, y]}``                               select the prim at a pixel (a click)
``{"ui": false}``                                  hide or show the panels
``{"screenshot": FILE}``                           write what the window shows (OIIO)
``{"save_edits": FILE}``                           write the session layer's edits
``{"mark": TEXT}``                                 print ``stb preview: mark TEXT window=0x..
                                                   selected=PATH`` on stdout
``{"quit": true}``                                 close the window (exit 0)
=================================================  ======================================
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

#: Event name -> the JSON types its value may have.
_NUM = (int, float)
EVENT_TYPES: dict[str, tuple[type, ...]] = {
    "wait": (int, str),
    "sleep": _NUM,
    "wait_file": (str,),
    "orbit": (list,),
    "track": (list,),
    "dolly": _NUM,
    "wheel": _NUM,
    "key": (str,),
    "method": (str,),
    "options": (dict,),
    "temporal": (str,),
    "light": (str,),
    "camera": (str, type(None)),
    "time": _NUM,
    "play": (bool,),
    "view": (str,),
    "exposure": _NUM,
    "ocio_view": (str,),
    "select": (str,),
    "pick": (list,),
    "ui": (bool,),
    "screenshot": (str,),
    "save_edits": (str,),
    "mark": (str,),
    "quit": (bool,),
}
#: Keys an event may carry besides its name (``method`` and ``light`` events).
EXTRA_KEYS = {
    "method": {"options"},
    "light": {"enabled", "intensity", "exposure", "color"},
}
TEMPORAL_CHOICES = ("auto", "accumulate", "taa", "off")


class ScriptError(ValueError):
    """A one-line problem with an event script (file, event number, what is wrong)."""


@dataclass
class Event:
    """One scripted event: ``kind`` is its name, ``value`` its value, ``extra`` the
    other keys (``options`` of a method switch, a light edit's fields)."""

    kind: str
    value: Any
    extra: dict[str, Any] = field(default_factory=dict)
    index: int = 0


def _check(where: str, kind: str, value: Any, extra: dict[str, Any]) -> None:
    if kind in ("orbit", "track", "pick"):
        if len(value) != 2 or not all(
            isinstance(v, _NUM) and not isinstance(v, bool) for v in value
        ):
            raise ScriptError(f"{where}: '{kind}' needs two numbers (pixels), got {value!r}")
    if kind == "wait":
        ok = (isinstance(value, int) and not isinstance(value, bool) and value >= 0) or (
            value == "converged"
        )
        if not ok:
            raise ScriptError(
                f"{where}: 'wait' needs a frame count >= 0 or \"converged\", got {value!r}"
            )
    if kind == "sleep" and not 0 <= value <= 600:
        raise ScriptError(f"{where}: 'sleep' needs 0..600 seconds, got {value!r}")
    if kind == "temporal" and value not in TEMPORAL_CHOICES:
        raise ScriptError(
            f"{where}: 'temporal' must be one of {', '.join(TEMPORAL_CHOICES)}, got {value!r}"
        )
    if kind == "light":
        if not extra:
            raise ScriptError(
                f"{where}: 'light' needs at least one of enabled, intensity, exposure, color"
            )
        if "enabled" in extra and not isinstance(extra["enabled"], bool):
            raise ScriptError(f"{where}: 'enabled' must be true or false")
        for k in ("intensity", "exposure"):
            if k in extra and (not isinstance(extra[k], _NUM) or isinstance(extra[k], bool)):
                raise ScriptError(f"{where}: '{k}' must be a number, got {extra[k]!r}")
        if "color" in extra:
            c = extra["color"]
            if not (isinstance(c, list) and len(c) == 3 and all(isinstance(v, _NUM) for v in c)):
                raise ScriptError(f"{where}: 'color' must be [r, g, b], got {c!r}")
    if kind == "method" and "options" in extra and not isinstance(extra["options"], dict):
        raise ScriptError(f"{where}: 'options' must be an object")


def parse_events(data: Any, source: str = "script") -> list[Event]:
    """Events from decoded JSON; raises :class:`ScriptError` naming the source and the
    event (1-based) for anything it cannot run."""
    if isinstance(data, dict) and set(data) == {"events"}:
        data = data["events"]
    if not isinstance(data, list):
        raise ScriptError(f'{source}: expected a list of events (or {{"events": [...]}})')
    out: list[Event] = []
    for i, ev in enumerate(data, 1):
        where = f"{source}: event {i}"
        if not isinstance(ev, dict) or not ev:
            raise ScriptError(f'{where}: expected an object like {{"wait": 10}}, got {ev!r}')
        # Events that carry extra keys are named by their own key ("light", "method").
        names = [k for k in EXTRA_KEYS if k in ev] or [k for k in ev if k in EVENT_TYPES]
        if not names:
            raise ScriptError(
                f"{where}: unknown event {next(iter(ev))!r} (choose from {', '.join(EVENT_TYPES)})"
            )
        kind = names[0]
        allowed = EXTRA_KEYS.get(kind, set())
        extra = {k: v for k, v in ev.items() if k != kind}
        bad = [k for k in extra if k not in allowed]
        if bad:
            raise ScriptError(
                f"{where}: unexpected key(s) {', '.join(map(repr, bad))} in a {kind!r} event"
            )
        value = ev[kind]
        if not isinstance(value, EVENT_TYPES[kind]) or (
            isinstance(value, bool) and bool not in EVENT_TYPES[kind]
        ):
            raise ScriptError(f"{where}: bad value {value!r} for {kind!r}")
        _check(where, kind, value, extra)
        out.append(Event(kind, value, extra, i))
    return out


def load_script(path: str | Path) -> list[Event]:
    """Read and parse an event script (:class:`ScriptError` on any problem)."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except OSError as exc:
        raise ScriptError(f"{p}: cannot read the script ({exc.strerror or exc})") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ScriptError(f"{p}: not JSON (line {exc.lineno}: {exc.msg})") from None
    return parse_events(data, str(p))
