"""The skin-source interface and :func:`open_source`, which turns a spec into a source.

Specs (the ``--skin`` option of every command):

- ``sim`` or ``sim:seed=3,speed=1`` -- the simulated skin with a simulated person
  performing gestures in real time (the default);
- ``serial:/dev/ttyACM0`` or ``serial:/dev/ttyACM0?format=text&order=col-major`` -- a
  real skin on a serial port (binary protocol of ``docs/protocol.md`` or text lines);
- ``replay:FILE`` -- a labelled-stream ``.npz`` or a native ``.wsrec`` recording played
  back in real time (``replay:FILE?speed=0`` plays as fast as possible).
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable
from urllib.parse import parse_qsl

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


def parse_spec(spec: str) -> tuple[str, str, dict[str, str]]:
    """Split ``kind:target?key=value&...`` (or ``sim:key=value,...``) into its parts."""
    kind, _, rest = spec.partition(":")
    kind = kind.strip().lower()
    target, _, query = rest.partition("?")
    options: dict[str, str] = dict(parse_qsl(query, keep_blank_values=True))
    if kind == "sim" and "=" in target:
        for item in target.split(","):
            key, _, value = item.partition("=")
            options[key.strip()] = value.strip()
        target = ""
    return kind, target, options


def open_source(spec: str = "sim", **overrides) -> SkinSource:
    """Create (but do not start) the source named by ``spec``; see the module docstring."""
    kind, target, options = parse_spec(spec)
    options.update({k: str(v) for k, v in overrides.items() if v is not None})
    if kind == "sim":
        from wovenskin.sim.live import SimulatedSkinSource

        return SimulatedSkinSource.from_options(options)
    if kind == "serial":
        if not target:
            raise ValueError("serial source needs a port, e.g. serial:/dev/ttyACM0")
        from wovenskin.skin.serial_source import SerialSkinSource

        return SerialSkinSource.from_options(target, options)
    if kind == "replay":
        if not target:
            raise ValueError("replay source needs a file, e.g. replay:stream.npz")
        from wovenskin.recording.replay import ReplaySource

        return ReplaySource.from_options(target, options)
    raise ValueError(f"unknown skin source {spec!r}: use sim, serial:PORT or replay:FILE")
