"""The options of a ``sim`` skin spec (``sim:seed=3,speed=0,gestures=swipe_up+push``).

:class:`SimOptions` reads them (text, as a spec gives them) with
:func:`wovenskin.settings.from_dict`; :meth:`SimOptions.source_kwargs` turns them into the
arguments of :class:`~wovenskin.sim.live.SimulatedSkinSource`.  Every problem is one
:class:`~wovenskin.errors.ConfigError` line that lists the options there are.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

from wovenskin.errors import ConfigError
from wovenskin.settings import from_dict
from wovenskin.sim.stream import parse_request
from wovenskin.skin.layout import (
    DEFAULT_COL_PITCH_MM,
    DEFAULT_COLS,
    DEFAULT_ROW_PITCH_MM,
    DEFAULT_ROWS,
    SkinLayout,
)

LOOKAHEAD_S = 0.25  # how far ahead of the wall clock frames are rendered (default)
DEFAULT_IDLE_S = (0.3, 1.5)  # idle gap between events, seconds (low, high)
_GESTURE_SEPARATORS = "+|;/,"
PERSON_RANGES = ("typical", "any")  # Person.sample_typical, Person.sample


@dataclass(frozen=True)
class SimOptions:
    """``seed`` (random when unset), ``speed`` (1: real time, 0: as fast as polled), the
    grid (``rows``, ``cols``, ``row_pitch``/``col_pitch`` in mm), ``gestures`` to draw
    from (``swipe_up+push``), ``idle`` gaps (``SECONDS`` or ``LOW-HIGH``), the ``invalid``
    share of events, ``auto`` (0: the person acts only on requests), ``lookahead`` (s) and
    ``person`` (``typical``: habits of the middle of the range; ``any``: the full range)."""

    seed: int | None = None
    speed: float = 1.0
    rows: int = DEFAULT_ROWS
    cols: int = DEFAULT_COLS
    row_pitch: float = DEFAULT_ROW_PITCH_MM
    col_pitch: float = DEFAULT_COL_PITCH_MM
    gestures: str = ""
    idle: str = ""
    invalid: float = 0.25
    auto: bool = True
    lookahead: float = LOOKAHEAD_S
    person: str = "typical"

    def __post_init__(self) -> None:
        if self.person not in PERSON_RANGES:
            raise ConfigError(
                f"sim person must be one of {', '.join(PERSON_RANGES)}, got {self.person!r}"
            )
        for name in self.gesture_list() or ():
            parse_request(name)
        self.idle_range()

    @classmethod
    def read(cls, options: dict[str, str]) -> SimOptions:
        """The options from a spec's ``key=value`` text; one :class:`ConfigError` if not."""
        try:
            return from_dict(cls, options, "sim options")
        except ConfigError as exc:
            known = ", ".join(field.name for field in dataclasses.fields(cls))
            raise ConfigError(f"{exc} (sim options: {known})") from None

    def gesture_list(self) -> list[str] | None:
        """The gestures to draw from (None: all)."""
        text = self.gestures
        for separator in _GESTURE_SEPARATORS:
            text = text.replace(separator, ",")
        names = [name.strip() for name in text.split(",") if name.strip()]
        return names or None

    def idle_range(self) -> tuple[float, float]:
        """The idle gap range in seconds (one value: a fixed gap)."""
        if not self.idle.strip():
            return DEFAULT_IDLE_S
        parts = self.idle.replace("..", "-").split("-")
        try:
            values = [float(part) for part in parts if part.strip()]
        except ValueError:
            values = []
        if len(values) not in (1, 2):
            raise ValueError(f"sim option idle must be SECONDS or LOW-HIGH, got {self.idle!r}")
        return values[0], values[-1]

    def source_kwargs(self) -> dict[str, Any]:
        """The keyword arguments of :class:`~wovenskin.sim.live.SimulatedSkinSource`."""
        layout = SkinLayout(self.rows, self.cols, self.row_pitch, self.col_pitch)
        return {
            "seed": self.seed,
            "speed": self.speed,
            "layout": layout,
            "gestures": self.gesture_list(),
            "idle_s": self.idle_range(),
            "invalid_fraction": self.invalid,
            "autonomous": self.auto,
            "lookahead_s": self.lookahead,
            "typical_person": self.person == "typical",
        }
