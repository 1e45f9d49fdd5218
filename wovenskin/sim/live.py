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
"""

from __future__ import annotations

import threading
import time
from collections import deque
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from wovenskin.gestures import CLASS_NAMES
from wovenskin.sim.motion import LEAD_S
from wovenskin.sim.person import Pad, Person
from wovenskin.sim.physics import ContactTrack, SkinModel, SkinPhysics
from wovenskin.sim.stream import INITIAL_IDLE_S, EventScheduler, StreamEvent, parse_request
from wovenskin.skin.frames import Frame, SkinInfo, SourceEvent, SourceStats
from wovenskin.skin.layout import (
    DEFAULT_COL_PITCH_MM,
    DEFAULT_ROW_PITCH_MM,
    DEFAULT_SAMPLE_RATE_HZ,
    SkinLayout,
)

OPTIONS = (
    "seed",
    "speed",
    "rows",
    "cols",
    "row_pitch",
    "col_pitch",
    "gestures",
    "idle",
    "invalid",
    "auto",
    "lookahead",
)
"""Keys understood by :meth:`SimulatedSkinSource.from_options`."""

_IDLE_CHUNK_S = 0.05  # idle is rendered in small pieces so that requests start promptly
_PERFORMANCE_CHUNK_S = 0.05  # performances too: a long one rendered at once starved the reader
_LOOKAHEAD_S = 0.25  # how far ahead of the wall clock frames are rendered (default)
_UNPACED_BUFFER_S = 1.0  # speed=0: frames kept ready for the consumer
_TOUCH_CHUNK_S = 0.01  # outside fingertips are rendered in pieces this long
_TOUCH_RAMP_S = 0.02  # an outside fingertip reaches its force (or lifts) over this time
MAX_TOUCH_FORCE_N = 10.0
MAX_TOUCHES = 10
_HOVER_TAIL_TAUS = 4.0  # a lifted outside fingertip is sensed for this many hover constants
TOUCH_JITTER_S = 0.03  # timestamped outside touches play this far behind their first sample
MAX_TOUCH_LEAD_S = 2.0  # a sample timed further ahead than this re-anchors the sender's clock
MAX_TOUCH_SEGMENT_S = 0.25  # a fingertip slides between sparse samples over at most this long
_TOUCH_MOVED_MM = 0.2  # a sample this far from where a fingertip waits moves it
_TOUCH_PRESSED_N = 0.02  # ... or one this much harder or lighter presses it
_RESUME_SEGMENT_S = 0.05  # after a rest, a sparse sample's slide lasts at most this long
_TOUCH_CURVE_STEP_S = 0.01  # a long segment is filled with a point on the curve this often
_VIRTUAL_PAD = Pad(width_mm=9.0, growth_mm=3.0, aspect=1.15)


@dataclass(frozen=True)
class Fingertip:
    """An outside fingertip: centre in mm (x right, y down from the sensing area's top-left
    corner, as in :class:`~wovenskin.sim.physics.ContactTrack`) and normal force in N."""

    x_mm: float
    y_mm: float
    force_n: float

    def __post_init__(self) -> None:
        values = (self.x_mm, self.y_mm, self.force_n)
        if not all(isinstance(v, int | float) and np.isfinite(v) for v in values):
            raise ValueError(f"fingertip values must be finite numbers, got {values}")
        if self.force_n < 0:
            raise ValueError(f"fingertip force must be >= 0 N, got {self.force_n}")


def _changes(before: dict[int, Fingertip], after: dict[int, Fingertip]) -> bool:
    """Whether ``after`` moves or presses (harder or lighter) a fingertip of ``before``."""
    for key, tip in after.items():
        old = before.get(key)
        if old is None:
            continue
        if np.hypot(tip.x_mm - old.x_mm, tip.y_mm - old.y_mm) > _TOUCH_MOVED_MM:
            return True
        pressing = tip.force_n > 0 and old.force_n > 0
        if pressing and abs(tip.force_n - old.force_n) > _TOUCH_PRESSED_N:
            return True
    return False


@dataclass
class _TouchSample:
    """The outside fingertips from one moment on, at ``t`` on the stream clock."""

    t: float
    touches: dict[int, Fingertip]


@dataclass
class _Finger:
    x: float  # where the last rendered frame put it
    y: float
    force: float
    target: Fingertip
    rate: float = 0.0  # N per frame toward the target force
    anchor_t: float = 0.0  # stream time of the sample that last placed it
    lifted_frames: int = 0  # frames since its force reached zero (the hover tail)
    ramped: bool = False  # its force reached the target (landed, no lift under way)

    def aim(self, target: Fingertip, frames_per_ramp: float) -> None:
        if target.force_n != self.target.force_n or self.rate == 0.0:
            change = max(abs(target.force_n - self.force), 0.05)
            self.rate = change / max(1.0, frames_per_ramp)
        self.target = target


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
        idle_s: tuple[float, float] = (0.3, 1.5),
        invalid_fraction: float = 0.25,
        physics: SkinPhysics | None = None,
        person: Person | None = None,
        sample_rate_hz: float = DEFAULT_SAMPLE_RATE_HZ,
        max_batch: int = 200,
        autonomous: bool = True,
        lookahead_s: float = _LOOKAHEAD_S,
    ) -> None:
        """``max_batch``: most frames one :meth:`poll` returns when ``speed=0``;
        ``autonomous=False``: the person rests and acts only on :meth:`perform` requests;
        ``lookahead_s``: seconds of frames rendered ahead of the wall clock."""
        if not np.isfinite(speed) or speed < 0:
            raise ValueError(f"sim speed must be >= 0 (0 = as fast as polled), got {speed}")
        if not np.isfinite(lookahead_s) or not 0.005 <= lookahead_s <= 5.0:
            raise ValueError(f"sim lookahead must be 0.005-5 s, got {lookahead_s}")
        self.lookahead_s = float(lookahead_s)
        self.seed = int(seed) if seed is not None else int(np.random.SeedSequence().entropy % 2**31)
        self.speed = float(speed)
        self.autonomous = bool(autonomous)
        self.max_batch = max(1, int(max_batch))
        self.layout = layout if layout is not None else SkinLayout()
        fs = float(sample_rate_hz)
        rng = np.random.default_rng(self.seed)
        # A typical skin by default: a demonstration should not land on the dullest skin
        # the simulator can draw (pass ``physics`` for any other).
        self.physics = physics if physics is not None else SkinPhysics.sample_typical(rng)
        self.person = person if person is not None else Person.sample(rng)
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
        self._paused_at = 0.0
        self._fingers: dict[int, _Finger] = {}  # outside fingertips (set_touches)
        self._touch_timeline: deque[_TouchSample] = deque()  # samples not yet reached
        self._touch_offset: float | None = None  # stream time = client time + offset
        self._touch_client_t: float | None = None  # sender's time of the newest sample
        self._touch_still = False  # the newest sample repeated the one before (a rest)
        self._touch_trail: dict[int, list[tuple[float, float]]] = {}  # last 2 positions each
        self._performing: _Performing | None = None  # a performance still being rendered

    # -- construction from a spec -------------------------------------------------------------
    @classmethod
    def from_options(cls, options: dict[str, str]) -> SimulatedSkinSource:
        """Build from ``open_source`` options (all values are strings); see :data:`OPTIONS`."""
        options = dict(options)
        # "sim:gestures=swipe_up,push" arrives split at the comma: gather stray class names.
        stray = [k for k, v in options.items() if k.partition(":")[0] in CLASS_NAMES and v == ""]
        for k in stray:
            del options[k]
        unknown = sorted(set(options) - set(OPTIONS))
        if unknown:
            raise ValueError(f"unknown sim option(s) {unknown}; known: {', '.join(OPTIONS)}")

        def number(key: str, kind, default):
            if key not in options or options[key] == "":
                return default
            try:
                return kind(options[key])
            except ValueError:
                raise ValueError(
                    f"sim option {key} must be a number, got {options[key]!r}"
                ) from None

        gestures = None
        if "gestures" in options or stray:
            text = options.get("gestures", "")
            for sep in "+|;/":
                text = text.replace(sep, ",")
            gestures = [g.strip() for g in text.split(",") if g.strip()] + stray
            for g in gestures:
                parse_request(g)
        idle = (0.3, 1.5)
        if options.get("idle"):
            parts = options["idle"].replace("..", "-").split("-")
            try:
                values = [float(p) for p in parts if p.strip()]
            except ValueError:
                raise ValueError(
                    f"sim option idle must be SECONDS or LOW-HIGH, got {options['idle']!r}"
                ) from None
            if len(values) not in (1, 2):
                raise ValueError(
                    f"sim option idle must be SECONDS or LOW-HIGH, got {options['idle']!r}"
                )
            idle = (values[0], values[-1])
        layout = SkinLayout(
            rows=number("rows", int, 10),
            cols=number("cols", int, 10),
            row_pitch_mm=number("row_pitch", float, DEFAULT_ROW_PITCH_MM),
            col_pitch_mm=number("col_pitch", float, DEFAULT_COL_PITCH_MM),
        )
        return cls(
            seed=number("seed", int, None),
            speed=number("speed", float, 1.0),
            layout=layout,
            gestures=gestures,
            idle_s=idle,
            invalid_fraction=number("invalid", float, 0.25),
            autonomous=bool(number("auto", int, 1)),
            lookahead_s=number("lookahead", float, _LOOKAHEAD_S),
        )

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
            self._clock_origin = time.monotonic()
            self._stop.clear()
            self._stats.connected = True
            self._notices.append(
                SourceEvent("connected", "simulated skin started", time.monotonic(), self._info)
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
                now = time.monotonic()
                due = self._due_frames(now)
                while self._buffer and self._delivered < due:
                    values = self._buffer.popleft()
                    seq = self._delivered
                    out.append(Frame(seq=seq, t=seq / self._fs, values=values, t_host=now))
                    self._delivered += 1
                    self._stats.good_frames += 1
                if out:
                    self._cond.notify_all()  # the producer may top up the buffer
                    return out
                if now >= deadline or self._stop.is_set():
                    return out
                self._cond.wait(min(deadline - now, self._wait_hint(now)))

    def stats(self) -> SourceStats:
        with self._cond:
            return self._stats.copy()

    def send_command(self, command: str) -> None:
        """``stop`` pauses the stream (and its clock), ``start`` resumes; ``recalibrate``: no-op."""
        command = command.strip().lower()
        with self._cond:
            if command == "stop" and not self._paused:
                self._paused, self._paused_at = True, time.monotonic()
            elif command == "start" and self._paused:
                self._paused = False
                self._clock_origin += time.monotonic() - self._paused_at
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
    def perform(self, name: str) -> None:
        """Queue ``name`` (a class name, or ``invalid:KIND``) as the person's next event."""
        parse_request(name)
        with self._cond:
            self._requests.append(name)
            self._cond.notify_all()

    def set_touches(self, touches: dict[int, Fingertip], client_t: float | None = None) -> None:
        """Put outside fingertips on the skin: ``{pointer id: Fingertip}``, replacing the
        previous sample's.  Fingertips missing from ``touches`` lift off; new ones land.

        ``client_t`` (seconds on the sender's clock, e.g. a browser event's timestamp)
        keeps the sender's timing: samples are played :data:`TOUCH_JITTER_S` behind the
        first sample of a touch, at their own spacing, however bunched they arrive, and a
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
        if len(touches) > MAX_TOUCHES:
            raise ValueError(f"at most {MAX_TOUCHES} fingertips, got {len(touches)}")
        for key, tip in touches.items():
            if not isinstance(tip, Fingertip):
                raise ValueError(f"touch {key!r} is not a Fingertip: {tip!r}")
        if client_t is not None and not np.isfinite(client_t):
            raise ValueError(f"touch time must be finite, got {client_t}")
        capped = {
            key: replace(tip, force_n=min(float(tip.force_n), MAX_TOUCH_FORCE_N))
            for key, tip in touches.items()
        }
        with self._cond:
            head = self._rendered / self._fs  # stream time of the next frame to render
            last = self._touch_timeline[-1].t if self._touch_timeline else head
            if client_t is None:
                t = max(head, last)
            else:
                idle = not self._fingers and not self._touch_timeline
                if self._touch_offset is None or idle:  # a new touch: set the delay
                    self._touch_offset = head + TOUCH_JITTER_S - client_t
                t = client_t + self._touch_offset
                if t < head:  # later than the buffer allows: delay the rest of the touch
                    self._touch_offset += head - t
                    t = head
                elif t > max(head, last) + MAX_TOUCH_LEAD_S:  # the sender's clock jumped ahead:
                    self._touch_offset -= t - (head + TOUCH_JITTER_S)  # play from now, not then
                    t = head + TOUCH_JITTER_S
                t = self._stretch_starved(capped, client_t, t, head)
                t = max(t, last)
                self._touch_client_t = float(client_t)
                previous = self._touch_timeline[-1].touches if self._touch_timeline else None
                if previous is None:
                    previous = {key: finger.target for key, finger in self._fingers.items()}
                self._touch_still = not _changes(previous, capped)
                if idle:
                    self._touch_trail.clear()
                start = self._touch_timeline[-1].t if self._touch_timeline else max(
                    (finger.anchor_t for finger in self._fingers.values()), default=head
                )  # fmt: skip
                self._touch_timeline.extend(self._curve(previous, capped, max(start, head), t))
            self._follow_trail(capped)
            self._touch_timeline.append(_TouchSample(t, capped))
            self._cond.notify_all()

    def _stretch_starved(
        self, touches: dict[int, Fingertip], client_t: float, t: float, head: float
    ) -> float:
        """The stream time of a sample that moves fingertips which already stand at the
        previous sample (the sender is sparser than the play-out delay): the slide starts
        at ``head`` and lasts the samples' spacing (see :meth:`set_touches`).  The caller
        holds the lock."""
        previous = self._touch_client_t
        if previous is None or self._touch_timeline or not self._fingers:
            return t  # nothing waits: the sample is in time (or lands new fingertips)
        waiting = {key: finger.target for key, finger in self._fingers.items()}
        if not _changes(waiting, touches):  # a resting hand's heartbeat: nothing to rebuild
            return t
        # After a rest (the previous sample repeated the one before: a heartbeat) the gap
        # says nothing about when the hand started again: it moves over a short segment.
        longest = _RESUME_SEGMENT_S if self._touch_still else MAX_TOUCH_SEGMENT_S
        spacing = min(max(float(client_t) - previous, 0.0), longest)
        if t >= head + spacing:
            return t
        for finger in self._fingers.values():
            finger.anchor_t = head  # it stood at its target until now; slides from here
        assert self._touch_offset is not None
        self._touch_offset += head + spacing - t
        return head + spacing

    def _curve(
        self, before: dict[int, Fingertip], touches: dict[int, Fingertip], start: float, end: float
    ) -> list[_TouchSample]:
        """Samples between ``start`` and ``end`` (stream times of ``before`` and ``touches``)
        on the curve through each fingertip's last three positions (see :meth:`set_touches`);
        none unless the same fingertips press throughout and one of them curves.  The caller
        holds the lock."""
        n = int((end - start) / _TOUCH_CURVE_STEP_S + 1e-9)
        if n < 2 or set(before) != set(touches):
            return []
        u = np.arange(1, n) / n  # the fraction of the segment, evenly in time
        paths: dict[int, np.ndarray] = {}
        curved = False
        for key, tip in touches.items():
            old = before[key]
            if old.force_n <= 0.0 or tip.force_n <= 0.0:
                return []
            p1, p2 = np.array([old.x_mm, old.y_mm]), np.array([tip.x_mm, tip.y_mm])
            paths[key] = p1 + np.outer(u, p2 - p1)  # the chord, unless the trail says more
            trail = self._touch_trail.get(key, [])
            if len(trail) < 2 or trail[-1] != (old.x_mm, old.y_mm):
                continue
            p0 = np.array(trail[0])
            d1, d2 = float(np.linalg.norm(p1 - p0)), float(np.linalg.norm(p2 - p1))
            if d1 < _TOUCH_MOVED_MM or d2 < _TOUCH_MOVED_MM:
                continue
            s = d1 + u * d2  # chord-length knots 0, d1, d1 + d2: Lagrange weights
            w0 = (s - d1) * (s - d1 - d2) / (d1 * (d1 + d2))
            w1 = -s * (s - d1 - d2) / (d1 * d2)
            w2 = s * (s - d1) / ((d1 + d2) * d2)
            paths[key] = np.outer(w0, p0) + np.outer(w1, p1) + np.outer(w2, p2)
            curved = True
        if not curved:
            return []
        samples = []
        for i, f in enumerate(u):
            tips = {
                key: Fingertip(
                    float(paths[key][i, 0]),
                    float(paths[key][i, 1]),
                    before[key].force_n + (tip.force_n - before[key].force_n) * float(f),
                )
                for key, tip in touches.items()
            }
            samples.append(_TouchSample(start + (end - start) * float(f), tips))
        return samples

    def _follow_trail(self, touches: dict[int, Fingertip]) -> None:
        """Remember each fingertip's last two positions for :meth:`_curve`; one that stays
        put (a rest) starts its trail again.  The caller holds the lock."""
        trail = {}
        for key, tip in touches.items():
            point = (tip.x_mm, tip.y_mm)
            old = self._touch_trail.get(key, [])
            if old and np.hypot(point[0] - old[-1][0], point[1] - old[-1][1]) < _TOUCH_MOVED_MM:
                trail[key] = [point]
            else:
                trail[key] = [*old[-1:], point]
        self._touch_trail = trail

    @property
    def touching(self) -> bool:
        """Whether outside fingertips are on the skin (or still lifting off or queued)."""
        with self._cond:
            return bool(self._fingers or self._touch_timeline)

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

    def _wait_hint(self, now: float) -> float:
        if self.speed == 0 or self._paused:
            return 0.05
        next_due = self._clock_origin + self._delivered / (self.speed * self._fs)
        return max(0.001, next_due - now)

    def _render_target(self) -> int:
        if self.speed == 0:
            return self._delivered + int(_UNPACED_BUFFER_S * self._fs)
        ahead = max(1, int(self.lookahead_s * self.speed * self._fs))
        return self._due_frames(time.monotonic()) + ahead

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
                self._notices.append(SourceEvent("error", message, time.monotonic()))
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
            touching = bool(self._fingers or self._touch_timeline)
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
        """``n`` frames of the outside fingertips: samples take effect at their stream time,
        each fingertip slides linearly toward its position in the next sample and ramps its
        force toward the newest force.  As with a real hand, the skin senses a fingertip a
        little before it lands (queued samples tell where and when) and after it lifts
        (it stays for a few hover time constants, then goes)."""
        fs = self._fs
        ramp = _TOUCH_RAMP_S * fs
        hover = max(1e-9, self.physics.hover_tau_s * fs)  # frames
        tail = int(np.ceil(_HOVER_TAIL_TAUS * hover))
        paths: dict[int, np.ndarray] = {}  # finger -> (n, 4): x, y, force, presence
        with self._cond:
            for k in range(n):
                t = (self._rendered + k) / fs
                while self._touch_timeline and self._touch_timeline[0].t <= t:
                    self._apply_sample(self._touch_timeline.popleft(), ramp)
                upcoming = self._touch_timeline[0] if self._touch_timeline else None
                for key, finger in self._fingers.items():
                    nxt = upcoming.touches.get(key) if upcoming is not None else None
                    force = None  # a pressing fingertip's force on its way to the next sample
                    if nxt is not None and upcoming.t > finger.anchor_t:
                        f = (t - finger.anchor_t) / (upcoming.t - finger.anchor_t)
                        f = min(max(f, 0.0), 1.0)
                        x = finger.target.x_mm + (nxt.x_mm - finger.target.x_mm) * f
                        y = finger.target.y_mm + (nxt.y_mm - finger.target.y_mm) * f
                        now_n, next_n = finger.target.force_n, nxt.force_n
                        if finger.ramped and now_n > 0 and next_n > 0:
                            force = now_n + (next_n - now_n) * f
                    else:
                        x, y = finger.target.x_mm, finger.target.y_mm
                    if force is None:  # landing, lifting, or no next sample: the force ramp
                        step = float(np.clip(finger.target.force_n - finger.force, -finger.rate,
                                             finger.rate))  # fmt: skip
                        force = max(0.0, finger.force + step)
                        finger.ramped = abs(force - finger.target.force_n) < 1e-9
                    finger.x, finger.y, finger.force = x, y, force
                    if finger.force > 0.0:
                        finger.lifted_frames = 0
                    elif finger.target.force_n == 0.0:
                        finger.lifted_frames += 1
                    presence = np.exp(-finger.lifted_frames / hover)
                    paths.setdefault(key, np.zeros((n, 4)))[k] = (x, y, finger.force, presence)
                for key, landing_t, tip in self._landings():
                    if key not in self._fingers:  # the hand approaches: sensed before contact
                        presence = np.exp(-(landing_t - t) * fs / hover)
                        paths.setdefault(key, np.zeros((n, 4)))[k] = (tip.x_mm, tip.y_mm, 0.0,
                                                                     presence)  # fmt: skip
                for key in [k2 for k2, f2 in self._fingers.items() if f2.lifted_frames > tail]:
                    del self._fingers[key]
        tracks = []
        for path in paths.values():
            major, minor = _VIRTUAL_PAD.axes_mm(path[:, 2])
            tracks.append(
                ContactTrack(path[:, 0], path[:, 1], path[:, 2], major, minor, presence=path[:, 3])
            )
        return self._model.render(tracks, n)

    def _landings(self) -> list[tuple[int, float, Fingertip]]:
        """Fingertips that queued samples will land, with when and where they first touch."""
        seen: dict[int, tuple[int, float, Fingertip]] = {}
        for sample in self._touch_timeline:
            for key, tip in sample.touches.items():
                if key not in seen and tip.force_n > 0:
                    seen[key] = (key, sample.t, tip)
        return list(seen.values())

    def _apply_sample(self, sample: _TouchSample, ramp: float) -> None:
        """Make ``sample`` the fingertips' targets (caller holds the lock)."""
        for key, finger in self._fingers.items():
            if key not in sample.touches:
                finger.aim(replace(finger.target, force_n=0.0), ramp)
                finger.anchor_t = sample.t
        for key, tip in sample.touches.items():
            finger = self._fingers.get(key)
            if finger is None:
                finger = self._fingers[key] = _Finger(tip.x_mm, tip.y_mm, 0.0, tip)
            finger.aim(tip, ramp)
            finger.anchor_t = sample.t
