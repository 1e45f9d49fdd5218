"""Fingertips put on the simulated skin from outside (the dashboard's virtual skin).

:class:`OutsideTouches` keeps the timeline of :class:`Fingertip` samples and turns it into
contact tracks for :class:`~wovenskin.sim.physics.SkinModel`, frame by frame on the stream
clock: fingertips land over a short force ramp and lift at once (the sender reports a lift
when the fingertip has left), slide between samples (along the curve through sparse ones)
and are sensed a little before landing and, for a few milliseconds, after lifting.
:meth:`wovenskin.sim.live.SimulatedSkinSource.set_touches` says how the timing works.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, replace

import numpy as np

from wovenskin.sim.contact import ContactTrack
from wovenskin.sim.person import Pad
from wovenskin.sim.physics import LIFT_HOVER_TAU_S

_TOUCH_RAMP_S = 0.02  # an outside fingertip reaches its force over this time (a lift: 1 frame)
MAX_TOUCH_FORCE_N = 10.0
MAX_TOUCHES = 10
_HOVER_TAIL_TAUS = 4.0  # a lifted outside fingertip is sensed for this many lift constants
TOUCH_JITTER_S = 0.03  # timestamped outside touches play at least this far behind their first
MAX_TOUCH_JITTER_S = 0.3  # sample, and after late samples at most this far (see OutsideTouches)
TOUCH_JITTER_MEMORY_S = 30.0  # a late sample's extra delay fades over this much stream time
SLOW_STREAM_S = 0.1  # a touch may fall this far behind the wall clock before it is pulled in
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


def checked_touches(touches: dict[int, Fingertip], client_t: float | None) -> dict[int, Fingertip]:
    """``touches`` with forces capped at :data:`MAX_TOUCH_FORCE_N`; ``ValueError`` for more
    than :data:`MAX_TOUCHES` fingertips, values that are not fingertips or a non-finite
    ``client_t``."""
    if len(touches) > MAX_TOUCHES:
        raise ValueError(f"at most {MAX_TOUCHES} fingertips, got {len(touches)}")
    for key, tip in touches.items():
        if not isinstance(tip, Fingertip):
            raise ValueError(f"touch {key!r} is not a Fingertip: {tip!r}")
    if client_t is not None and not np.isfinite(client_t):
        raise ValueError(f"touch time must be finite, got {client_t}")
    return {
        key: replace(tip, force_n=min(float(tip.force_n), MAX_TOUCH_FORCE_N))
        for key, tip in touches.items()
    }


class OutsideTouches:
    """The outside fingertips of one simulated skin: queued samples and the fingertips on
    the skin.  The caller (the source) holds its lock around every call.

    The play-out delay is adaptive, as in a voice-over-IP jitter buffer: a touch starts
    :attr:`jitter_s` behind its first sample; a sample that arrives later than its turn
    delays the rest of that touch (no jump) and raises :attr:`jitter_s` by its lateness
    (up to :data:`MAX_TOUCH_JITTER_S`), so the next touches from a sender that stalls (a
    busy page held up 100-400 ms) play intact rather than broken into pieces; the extra
    delay fades over :data:`TOUCH_JITTER_MEMORY_S` of stream time once the sender keeps
    time again.  Delays change only between touches, never inside one.

    Lift-off is the exception, because it stops the arm: when the stream renders slower than
    the wall clock (a starved session: the simulated world runs slow), a long touch builds
    up a lead over the stream and its lift-off would play seconds after the person lifted.
    A lift-off (no fingertips left) is brought forward by how far the stream fell behind the
    wall clock since the touch began, less :data:`SLOW_STREAM_S`, and queued samples after it
    are dropped: lifting stops the arm as promptly as the stream allows."""

    def __init__(self, fs: float, hover_tau_s: float) -> None:
        self.fs = float(fs)
        self.hover_tau_s = float(hover_tau_s)
        self.fingers: dict[int, _Finger] = {}  # fingertips on the skin (or lifting off)
        self.timeline: deque[_TouchSample] = deque()  # samples not yet reached
        self._offset: float | None = None  # stream time = client time + offset
        self._client_t: float | None = None  # sender's time of the newest sample
        self._still = False  # the newest sample repeated the one before (a rest)
        self._moved_t: float | None = None  # sender's time of the last sample that moved
        self._trail: dict[int, list[tuple[float, float]]] = {}  # last 2 positions each
        self.jitter_s = TOUCH_JITTER_S  # the play-out delay a new touch starts with
        self._jitter_at = 0.0  # stream time when jitter_s was last raised
        self._touch_delay = TOUCH_JITTER_S  # the touch under way plays this far behind
        self._wall_anchor: tuple[float, float] | None = None  # (wall, head) at touch start

    @property
    def active(self) -> bool:
        """Whether fingertips are on the skin (or still lifting off or queued)."""
        return bool(self.fingers or self.timeline)

    def add(
        self,
        capped: dict[int, Fingertip],
        client_t: float | None,
        head: float,
        wall: float | None = None,
    ) -> None:
        """Queue the sample ``capped`` (from :func:`checked_touches`); ``head`` is the stream
        time of the next frame to render, ``wall`` the receiver's clock (s, monotonic) when
        the sample arrived (None: the stream is taken to keep time)."""
        last = self.timeline[-1].t if self.timeline else head
        if client_t is None:
            t = max(head, last)
        else:
            idle = not self.fingers and not self.timeline
            if self._offset is None or idle:  # a new touch: set the delay
                self._touch_delay = self._playout_delay(head)
                self._offset = head + self._touch_delay - client_t
                self._wall_anchor = None if wall is None else (float(wall), head)
            t = client_t + self._offset
            if t < head:  # later than the buffer allows: delay the rest of the touch
                self._raise_jitter(head - t, head)
                self._offset += head - t
                t = head
            elif t > max(head, last) + MAX_TOUCH_LEAD_S:  # the sender's clock jumped ahead:
                self._offset -= t - (head + TOUCH_JITTER_S)  # play from now, not then
                t = head + TOUCH_JITTER_S
            t = self._stretch_starved(capped, client_t, t, head)
            if not capped:
                t = self._lift_now(t, head, wall, float(client_t))
                last = self.timeline[-1].t if self.timeline else head
            t = max(t, last)
            self._client_t = float(client_t)
            previous = self.timeline[-1].touches if self.timeline else None
            if previous is None:
                previous = {key: finger.target for key, finger in self.fingers.items()}
            self._still = not _changes(previous, capped)
            if not self._still or set(previous) != set(capped) or idle:
                self._moved_t = float(client_t)
            if idle:
                self._trail.clear()
            start = self.timeline[-1].t if self.timeline else max(
                (finger.anchor_t for finger in self.fingers.values()), default=head
            )  # fmt: skip
            self.timeline.extend(self._curve(previous, capped, max(start, head), t))
        self._follow_trail(capped)
        self.timeline.append(_TouchSample(t, capped))

    def _lift_now(self, t: float, head: float, wall: float | None, client_t: float) -> float:
        """The stream time of a lift-off sample due at ``t``: earlier by how far the stream
        fell behind the wall clock since the touch began (less :data:`SLOW_STREAM_S`),
        and no later than the end of the motion still queued (a rest before a lift-off
        says nothing more: the play-out delay is there to keep a motion's shape, not to
        hold a resting finger down), never before ``head``; queued samples after it are
        dropped (class docstring).

        A hand that rested on the sender's clock for longer than the touch's play-out delay
        before lifting lifts at ``head``, the motion still queued dropped: the sender's
        samples came late and sparse (a busy page stretches each slide: see
        :meth:`_stretch_starved`), the stream fell that far behind the hand, and the
        motion it still has to play is one the person finished a rest ago.  The arm stops
        when the finger lifts, not 0.3-0.7 s later (measured in Chromium)."""
        rested = None if self._moved_t is None else client_t - self._moved_t
        if rested is not None and rested >= self._touch_delay:
            t = head
        if wall is not None and self._wall_anchor is not None:
            wall0, head0 = self._wall_anchor
            behind = (float(wall) - wall0) - (head - head0) - SLOW_STREAM_S
            if behind > 0.0:
                t = t - behind
        t = max(head, min(t, self._motion_end(head)))
        while self.timeline and self.timeline[-1].t > t:
            self.timeline.pop()
        return t

    def _motion_end(self, head: float) -> float:
        """The stream time of the last queued sample that moves or presses a fingertip
        (``head`` when only rests are queued)."""
        before = {key: finger.target for key, finger in self.fingers.items()}
        end = head
        for sample in self.timeline:
            if set(sample.touches) != set(before) or _changes(before, sample.touches):
                end = sample.t
            before = sample.touches
        return end

    def _playout_delay(self, head: float) -> float:
        """The delay a touch starting at stream time ``head`` plays behind its first sample:
        :attr:`jitter_s`, its excess over :data:`TOUCH_JITTER_S` faded since it was raised."""
        excess = self.jitter_s - TOUCH_JITTER_S
        fade = np.exp(-max(0.0, head - self._jitter_at) / TOUCH_JITTER_MEMORY_S)
        self.jitter_s = TOUCH_JITTER_S + excess * float(fade)
        self._jitter_at = head
        return self.jitter_s

    def _raise_jitter(self, lateness: float, head: float) -> None:
        """A sample came ``lateness`` seconds after its turn: the touch under way plays that
        much later, and so do the next touches (at most :data:`MAX_TOUCH_JITTER_S`)."""
        self._touch_delay += lateness
        self.jitter_s = min(MAX_TOUCH_JITTER_S, max(self.jitter_s, self._touch_delay))
        self._jitter_at = head

    def _stretch_starved(
        self, touches: dict[int, Fingertip], client_t: float, t: float, head: float
    ) -> float:
        """The stream time of a sample that moves fingertips which already stand at the
        previous sample (the sender is sparser than the play-out delay): the slide starts
        at ``head`` and lasts the samples' spacing, or longer if the sample is due later (see
        :meth:`~wovenskin.sim.live.SimulatedSkinSource.set_touches`).  It never starts when
        the fingertips reached the previous sample: the frames since show them standing
        there, so a slide timed from then would jump to where it had got by ``head``."""
        previous = self._client_t
        if previous is None or self.timeline or not self.fingers:
            return t  # nothing waits: the sample is in time (or lands new fingertips)
        waiting = {key: finger.target for key, finger in self.fingers.items()}
        if not _changes(waiting, touches):  # a resting hand's heartbeat: nothing to rebuild
            return t
        # After a rest (the previous sample repeated the one before: a heartbeat) the gap
        # says nothing about when the hand started again: it moves over a short segment.
        longest = _RESUME_SEGMENT_S if self._still else MAX_TOUCH_SEGMENT_S
        spacing = min(max(float(client_t) - previous, 0.0), longest)
        for finger in self.fingers.values():
            finger.anchor_t = head  # it stood at its target until now; slides from here
        if t >= head + spacing:
            return t
        assert self._offset is not None
        self._offset += head + spacing - t
        return head + spacing

    def _curve(
        self, before: dict[int, Fingertip], touches: dict[int, Fingertip], start: float, end: float
    ) -> list[_TouchSample]:
        """Samples between ``start`` and ``end`` (stream times of ``before`` and ``touches``)
        on the curve through each fingertip's last three positions (see ``set_touches``);
        none unless the same fingertips press throughout and one of them curves."""
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
            trail = self._trail.get(key, [])
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
        put (a rest) starts its trail again."""
        trail = {}
        for key, tip in touches.items():
            point = (tip.x_mm, tip.y_mm)
            old = self._trail.get(key, [])
            if old and np.hypot(point[0] - old[-1][0], point[1] - old[-1][1]) < _TOUCH_MOVED_MM:
                trail[key] = [point]
            else:
                trail[key] = [*old[-1:], point]
        self._trail = trail

    def tracks(self, first: int, n: int) -> list[ContactTrack]:
        """Contact tracks of the outside fingertips over ``n`` frames from stream frame
        ``first``: samples take effect at their stream time,
        each fingertip slides linearly toward its position in the next sample and ramps its
        force toward the newest force.  As with a real hand, the skin senses a fingertip a
        little before it lands (queued samples tell where and when) and after it lifts
        (its coupling fades with :data:`~wovenskin.sim.physics.LIFT_HOVER_TAU_S`: it stays
        for a few of those, then goes).  A lift-off plays at once: the force is gone in the
        next frame, since the sender reports a lift when the fingertip has left."""
        fs = self.fs
        ramp = _TOUCH_RAMP_S * fs
        hover = max(1e-9, self.hover_tau_s * fs)  # frames
        lift = max(1e-9, min(self.hover_tau_s, LIFT_HOVER_TAU_S) * fs)
        tail = int(np.ceil(_HOVER_TAIL_TAUS * lift))
        paths: dict[int, np.ndarray] = {}  # finger -> (n, 4): x, y, force, presence
        for k in range(n):
            t = (first + k) / fs
            while self.timeline and self.timeline[0].t <= t:
                self._apply_sample(self.timeline.popleft(), ramp)
            upcoming = self.timeline[0] if self.timeline else None
            for key, finger in self.fingers.items():
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
                presence = np.exp(-finger.lifted_frames / lift)
                paths.setdefault(key, np.zeros((n, 4)))[k] = (x, y, finger.force, presence)
            for key, landing_t, tip in self._landings():
                if key not in self.fingers:  # the hand approaches: sensed before contact
                    presence = np.exp(-(landing_t - t) * fs / hover)
                    paths.setdefault(key, np.zeros((n, 4)))[k] = (tip.x_mm, tip.y_mm, 0.0,
                                                                 presence)  # fmt: skip
            for key in [k2 for k2, f2 in self.fingers.items() if f2.lifted_frames > tail]:
                del self.fingers[key]
        tracks = []
        for path in paths.values():
            major, minor = _VIRTUAL_PAD.axes_mm(path[:, 2])
            tracks.append(
                ContactTrack(path[:, 0], path[:, 1], path[:, 2], major, minor, presence=path[:, 3])
            )
        return tracks

    def _landings(self) -> list[tuple[int, float, Fingertip]]:
        """Fingertips that queued samples will land, with when and where they first touch."""
        seen: dict[int, tuple[int, float, Fingertip]] = {}
        for sample in self.timeline:
            for key, tip in sample.touches.items():
                if key not in seen and tip.force_n > 0:
                    seen[key] = (key, sample.t, tip)
        return list(seen.values())

    def _apply_sample(self, sample: _TouchSample, ramp: float) -> None:
        """Make ``sample`` the fingertips' targets ."""
        for key, finger in self.fingers.items():
            if key not in sample.touches:
                finger.aim(replace(finger.target, force_n=0.0), 1.0)  # lifted: gone at once
                finger.anchor_t = sample.t
        for key, tip in sample.touches.items():
            finger = self.fingers.get(key)
            if finger is None:
                finger = self.fingers[key] = _Finger(tip.x_mm, tip.y_mm, 0.0, tip)
            finger.aim(tip, ramp if tip.force_n > 0 else 1.0)
            finger.anchor_t = sample.t
