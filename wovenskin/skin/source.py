"""The skin-source interface every backend (simulated, serial, replay) implements."""

from __future__ import annotations

from typing import Protocol, runtime_checkable

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
