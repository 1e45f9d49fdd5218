"""``wovenskin fake-device``: a fake skin on a pty streaming a simulated person's gestures.

:func:`run_fake_device` plays a looped simulated recording through a
:class:`~wovenskin.sim.pty_skin.FakeSkinDevice` (whose person rests while a host
calibrates: :class:`RestingPerson`) and prints the ``--skin serial:...`` spec to read it
with, so a setup can be tried without a skin.  POSIX only (pseudo-terminals).
"""

from __future__ import annotations

import contextlib
import signal
import threading
import time
from collections.abc import Iterator
from typing import TYPE_CHECKING

import numpy as np

from wovenskin.errors import ConfigError
from wovenskin.sim.pty_skin import FakeSkinDevice
from wovenskin.sim.stream import simulate_stream
from wovenskin.skin.layout import ROW_MAJOR, ChannelOrder, SkinLayout
from wovenskin.skin.messages import SampleDtype

if TYPE_CHECKING:
    from rich.console import Console


def run_fake_device(
    seconds: float | None = None,
    fmt: str = "binary",
    seed: int = 0,
    console: Console | None = None,
    *,
    layout: SkinLayout | None = None,
    order: ChannelOrder = ROW_MAJOR,
    dtype: SampleDtype = SampleDtype.F32,
    loop_s: float = 120.0,
) -> FakeSkinDevice:
    """Stream a simulated person's gestures from a fake skin until ``seconds`` pass or Ctrl-C.

    The frames are a ``loop_s`` simulated recording (``wovenskin.sim``, drawn from ``seed``)
    played in a loop.  Prints the port and the ``--skin`` spec that reads it; returns the
    (stopped) device so callers can inspect what it sent.
    """
    if fmt not in ("binary", "text"):
        raise ConfigError(f"format must be 'binary' or 'text', got {fmt!r}")
    if seconds is not None and not seconds > 0:
        raise ConfigError(f"seconds must be positive, got {seconds}")
    layout = layout or SkinLayout()
    length = loop_s if seconds is None else min(loop_s, max(seconds, 2.0))
    stream = simulate_stream(length, seed, layout=layout)
    first_touch = float(np.min(stream.event_start_s)) if len(stream.event_start_s) else length
    idle = int(max(0.0, first_touch - 0.2) * stream.sample_rate_hz)  # the hand still away
    person = RestingPerson(stream.frames, idle, stream.sample_rate_hz)
    device = FakeSkinDevice(
        person, stream.sample_rate_hz, layout, order, dtype, fmt, seed=seed, on_start=person.rest
    )
    say = console.print if console is not None else print  # the CLI's never wraps off a tty
    with device, _terminate_as_interrupt():
        spec = f"serial:{device.port}"
        if fmt == "text":
            spec += f"?format=text&skip=1&order={order}&rows={layout.rows}&cols={layout.cols}"
        say(f"fake skin streaming {fmt} at {stream.sample_rate_hz:g} Hz on {device.port}")
        say(f"read it with: --skin '{spec}'  (Ctrl-C to stop)")
        deadline = None if seconds is None else time.monotonic() + seconds
        with contextlib.suppress(KeyboardInterrupt):
            while deadline is None or time.monotonic() < deadline:
                time.sleep(
                    0.1 if deadline is None else min(0.1, max(0.0, deadline - time.monotonic()))
                )
    say(f"sent {device.frames_sent} frames")
    return device


REST_ON_START_S = 1.0  # the simulated person rests this long when a host starts reading


class RestingPerson:
    """A looped simulated recording whose person keeps hands off while a host calibrates.

    A reader calibrates on its first 0.5 s of frames (hands off); a person who never rests
    put a gesture into that half second for most readers, so every ``view`` began with a
    calibration warning.  :meth:`rest` (the device calls it on START and RECALIBRATE, i.e.
    whenever a host starts reading or recalibrates) plays contact-free frames of the same
    recording (its first, idle second) for :data:`REST_ON_START_S`, then the loop goes on.
    """

    def __init__(self, frames: np.ndarray, idle_frames: int, rate_hz: float) -> None:
        self.frames = np.asarray(frames, dtype=np.float32)
        self.idle_frames = max(1, min(int(idle_frames), len(self.frames)))
        self.rate_hz = float(rate_hz)
        self._rest_from: int | None = None  # the device's frame index when the rest began
        self._rest_frames = int(round(REST_ON_START_S * self.rate_hz))
        self._pending = False

    def rest(self) -> None:
        """Rest from the next frame on (called from the device's thread)."""
        self._pending = True

    def __call__(self, index: int, t_s: float) -> np.ndarray:
        if self._pending:
            self._pending, self._rest_from = False, index
        if self._rest_from is not None and index - self._rest_from < self._rest_frames:
            return self.frames[(index - self._rest_from) % self.idle_frames]
        return self.frames[index % len(self.frames)]


@contextlib.contextmanager
def _terminate_as_interrupt() -> Iterator[None]:
    """SIGTERM (``kill``, a service manager) ends the device as Ctrl-C does, so its
    temporary port folder is removed; the previous handler comes back afterwards."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def interrupt(signum: int, frame: object) -> None:
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)
