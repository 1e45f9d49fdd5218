"""The live simulated skin: a :class:`~wovenskin.skin.source.SkinSource` backed by the simulator.

Owns :class:`SimulatedSkinSource` (``open_source("sim")``).  A background thread renders a
simulated person performing random gestures, invalid touches and idle gaps forever (after
at least one contact-free second), a little ahead of the wall clock; :meth:`poll` hands out
the frames that are due.  ``speed=1`` paces frames in real time, ``speed=2`` twice as fast,
``speed=0`` as fast as the consumer polls.  :meth:`perform` queues a specific gesture next
(guided recording, dashboards) and :meth:`current_label` / :attr:`events` give the ground
truth of what the simulated person is doing.  With ``auto=0`` the person rests between
requests and performs only what :meth:`perform` asks for.

:meth:`set_touches` puts fingertips on the skin from outside (the dashboard's virtual
skin): they go through the same :class:`~wovenskin.sim.physics.SkinModel` as the person's
gestures, landing and lifting over a short force ramp and sliding smoothly between the
positions given.  While such fingertips touch, the person's next performance waits.  The
``lookahead`` option (seconds of frames rendered ahead of the wall clock) bounds how late
an outside touch can show up; the dashboard uses a few tens of milliseconds.

The stream is paced by a ``clock`` (default :func:`time.monotonic`): everything that reads
the time (which frames are due, how far ahead to render, when an outside touch arrived, the
frames' ``t_host``) reads it, so a test can drive the source with a clock it advances
itself.  Only :meth:`~SimulatedSkinSource.poll`'s ``timeout`` is real waiting.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from wovenskin.custom_gestures import CustomGesture
from wovenskin.errors import ConfigError
from wovenskin.sim.live_options import DEFAULT_IDLE_S, LOOKAHEAD_S, SimOptions
from wovenskin.sim.live_touches import (
    Fingertip,
    OutsideTouches,
    checked_touches,
)
from wovenskin.sim.motion import LEAD_S
from wovenskin.sim.person import Person
from wovenskin.sim.physics import SkinModel
from wovenskin.sim.skin_physics import SkinPhysics
from wovenskin.sim.stream import INITIAL_IDLE_S, EventScheduler, StreamEvent, parse_request
from wovenskin.skin.frames import Frame, SkinInfo, SourceEvent, SourceStats
from wovenskin.skin.layout import DEFAULT_SAMPLE_RATE_HZ, SkinLayout
from wovenskin.skin.source import held_back

_IDLE_CHUNK_S = 0.05  # idle is rendered in small pieces so that requests start promptly
_PERFORMANCE_CHUNK_S = 0.05  # performances too: a long one rendered at once starved the reader
_UNPACED_BUFFER_S = 1.0  # speed=0: frames kept ready for the consumer
_TOUCH_CHUNK_S = 0.01  # outside fingertips are rendered in pieces this long


@dataclass
class _Upcoming:
    request: str | None
    contact_frame: int  # stream frame of the next event's first contact


@dataclass
class _Performing:
    """A performance being rendered piece by piece: ``done`` of its frames so far."""

    performance: Any
    done: int = 0


class SimulatedSkinSource:
    """A simulated skin and person streaming frames paced to the wall clock."""

    def __init__(
        self,
        seed: int | None = None,
        speed: float = 1.0,
        layout: SkinLayout | None = None,
        gestures: list[str] | None = None,
        idle_s: tuple[float, float] = DEFAULT_IDLE_S,
        invalid_fraction: float = 0.25,
        physics: SkinPhysics | None = None,
        person: Person | None = None,
        typical_person: bool = True,
        sample_rate_hz: float = DEFAULT_SAMPLE_RATE_HZ,
        max_batch: int = 200,
        autonomous: bool = True,
        lookahead_s: float = LOOKAHEAD_S,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        """``max_batch``: most frames one :meth:`poll` returns when ``speed=0``;
        ``typical_person``: draw the person (when ``person`` is None) with
        :meth:`Person.sample_typical`, else from the full range; ``autonomous=False``: the
        person rests and acts only on :meth:`perform` requests;
        ``lookahead_s``: seconds of frames rendered ahead of the wall clock; ``clock``:
        the wall clock (seconds, never going back) that paces the stream."""
        if not np.isfinite(speed) or speed < 0:
            raise ConfigError(f"sim speed must be >= 0 (0 = as fast as polled), got {speed}")
        if not np.isfinite(lookahead_s) or not 0.005 <= lookahead_s <= 5.0:
            raise ConfigError(f"sim lookahead must be 0.005-5 s, got {lookahead_s}")
        self.lookahead_s = float(lookahead_s)
        self._clock = clock
        self.seed = int(seed) if seed is not None else int(np.random.SeedSequence().entropy % 2**31)
        self.speed = float(speed)
        self.autonomous = bool(autonomous)
        self.max_batch = max(1, int(max_batch))
        self.layout = layout if layout is not None else SkinLayout()
        fs = float(sample_rate_hz)
        self.layout.check_supported(fs, "sim")
        rng = np.random.default_rng(self.seed)
        # A typical skin by default: a demonstration should not land on the dullest skin
        # the simulator can draw (pass ``physics`` for any other).
        self.physics = physics if physics is not None else SkinPhysics.sample_typical(rng)
        # A typical person too, so that the gesture buttons perform what they name.
        draw = Person.sample_typical if typical_person else Person.sample
        self.person = person if person is not None else draw(rng)
        self._model = SkinModel(self.physics, self.layout, int(rng.integers(2**31)), fs)
        self._scheduler = EventScheduler(
            rng, self.person, self.layout, gestures, invalid_fraction, idle_s, fs
        )
        self._fs = fs
        self._info = SkinInfo(
            rows=self.layout.rows,
            cols=self.layout.cols,
            sample_rate_hz=fs,
            firmware="wovenskin-sim",
            device_id=f"sim-seed-{self.seed}",
            channel_order="row-major",
            units="pF",
            source="sim",
            row_pitch_mm=self.layout.row_pitch_mm,
            col_pitch_mm=self.layout.col_pitch_mm,
        )
        self._cond = threading.Condition()
        self._buffer: deque[np.ndarray] = deque()  # rendered, not yet delivered frames
        self._rendered = 0  # frames rendered so far (stream frames)
        self._delivered = 0
        self._requests: deque[str] = deque()
        self._events: list[StreamEvent] = []
        self._notices: list[SourceEvent] = []
        self._stats = SourceStats()
        self._upcoming = _Upcoming(None, int(round(rng.uniform(*INITIAL_IDLE_S) * fs)))
        self._earliest_contact = self._upcoming.contact_frame
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._closed = False
        self._paused = False
        self._clock_origin = 0.0  # wall time at which stream time 0 was (shifted by pauses)
        self.slowed_s = 0.0  # wall seconds the stream was held back for a slow reader (poll)
        self._paused_at = 0.0
        self._touches = OutsideTouches(fs, self.physics.hover_tau_s)  # set_touches
        self._performing: _Performing | None = None  # a performance still being rendered

    # -- construction from a spec -------------------------------------------------------------
    @classmethod
    def from_options(cls, options: dict[str, str]) -> SimulatedSkinSource:
        """Build from a spec's options (all values are strings): :class:`SimOptions`."""
        return cls(**SimOptions.read(options).source_kwargs())

    # -- SkinSource ---------------------------------------------------------------------------
    @property
    def info(self) -> SkinInfo:
        return self._info

    def start(self) -> None:
        with self._cond:
            if self._closed:
                raise RuntimeError("the simulated skin was closed; open a new source")
            if self._thread is not None:
                return
            self._clock_origin = self._clock()
            self._stop.clear()
            self._stats.connected = True
            self._notices.append(
                SourceEvent("connected", "simulated skin started", self._clock(), self._info)
            )
            self._thread = threading.Thread(target=self._produce, name="sim-skin", daemon=True)
            self._thread.start()

    def poll(self, timeout: float = 0.05) -> list[Frame | SourceEvent]:
        deadline = time.monotonic() + max(0.0, timeout)
        out: list[Frame | SourceEvent] = []
        with self._cond:
            if self._thread is None:
                return out
            while True:
                out.extend(self._notices)
                self._notices.clear()
                now = self._clock()
                due = self._hold_back(self._due_frames(now))
                while self._buffer and self._delivered < due:
                    values = self._buffer.popleft()
                    seq = self._delivered
                    out.append(Frame(seq=seq, t=seq / self._fs, values=values, t_host=now))
                    self._delivered += 1
                    self._stats.good_frames += 1
                if out:
                    self._cond.notify_all()  # the producer may top up the buffer
                    return out
                left = deadline - time.monotonic()  # real waiting, whatever paces the stream
                if left <= 0 or self._stop.is_set():
                    return out
                self._cond.wait(min(left, self._wait_hint(now)))

    def stats(self) -> SourceStats:
        with self._cond:
            return self._stats.copy()

    def send_command(self, command: str) -> None:
        """``stop`` pauses the stream (and its clock), ``start`` resumes; ``recalibrate``: no-op."""
        command = command.strip().lower()
        with self._cond:
            if command == "stop" and not self._paused:
                self._paused, self._paused_at = True, self._clock()
            elif command == "start" and self._paused:
                self._paused = False
                self._clock_origin += self._clock() - self._paused_at
            elif command not in ("start", "stop", "recalibrate"):
                raise ValueError(
                    f"unknown skin command {command!r}: use start, stop or recalibrate"
                )
            self._cond.notify_all()

    def close(self) -> None:
        with self._cond:
            thread, self._thread = self._thread, None
            self._closed = True
            self._stop.set()
            self._stats.connected = False
            self._cond.notify_all()
        if thread is not None:
            thread.join(timeout=5.0)

    # -- ground truth and requests --------------------------------------------------------------
    def define_gestures(self, custom: Mapping[str, CustomGesture]) -> None:
        """Teach the person a user's custom gestures (performed from their stroke scripts),
        so that :meth:`perform` accepts their names."""
        with self._cond:
            self._scheduler.custom.update(custom)

    def perform(self, name: str) -> None:
        """Queue ``name`` (a class name, a custom gesture defined with
        :meth:`define_gestures`, or ``invalid:KIND``) as the person's next event."""
        parse_request(name, self._scheduler.custom)
        with self._cond:
            self._requests.append(name)
            self._cond.notify_all()

    def set_touches(self, touches: dict[int, Fingertip], client_t: float | None = None) -> None:
        """Put outside fingertips on the skin: ``{pointer id: Fingertip}``, replacing the
        previous sample's.  Fingertips missing from ``touches`` lift off; new ones land.

        ``client_t`` (seconds on the sender's clock, e.g. a browser event's timestamp)
        keeps the sender's timing: samples are played a play-out delay behind the first
        sample of a touch (:data:`TOUCH_JITTER_S`, adapted to how late the sender's samples
        have been arriving: see :class:`~wovenskin.sim.live_touches.OutsideTouches`), at
        their own spacing, however bunched they arrive (but never seconds behind a stream
        that renders slower than the wall clock: lifting stops the arm promptly), and a
        fingertip slides in a straight line from one sample to the next.  A sample later
        than that delays the rest of the touch rather than making the finger jump; one
        timed more than :data:`MAX_TOUCH_LEAD_S` ahead (the sender's clock jumped) plays
        from now.  Without ``client_t`` a sample applies at the next rendered frame.

        Sparse samples (a busy page, a slow tablet: 3-13 per stroke) are reconstructed,
        not jumped: when a sample that moves a fingertip arrives after the fingertip has
        already reached the previous one and stood waiting, the slide to it starts at the
        next rendered frame and lasts the samples' own spacing (at most
        :data:`MAX_TOUCH_SEGMENT_S`), and the rest of the touch plays that much later.  The
        play-out delay so grows to the sender's sample spacing and the fingertip moves
        along the drawn path at the drawn speed, frame by frame (a jump of 10-20 mm between
        two frames looked like two fingers to the recogniser).  A pressing fingertip's
        force changes the same way, in a straight line from sample to sample (a busy page
        sent a mouse's rising press as steps 100 ms apart, and `push` was not recognised).
        A segment longer than 2 x :data:`_TOUCH_CURVE_STEP_S` of stream time (never between
        dense samples) follows the curve the samples lie on, not the chord: when the two
        samples before it placed the same pressing fingertips, moving, points every
        :data:`_TOUCH_CURVE_STEP_S` are added on the quadratic through the last three
        positions (parametrised by chord length, so three collinear points give the straight
        line at an even speed), with the segment's timing unchanged (sparse circles drawn as
        polygons read as two-finger swipes).  Positions may lie off the sensing area
        (nothing is sensed there); forces are capped at :data:`MAX_TOUCH_FORCE_N`.  Raises
        ``ValueError`` for more than :data:`MAX_TOUCHES` fingertips, values that are not
        fingertips or a non-finite ``client_t``."""
        capped = checked_touches(touches, client_t)
        with self._cond:
            self._touches.add(capped, client_t, self._rendered / self._fs, self._clock())
            self._cond.notify_all()

    @property
    def touching(self) -> bool:
        """Whether outside fingertips are on the skin (or still lifting off or queued)."""
        with self._cond:
            return self._touches.active

    @property
    def events(self) -> list[StreamEvent]:
        """Events that have begun by the last delivered frame (stream clock)."""
        with self._cond:
            now = self._delivered / self._fs
            return [e for e in self._events if e.start_s <= now]

    def current_label(self) -> str | None:
        """What the simulated person is doing at the last delivered frame (None: nothing)."""
        with self._cond:
            if self._delivered == 0:
                return None
            t = (self._delivered - 1) / self._fs
            for e in reversed(self._events):
                if e.start_s <= t < e.end_s:
                    return e.label
            return None

    # -- pacing -----------------------------------------------------------------------------
    def _due_frames(self, now: float) -> int:
        """Frames that should have been delivered by wall time ``now``."""
        if self.speed == 0:
            return self._delivered + self.max_batch
        clock = (self._paused_at if self._paused else now) - self._clock_origin
        return int(clock * self.speed * self._fs) + 1

    def _hold_back(self, due: int) -> int:
        """``due``, or fewer when the reader is more than
        :data:`~wovenskin.skin.source.MAX_READER_LAG_S` behind:
        then the stream clock is held back by the excess, so a starved reader (a session
        that cannot keep real time beside a browser) runs the simulated world slower
        instead of receiving seconds of frames at once and acting on touches seconds old
        (a lift-off among them: the arm moved on for as long).  Lock held."""
        if self.speed == 0 or self._paused or due <= self._delivered:
            return due
        now, behind = held_back(due - self._delivered, self.speed * self._fs)
        self._clock_origin += behind
        self.slowed_s += behind
        return self._delivered + now

    def _wait_hint(self, now: float) -> float:
        if self.speed == 0 or self._paused:
            return 0.05
        next_due = self._clock_origin + self._delivered / (self.speed * self._fs)
        return max(0.001, next_due - now)

    def _render_target(self) -> int:
        if self.speed == 0:
            return self._delivered + int(_UNPACED_BUFFER_S * self._fs)
        ahead = max(1, int(self.lookahead_s * self.speed * self._fs))
        return self._due_frames(self._clock()) + ahead

    # -- producer thread --------------------------------------------------------------------------
    def _produce(self) -> None:
        try:
            while not self._stop.is_set():
                with self._cond:
                    if self._paused or self._rendered >= self._render_target():
                        self._cond.wait(0.02)
                        continue
                    request = self._requests.popleft() if self._requests else None
                frames = self._render_next(request)
                with self._cond:
                    self._buffer.extend(frames)
                    self._rendered += len(frames)
                    self._cond.notify_all()
        except Exception as exc:  # never let the consumer hang on a dead producer
            with self._cond:
                message = f"simulator stopped: {type(exc).__name__}: {exc}"
                self._stats.last_error = message
                self._notices.append(SourceEvent("error", message, self._clock()))
                self._cond.notify_all()

    def _render_next(self, request: str | None) -> np.ndarray:
        """Render the next piece: an idle chunk, or the next chunk of a performance.

        Every piece is at most :data:`_PERFORMANCE_CHUNK_S` long (or the lookahead, if
        shorter): rendering a whole multi-second performance at once took up to 130 ms on
        an idle machine, longer than the dashboard's 30 ms lookahead plus the safety
        layer's 100 ms skin watchdog, so the reader starved and the arm stopped."""
        fs = self._fs
        lead = int(round(LEAD_S * fs))
        upcoming = self._upcoming
        chunk = int(round(min(_IDLE_CHUNK_S, self.lookahead_s) * fs))
        if self._performing is not None:  # finish the performance under way first
            if request is not None:
                with self._cond:
                    self._requests.appendleft(request)
            return self._continue_performance()
        with self._cond:
            touching = self._touches.active
        if touching:  # outside fingertips: the person waits until they have lifted
            if request is not None:
                with self._cond:
                    self._requests.appendleft(request)
            frames = self._render_touches(max(1, int(round(_TOUCH_CHUNK_S * fs))))
            gap = int(round(self._scheduler.idle_s[0] * fs))
            upcoming.contact_frame = max(upcoming.contact_frame, self._rendered + lead + gap)
            self._earliest_contact = max(self._earliest_contact, upcoming.contact_frame)
            return frames
        if request is not None:
            if upcoming.request is not None:
                with self._cond:
                    self._requests.appendleft(request)  # keep it for the event after next
            else:
                upcoming.request = request
                upcoming.contact_frame = max(self._earliest_contact, self._rendered + lead)
        if not self.autonomous and upcoming.request is None:
            return self._model.render_idle(max(1, chunk))
        start = upcoming.contact_frame - lead
        if self._rendered < start:
            n = min(start - self._rendered, max(1, chunk))
            return self._model.render_idle(n)
        performance = self._scheduler.next_performance(upcoming.request)
        offset = self._rendered / fs  # the performance's frame 0 on the stream clock
        event = StreamEvent(
            performance.label,
            performance.invalid_kind,
            offset + performance.event_start_s,
            offset + performance.event_end_s,
        )
        end_frame = int(round(event.end_s * fs))
        gap = int(round(self._scheduler.idle_gap_s() * fs))
        min_gap = int(round(self._scheduler.idle_s[0] * fs))
        with self._cond:
            self._events.append(event)
            self._upcoming = _Upcoming(None, end_frame + gap)
            self._earliest_contact = end_frame + max(min_gap, 2 * lead)
        self._performing = _Performing(performance)
        return self._continue_performance()

    def _continue_performance(self) -> np.ndarray:
        """The next chunk of the performance under way (the same frames as rendering it
        at once: the model renders a track in pieces by offset)."""
        performing = self._performing
        assert performing is not None
        performance = performing.performance
        chunk = max(1, int(round(min(_PERFORMANCE_CHUNK_S, self.lookahead_s) * self._fs)))
        n = min(chunk, performance.n_frames - performing.done)
        frames = self._model.render(performance.contacts, n, performance.bursts, performing.done)
        performing.done += n
        if performing.done >= performance.n_frames:
            self._performing = None
        return frames

    def _render_touches(self, n: int) -> np.ndarray:
        """The next ``n`` frames of the outside fingertips (:meth:`OutsideTouches.tracks`)."""
        with self._cond:
            tracks = self._touches.tracks(self._rendered, n)
        return self._model.render(tracks, n)
