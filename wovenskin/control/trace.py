"""The control trace: one JSON line per control tick of a robot session (JSONL).

Each line is exactly ``{"t", "gesture", "tcp", "quat", "tcp_speed", "q"}``: ``t`` the
tick's time in seconds on the skin stream's clock, ``gesture`` the active command (or
``null``), ``tcp`` the tool centre point ``[x, y, z]`` in metres and ``quat`` its
orientation ``[w, x, y, z]``, both in the robot base frame, ``tcp_speed`` its linear speed
in m/s and ``q`` the six joint angles in radians.  :class:`TraceWriter` writes a file (or
any text stream, e.g. stdout for ``--trace -``) and :func:`read_trace` reads one back.
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path
from typing import IO

import numpy as np

from wovenskin.errors import DataError
from wovenskin.outputs import open_new
from wovenskin.robots.base import RobotState

TRACE_KEYS = ("t", "gesture", "tcp", "quat", "tcp_speed", "q")
"""The keys of every trace line, in the order they are written."""


def trace_record(t: float, gesture: str | None, state: RobotState) -> dict:
    """The trace line of one tick as a dict (plain floats, keys in :data:`TRACE_KEYS` order)."""
    if not np.isfinite(t):
        raise ValueError(f"trace time must be finite, got {t}")
    return {
        "t": float(t),
        "gesture": None if gesture is None else str(gesture),
        "tcp": [float(v) for v in state.tcp.position],
        "quat": [float(v) for v in state.tcp.quat],
        "tcp_speed": float(state.tcp_speed),
        "q": [float(v) for v in np.asarray(state.q).reshape(-1)],
    }


class TraceWriter:
    """Writes trace lines to ``target``: a path, ``"-"`` (stdout) or an open text stream.

    A path is created new unless ``overwrite``; lines are flushed every ``flush_every``
    ticks and on :meth:`close`, so a killed session leaves a readable prefix.
    """

    def __init__(
        self,
        target: str | os.PathLike | IO[str],
        *,
        overwrite: bool = False,
        flush_every: int = 200,
    ) -> None:
        self._owns = False
        if isinstance(target, str | os.PathLike) and str(target) == "-":
            self._stream: IO[str] = sys.stdout
            self.path: Path | None = None
        elif isinstance(target, str | os.PathLike):
            self.path = Path(target)
            self._stream = open_new(self.path, overwrite)
            self._owns = True
        else:
            self._stream = target
            self.path = None
        self.flush_every = max(1, int(flush_every))
        self.lines = 0
        self._closed = False

    def write(self, t: float, gesture: str | None, state: RobotState) -> None:
        """Append the line of one tick."""
        if self._closed:
            raise ValueError("the trace is closed")
        self._stream.write(json.dumps(trace_record(t, gesture, state)) + "\n")
        self.lines += 1
        if self.lines % self.flush_every == 0:
            self._stream.flush()

    def close(self) -> None:
        """Flush, and close the file if this writer opened it; safe to call twice."""
        if self._closed:
            return
        self._closed = True
        self._stream.flush()
        if self._owns:
            self._stream.close()

    def __enter__(self) -> TraceWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def read_trace(path: str | os.PathLike) -> list[dict]:
    """The lines of a trace file; ``ValueError`` naming the line when one is malformed."""
    records = []
    with open(path, encoding="utf-8") as f:
        for number, line in enumerate(f, start=1):
            if not line.strip():
                continue
            try:
                record = json.loads(line)
            except json.JSONDecodeError as exc:
                raise DataError(f"{path}:{number}: not JSON ({exc.msg})") from None
            if not isinstance(record, dict) or tuple(record) != TRACE_KEYS:
                raise DataError(f"{path}:{number}: a trace line needs exactly {TRACE_KEYS}")
            records.append(record)
    return records
