"""Gestures of a user's own: :class:`CustomGesture`, read from a mapping file's
``[custom_gestures]`` table (``docs/custom-gestures.md``).

A custom gesture has a name (a lowercase identifier that is none of the 15 built-in class
names of :mod:`wovenskin.gestures`), how many fingers make it (1-5), the description a
person is shown when ``wovenskin record`` prompts it and, optionally, a stroke script: how
a *simulated* person performs it.  A script is a list of strokes, each a polyline of
``(x, y)`` offsets in millimetres from the touch centre (x right, y down: the conventions
of ``docs/gestures.md``); a stroke of one point is a tap.  The fingers lift between
strokes.  ``speed_mm_s`` (the mean speed along a stroke) and ``pause_s`` (the time off the
skin between strokes) are drawn per person where left out.

:func:`parse_custom_gestures` validates the table and reports the first problem as one
:class:`~wovenskin.errors.ConfigError` line naming the key; :func:`custom_from_settings`
reads definitions back from a recording's settings.  The class names a mapping or a
model knows are :func:`wovenskin.gestures.known_classes` of the built-ins and these.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from wovenskin.errors import ConfigError
from wovenskin.gestures import CLASS_NAMES

NAME_PATTERN = re.compile(r"^[a-z][a-z0-9_]{0,39}$")
"""A lowercase identifier: a letter, then letters, digits or ``_`` (at most 40 in all)."""

RESERVED_NAMES = ("idle", "none")
"""Words the request and action languages already use (``idle:4``, ``"none"``)."""

MAX_STROKES = 8
MAX_POINTS = 64
MAX_OFFSET_MM = 200.0
SPEED_RANGE_MM_S = (5.0, 1000.0)
PAUSE_RANGE_S = (0.0, 2.0)
KEYS = ("fingers", "description", "strokes", "speed_mm_s", "pause_s")

Stroke = tuple[tuple[float, float], ...]


@dataclass(frozen=True)
class CustomGesture:
    """A user's gesture: its name, fingers, prompt text and (optional) stroke script."""

    name: str
    fingers: int = 1
    description: str = ""
    strokes: tuple[Stroke, ...] = ()
    speed_mm_s: float | None = None  # mean speed along a stroke (None: the person's own)
    pause_s: float | None = None  # time off the skin between strokes (None: the person's)

    def __post_init__(self) -> None:
        check_custom_name(self.name)
        where = f"custom gesture {self.name!r}"
        if isinstance(self.fingers, bool) or not isinstance(self.fingers, int):
            raise ConfigError(f"{where}: fingers must be a whole number 1-5, got {self.fingers!r}")
        if not 1 <= self.fingers <= 5:
            raise ConfigError(f"{where}: fingers must be 1-5, got {self.fingers}")
        if not isinstance(self.description, str):
            raise ConfigError(f"{where}: description must be text, got {self.description!r}")
        object.__setattr__(self, "description", " ".join(self.description.split()))
        object.__setattr__(self, "strokes", _strokes(self.strokes, where))
        for key, (low, high) in (("speed_mm_s", SPEED_RANGE_MM_S), ("pause_s", PAUSE_RANGE_S)):
            value = getattr(self, key)
            if value is None:
                continue
            if not _number(value) or not low <= float(value) <= high:
                raise ConfigError(
                    f"{where}: {key} must be a number {low:g}-{high:g}, got {value!r}"
                )
            object.__setattr__(self, key, float(value))

    @property
    def prompt(self) -> str:
        """What a person is asked to do: the name, and the description where there is one."""
        shown = self.name.replace("_", " ")
        return f"{shown}: {self.description}" if self.description else shown

    @property
    def performable(self) -> bool:
        """Whether a simulated person can perform it (it has a stroke script)."""
        return bool(self.strokes)

    def to_dict(self) -> dict[str, Any]:
        """JSON/TOML-ready values, the keys of a ``[custom_gestures.NAME]`` table."""
        out: dict[str, Any] = {"fingers": self.fingers, "description": self.description}
        if self.strokes:
            out["strokes"] = [[list(point) for point in stroke] for stroke in self.strokes]
        for key in ("speed_mm_s", "pause_s"):
            if getattr(self, key) is not None:
                out[key] = getattr(self, key)
        return out


def check_custom_name(name: Any) -> str:
    """``name`` if it can name a custom gesture, else one :class:`ConfigError` line."""
    if not isinstance(name, str) or not NAME_PATTERN.match(name):
        raise ConfigError(
            f"custom gesture name {name!r} must be a lowercase identifier "
            "(a letter, then letters, digits or '_', at most 40)"
        )
    if name in CLASS_NAMES:
        raise ConfigError(f"custom gesture name {name!r} is a built-in gesture; choose another")
    if name in RESERVED_NAMES:
        raise ConfigError(f"custom gesture name {name!r} is reserved; choose another")
    return name


def parse_custom_gestures(table: Any, source: str = "<string>") -> dict[str, CustomGesture]:
    """The ``[custom_gestures]`` table as ``{name: CustomGesture}``, in file order.

    Every problem is one :class:`ConfigError` line naming ``source`` and the key
    (``my.toml: custom_gestures.l_stroke.strokes: ...``).
    """
    if not isinstance(table, Mapping):
        raise ConfigError(f"{source}: custom_gestures must be a table of [custom_gestures.NAME]")
    out: dict[str, CustomGesture] = {}
    for name, spec in table.items():
        key = f"custom_gestures.{name}"
        if not isinstance(spec, Mapping):
            raise ConfigError(f"{source}: {key} must be a table (fingers, description, strokes)")
        for field_name in spec:
            if field_name not in KEYS:
                raise ConfigError(
                    f"{source}: {key}.{field_name}: unknown key (expected one of {', '.join(KEYS)})"
                )
        try:
            out[name] = CustomGesture(name=name, **dict(spec))
        except ConfigError as exc:
            raise ConfigError(f"{source}: {key}: {_without_where(str(exc), name)}") from None
    return out


def custom_from_settings(settings: Any) -> dict[str, CustomGesture]:
    """The custom gestures a recording's settings keep (``settings["custom_gestures"]``,
    as ``wovenskin record --mapping`` writes them); ``{}`` where there are none or they
    cannot be read."""
    table = settings.get("custom_gestures") if isinstance(settings, Mapping) else None
    if not table:
        return {}
    try:
        return parse_custom_gestures(table, "recording")
    except ConfigError:
        return {}


def _without_where(message: str, name: str) -> str:
    return message.removeprefix(f"custom gesture {name!r}: ")


def _number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def _strokes(value: Any, where: str) -> tuple[Stroke, ...]:
    """The stroke script as tuples of float points; one ConfigError line if it is not."""
    if value is None:
        return ()
    example = "e.g. strokes = [[[0, -20], [0, 15], [20, 15]]]"
    if not isinstance(value, list | tuple):
        raise ConfigError(f"{where}: strokes must be a list of strokes ({example})")
    if len(value) > MAX_STROKES:
        raise ConfigError(f"{where}: strokes: at most {MAX_STROKES} strokes, got {len(value)}")
    strokes = []
    for i, stroke in enumerate(value):
        if not isinstance(stroke, list | tuple) or not stroke:
            raise ConfigError(
                f"{where}: strokes[{i}] must be a non-empty list of [x, y] points ({example})"
            )
        if len(stroke) > MAX_POINTS:
            raise ConfigError(f"{where}: strokes[{i}]: at most {MAX_POINTS} points")
        points = []
        for j, point in enumerate(stroke):
            ok = isinstance(point, list | tuple) and len(point) == 2 and all(map(_number, point))
            if not ok or max(abs(float(v)) for v in point) > MAX_OFFSET_MM:
                raise ConfigError(
                    f"{where}: strokes[{i}][{j}] must be [x, y] in mm (finite, within "
                    f"+-{MAX_OFFSET_MM:g}), got {point!r}"
                )
            points.append((float(point[0]), float(point[1])))
        strokes.append(tuple(points))
    return tuple(strokes)
