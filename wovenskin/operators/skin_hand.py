"""The skin a simulated operator's hand touches, rendered on the session's clock.

:class:`OperatorSkin` is a :class:`~wovenskin.skin.source.SkinSource` that renders its
frames when the session polls it, ``block`` frames (50 ms) a poll, in the session's own
thread: a simulated operator acting at session time sees its touch in the very next
frames, and a run is the same for the same seeds (the dashboard's simulated skin renders
on a thread of its own, paced to the wall clock).  The skin is drawn from the simulator's
skins of typical response by default (a lab's working skin; the full range, responses
150x apart, on request), touched by a simulated person's hand
(:class:`~wovenskin.sim.person.Person`).

:meth:`OperatorSkin.touch` performs a gesture as the person of :mod:`wovenskin.sim` does
(landing, the pause after landing, the motion, the fingers resting), and keeps the fingers
resting where the motion ended until :meth:`OperatorSkin.lift`, which plays the person's
own lift-off: a held gesture, as an operator holds a swipe while the arm moves.
Everything it renders goes through the session's conditioning and recogniser: a gesture
the recogniser misreads costs the operator as it would cost a person.
"""

from __future__ import annotations

import time

import numpy as np

from wovenskin.errors import ConfigError
from wovenskin.sim.contact import ContactTrack
from wovenskin.sim.motion import Performance
from wovenskin.sim.performances import perform
from wovenskin.sim.person import Person
from wovenskin.sim.physics import SkinModel
from wovenskin.sim.skin_physics import SkinPhysics
from wovenskin.skin.frames import Frame, SkinInfo, SourceEvent, SourceStats
from wovenskin.skin.layout import DEFAULT_SAMPLE_RATE_HZ, SkinLayout
from wovenskin.skin.source import DevicelessSource

BLOCK_FRAMES = 10
"""Frames rendered per poll (50 ms at 200 Hz)."""


class OperatorSkin(DevicelessSource):
    """A simulated skin touched by a simulated operator (module docstring)."""

    def __init__(
        self,
        seed: int,
        physics: SkinPhysics | None = None,
        person: Person | None = None,
        block: int = BLOCK_FRAMES,
        sample_rate_hz: float = DEFAULT_SAMPLE_RATE_HZ,
        full_range: bool = False,
        gesture_seed: int | None = None,
    ) -> None:
        """``physics`` default: a skin of typical response drawn from ``seed``
        (:meth:`~wovenskin.sim.skin_physics.SkinPhysics.sample_typical`), or from the
        simulator's full range with ``full_range`` (responses 150x apart: the dullest
        skins lose a light touch in the noise).  ``gesture_seed``: the draws of each
        performance and of the sensor noise (default: from ``seed``), so one person on one
        skin performs differently from trial to trial."""
        rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, 0x5C1])
        self.layout = SkinLayout()
        if physics is None:
            draw = SkinPhysics.sample if full_range else SkinPhysics.sample_typical
            physics = draw(rng)
        self.physics = physics
        self.person = person if person is not None else Person.sample(rng)
        if gesture_seed is not None:
            rng = np.random.default_rng([int(gesture_seed) & 0xFFFFFFFF, 0x6E5])
        self._rng = rng
        self._fs = float(sample_rate_hz)
        self._model = SkinModel(self.physics, self.layout, int(rng.integers(2**31)), self._fs)
        self.block = max(1, int(block))
        self._info = SkinInfo(
            rows=self.layout.rows, cols=self.layout.cols, sample_rate_hz=self._fs,
            firmware="wovenskin-operator-sim", device_id=f"operator-sim-{int(seed)}",
            source="sim", row_pitch_mm=self.layout.row_pitch_mm,
            col_pitch_mm=self.layout.col_pitch_mm,
        )  # fmt: skip
        self._stats = SourceStats()
        self._closed = self._started = False
        self._queue: list[Frame | SourceEvent] = []
        self._next = 0  # sequence number of the next frame
        self._performance: Performance | None = None
        self._done = 0  # frames of the performance rendered
        self._hold_from = 0  # its first lift-off frame: the hold repeats the frame before
        self._motion_end = 0  # the frame its motion ends (a flick lifts from there)
        self._lifting = False
        self.touches = 0  # gestures begun

    # -- what the operator does

    def touch(self, gesture: str) -> Performance:
        """Begin ``gesture`` (a class name) now; the fingers stay down until :meth:`lift`."""
        if self._performance is not None:
            raise ConfigError("the hand is on the skin: lift it first")
        performance = perform(gesture, self.person, self._rng, self.layout,
                              sample_rate_hz=self._fs)  # fmt: skip
        self._performance, self._done, self._lifting = performance, 0, False
        self._hold_from = int(round(performance.phases.lift_start_s * self._fs))
        self._motion_end = min(
            int(round(performance.phases.motion_end_s * self._fs)), self._hold_from
        )
        self.touches += 1
        return performance

    def lift(self) -> None:
        """Lift the hand: a held hand's lift-off plays from the next frame; a hand still
        moving finishes its motion and lifts without the rest after it (a flick)."""
        if self._performance is not None:
            self._lifting = True

    @property
    def touching(self) -> bool:
        """Whether a hand is on the skin or lifting off."""
        return self._performance is not None

    @property
    def holding(self) -> bool:
        """Whether the gesture's motion is over and the fingers rest, held."""
        return self._performance is not None and not self._lifting and self._done >= self._hold_from

    @property
    def stream_t(self) -> float:
        """Stream time of the next frame (s)."""
        return self._next / self._fs

    # -- SkinSource

    def start(self) -> None:
        if self._started or self._closed:
            return
        self._open("simulated skin under a simulated operator's hand", time.monotonic())

    def poll(self, timeout: float = 0.05) -> list[Frame | SourceEvent]:
        if not self._started or self._closed:
            return []
        items, self._queue = self._queue, []
        values = self._render(self.block)
        now = time.monotonic()
        for frame in values:
            items.append(Frame(seq=self._next, t=self._next / self._fs, values=frame, t_host=now))
            self._next += 1
            self._stats.good_frames += 1
        return items

    # -- rendering

    def _render(self, n: int) -> np.ndarray:
        out = []
        while n > 0:
            piece = self._piece(n)
            out.append(piece)
            n -= len(piece)
        return np.concatenate(out) if len(out) > 1 else out[0]

    def _piece(self, n: int) -> np.ndarray:
        performance = self._performance
        if performance is None:
            return self._model.render_idle(n)
        if not self._lifting and self._done >= self._hold_from:
            return self._model.render(_held(performance.contacts, self._hold_from - 1, n), n)
        if self._lifting and self._motion_end <= self._done < self._hold_from:
            self._done = self._hold_from  # the fingers stand where the motion ended: lift
        if self._done < self._motion_end:
            end = self._motion_end
        else:
            end = self._hold_from if not self._lifting else performance.n_frames
        k = max(1, min(n, end - self._done))
        frames = self._model.render(performance.contacts, k, performance.bursts, self._done)
        self._done += k
        if self._done >= performance.n_frames:
            self._performance = None
        return frames


def _held(contacts: list[ContactTrack], frame: int, n: int) -> list[ContactTrack]:
    """``n`` frames of every contact as it is at ``frame`` (the fingers resting, held)."""
    held = []
    for c in contacts:
        i = min(max(frame, 0), c.n_frames - 1)

        def at(value: np.ndarray | float, i: int = i) -> np.ndarray:
            array = np.asarray(value, dtype=np.float64)
            return np.full(n, array if array.ndim == 0 else array[i])

        held.append(ContactTrack(
            at(c.x_mm), at(c.y_mm), at(c.force_n), at(c.semi_major_mm), at(c.semi_minor_mm),
            at(c.angle_rad), c.kind, c.finger,
            None if c.presence is None else at(c.presence),
        ))  # fmt: skip
    return held
