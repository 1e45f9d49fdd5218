"""The command log of docs/formats.md: JSON lines ``{"t": s, "gesture": name | null}``.

Each line means: from time ``t`` (seconds on the stream's own clock) the active command is
``gesture`` (``null``: none).  A line is written only when the active command changes.

- Writers (:func:`format_command_log`, :func:`write_command_log`) take anything with
  ``t`` and ``gesture`` attributes (a :class:`Command`, an arbiter ``CommandChange``) in
  time order, leave out entries that do not change the command (the command is ``null``
  before the first line), and write ``t`` rounded to the microsecond.  They refuse a
  non-finite or decreasing time, or a gesture that is not a string or None, with a
  one-line ``ValueError``.
- Readers (:func:`parse_command_log`, :func:`read_command_log`) ignore every line that is
  not a JSON object with both keys, as docs/formats.md requires, and also those whose ``t`` is
  not a finite number or whose ``gesture`` is neither a string nor null (they cannot mean
  a command).  They return the lines as written, repeats included.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol, TextIO

from wovenskin.io import atomic_write_text

TIME_DECIMALS = 6


class CommandLike(Protocol):
    t: float
    gesture: str | None


@dataclass(frozen=True)
class Command:
    """One command-log line: from ``t`` on, the active command is ``gesture``."""

    t: float
    gesture: str | None

    def to_dict(self) -> dict[str, Any]:
        return {"t": self.t, "gesture": self.gesture}


def changes_only(commands: Iterable[CommandLike]) -> list[Command]:
    """The entries that change the active command (``None`` before the first), validated."""
    out: list[Command] = []
    current: str | None = None
    last_t = -math.inf
    for entry in commands:
        t, gesture = entry.t, entry.gesture
        if isinstance(t, bool) or not isinstance(t, int | float) or not math.isfinite(t):
            raise ValueError(f"command time must be a finite number, got {t!r}")
        if t < last_t:
            raise ValueError(f"command times must not decrease: {t} after {last_t}")
        if gesture is not None and not isinstance(gesture, str):
            raise ValueError(f"gesture must be a name or None, got {gesture!r}")
        last_t = float(t)
        if gesture != current:
            out.append(Command(float(t), gesture))
            current = gesture
    return out


def format_command_log(commands: Iterable[CommandLike]) -> str:
    """The command log as text: one JSON object per change, each line ending in a newline."""
    lines = [
        json.dumps({"t": round(c.t, TIME_DECIMALS), "gesture": c.gesture})
        for c in changes_only(commands)
    ]
    return "".join(line + "\n" for line in lines)


def write_command_log(target: str | os.PathLike | TextIO, commands: Iterable[CommandLike]) -> None:
    """Write the command log to a path (replaced) or an open text stream."""
    text = format_command_log(commands)
    if hasattr(target, "write"):
        target.write(text)  # type: ignore[union-attr]
        return
    atomic_write_text(target, text)  # type: ignore[arg-type]


def _entry(line: str) -> Command | None:
    try:
        value = json.loads(line)
    except (json.JSONDecodeError, RecursionError):
        return None
    if not isinstance(value, dict) or "t" not in value or "gesture" not in value:
        return None
    t, gesture = value["t"], value["gesture"]
    if isinstance(t, bool) or not isinstance(t, int | float) or not math.isfinite(t):
        return None
    if gesture is not None and not isinstance(gesture, str):
        return None
    return Command(float(t), gesture)


def parse_command_log(text: str | Iterable[str]) -> list[Command]:
    """Command-log lines from text (or an iterable of lines); other lines are ignored."""
    lines = text.splitlines() if isinstance(text, str) else text
    return [entry for line in lines if (entry := _entry(line)) is not None]


def read_command_log(path: str | os.PathLike) -> list[Command]:
    """Read a command-log file; ``FileNotFoundError`` / ``ValueError`` in one line if unreadable."""
    path = Path(path)
    if path.is_dir():
        raise FileNotFoundError(f"{path}: is a folder, not a command log")
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no such file")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise ValueError(f"{path}: not a text file (a command log is JSON lines)") from None
    return parse_command_log(text)


def commands_table(commands: Iterable[CommandLike]):
    """A Rich table of command changes (with their reasons when they carry one)."""
    from rich.table import Table

    entries = list(commands)
    with_reason = any(hasattr(c, "reason") for c in entries)
    table = Table("t (s)", "command", *(("reason",) if with_reason else ()), title="commands")
    for c in entries:
        cells = [f"{c.t:.3f}", c.gesture if c.gesture is not None else "-"]
        if with_reason:
            cells.append(str(getattr(c, "reason", "")))
        table.add_row(*cells)
    return table
