"""The skin-source interface every backend (simulated, serial, replay) implements."""

from __future__ import annotations

from typing import Protocol, runtime_checkable

from wovenskin.errors import ConfigError
from wovenskin.skin.frames import Frame, SkinInfo, SourceEvent, SourceStats


@runtime_checkable
class SkinSource(Protocol):
    """A running stream of frames; every backend (sim, serial, replay) implements this."""

    @property
    def info(self) -> SkinInfo: ...

    def start(self) -> None:
        """Begin streaming (idempotent)."""

    def poll(self, timeout: float = 0.05) -> list[Frame | SourceEvent]:
        """Frames and events that arrived since the last call, waiting up to ``timeout``.

        Returns an empty list when nothing arrived in time.  Never raises for stream
        problems: those arrive as :class:`SourceEvent` items and in :meth:`stats`.
        """

    def stats(self) -> SourceStats:
        """A snapshot of the source's counters."""

    def send_command(self, command: str) -> None:
        """Forward ``start``, ``stop`` or ``recalibrate`` to the device (no-op if none)."""

    def close(self) -> None:
        """Stop streaming and release the device; safe to call twice."""


SOURCE_COMMANDS = ("start", "stop", "recalibrate")


MAX_READER_LAG_S = 0.1
"""A paced source without a device (simulated, idle) delivers at most this much of its
stream at once: a reader further behind (a session that cannot keep real time) holds the
stream clock back, so the simulated world runs slower rather than handing the reader
seconds of frames, in ever larger batches, to act on late."""


def held_back(pending: int, frames_per_s: float) -> tuple[int, float]:
    """Of ``pending`` frames due to a reader (paced at ``frames_per_s`` frames per wall
    second), the number to deliver now and how many wall seconds to hold the stream clock
    back: at most :data:`MAX_READER_LAG_S` of frames, the excess becomes slower time."""
    allowed = max(1, int(MAX_READER_LAG_S * frames_per_s))
    if pending <= allowed:
        return pending, 0.0
    return allowed, (pending - allowed) / frames_per_s


class DevicelessSource:
    """What every source without a device shares (a replayed file, the idle clock, a
    simulated operator's skin): its info, starting (once, queueing the "connected" event),
    the stats snapshot, device commands accepted and ignored, and closing.  A subclass sets
    ``self._info`` (a :class:`SkinInfo`), ``self._stats`` (a :class:`SourceStats`),
    ``self._queue`` (an empty list), ``self._started`` and ``self._closed`` (False), and
    its ``start`` calls :meth:`_open`."""

    _info: SkinInfo
    _stats: SourceStats
    _queue: list[Frame | SourceEvent]
    _started: bool
    _closed: bool

    @property
    def info(self) -> SkinInfo:
        return self._info

    def _open(self, message: str, t_host: float) -> None:
        """Mark the source started and connected and queue the "connected" event
        (``message``, at host time ``t_host``)."""
        self._started = True
        self._stats.connected = True
        self._queue.append(SourceEvent("connected", message, t_host, self._info))

    def stats(self) -> SourceStats:
        return self._stats.copy()

    def send_command(self, command: str) -> None:
        """No device: known commands are accepted and ignored."""
        if command not in SOURCE_COMMANDS:
            known = ", ".join(SOURCE_COMMANDS)
            raise ConfigError(f"unknown command {command!r}; known: {known}")

    def close(self) -> None:
        self._closed = True
        self._stats.connected = False
