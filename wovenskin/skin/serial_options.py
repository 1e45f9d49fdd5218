"""The options of a ``serial:PORT?key=value&...`` skin spec, read into :class:`SerialOptions`."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Annotated, Literal

from pydantic import BeforeValidator

from wovenskin.settings import from_dict
from wovenskin.skin.layout import DEFAULT_COLS, DEFAULT_ROWS, DEFAULT_SAMPLE_RATE_HZ

DEFAULT_BAUD = 921600
DEFAULT_STALL_MS = 30.0
SEPARATOR_NAMES = {"comma": ",", "semicolon": ";", "tab": "\t", "space": " ", "auto": ""}
"""Names a ``sep`` option may use for a separator that is awkward to type in a spec."""


def _lower(value: object) -> object:
    return value.strip().lower() if isinstance(value, str) else value


@dataclass(frozen=True)
class SerialOptions:
    """What ``serial:PORT?...`` may say (``docs/protocol.md``); every value is optional.

    ``format`` is ``binary`` (the protocol) or ``text`` (lines of numbers); ``order`` (a
    :class:`~wovenskin.skin.layout.ChannelOrder` text), ``sep`` (a separator or one of
    :data:`SEPARATOR_NAMES`) and ``skip`` (leading fields to ignore) apply to text only,
    since a binary device declares its layout in INFO.
    """

    format: Annotated[Literal["binary", "text"], BeforeValidator(_lower)] = "binary"
    order: str = ""
    rows: int = DEFAULT_ROWS
    cols: int = DEFAULT_COLS
    rate: float = DEFAULT_SAMPLE_RATE_HZ
    baud: int = DEFAULT_BAUD
    stall_ms: float = DEFAULT_STALL_MS
    sep: str = ""
    skip: int = 0

    def __post_init__(self) -> None:
        if self.format == "binary" and self.order:
            raise ValueError("order applies to format=text; binary devices declare it in INFO")
        for key, given in (("sep", self.sep), ("skip", self.skip)):
            if self.format == "binary" and given:
                raise ValueError(f"serial option {key} applies to format=text only")

    @property
    def separator(self) -> str | None:
        """The text separator, ``None`` to detect it line by line."""
        return SEPARATOR_NAMES.get(self.sep.lower(), self.sep) or None


def read_serial_options(options: Mapping[str, str]) -> SerialOptions:
    """The spec's options as :class:`SerialOptions` (an empty value means the default);
    one :class:`~wovenskin.errors.ConfigError` line naming the option otherwise."""
    given = {key: value for key, value in options.items() if value != ""}
    return from_dict(SerialOptions, given, "serial options")
