"""Tests of the outside fingertips' timeline (wovenskin.sim.live_touches): the adaptive
play-out delay, checked on stream times alone (no threads, no clocks)."""

from __future__ import annotations

import pytest

from wovenskin.sim.live_touches import (
    MAX_TOUCH_JITTER_S,
    SLOW_STREAM_S,
    TOUCH_JITTER_MEMORY_S,
    TOUCH_JITTER_S,
    Fingertip,
    OutsideTouches,
)

FS = 200.0


def _touch(touches: OutsideTouches, head: float, client_t0: float, late_s: float = 0.0) -> float:
    """One 0.2 s press at the sender's ``client_t0`` whose second half arrives ``late_s`` after
    its turn; renders it out and returns the stream time its first sample was given."""
    tip = Fingertip(50.0, 50.0, 1.5)
    touches.add({1: tip}, client_t0, head)
    first = touches.timeline[0].t
    touches.add({1: tip}, client_t0 + 0.1, first + 0.1 + late_s)  # arrives late_s late
    touches.add({}, client_t0 + 0.2, first + 0.2 + late_s)
    frames = int(round((touches.timeline[-1].t + 1.0) * FS))
    start = int(round(head * FS))
    touches.tracks(start, frames - start)  # play it all out: the fingertip lifts and goes
    assert not touches.active
    return first


def test_a_touch_starts_the_base_delay_behind_its_first_sample():
    touches = OutsideTouches(FS, hover_tau_s=0.01)
    first = _touch(touches, head=1.0, client_t0=500.0)
    assert first == pytest.approx(1.0 + TOUCH_JITTER_S)


def test_a_late_sample_makes_the_next_touch_wait_longer():
    touches = OutsideTouches(FS, hover_tau_s=0.01)
    _touch(touches, head=1.0, client_t0=500.0, late_s=0.2)
    first = _touch(touches, head=3.0, client_t0=502.0)
    delay = first - 3.0  # 0.2 s more, faded a little over the ~1.7 s since it was late
    assert TOUCH_JITTER_S + 0.18 < delay <= TOUCH_JITTER_S + 0.2


def test_the_extra_delay_fades_once_the_sender_keeps_time():
    touches = OutsideTouches(FS, hover_tau_s=0.01)
    _touch(touches, head=1.0, client_t0=500.0, late_s=0.2)
    first = _touch(touches, head=1.0 + 5 * TOUCH_JITTER_MEMORY_S, client_t0=900.0)
    assert first - (1.0 + 5 * TOUCH_JITTER_MEMORY_S) < TOUCH_JITTER_S + 0.2 * 0.01


def test_the_delay_never_grows_past_its_cap():
    touches = OutsideTouches(FS, hover_tau_s=0.01)
    _touch(touches, head=1.0, client_t0=500.0, late_s=5.0)
    assert touches.jitter_s == pytest.approx(MAX_TOUCH_JITTER_S)
    first = _touch(touches, head=20.0, client_t0=600.0)
    assert first - 20.0 <= MAX_TOUCH_JITTER_S + 1e-9


def test_a_stream_slower_than_the_wall_clock_never_holds_back_a_lift_off():
    """The session renders at half speed: without being brought forward, the lift sent
    after 2 s would play a second of stream time after the stream reached it."""
    touches = OutsideTouches(FS, hover_tau_s=0.01)
    tip = Fingertip(50.0, 50.0, 1.5)
    head, wall, client = 1.0, 100.0, 500.0
    touches.add({1: tip}, client, head, wall)
    for k in range(1, 21):  # 2 s of a resting finger (heartbeats), the stream at half speed
        touches.add({1: tip}, client + 0.1 * k, head + 0.05 * k, wall + 0.1 * k)
    head_now = head + 0.05 * 20
    touches.add({}, client + 2.05, head_now, wall + 2.05)
    lift = touches.timeline[-1].t
    assert lift - head_now <= SLOW_STREAM_S + TOUCH_JITTER_S + 1e-9
    assert all(sample.t <= lift for sample in touches.timeline)  # nothing queued after it


def test_a_slow_stream_keeps_the_spacing_of_moving_samples():
    touches = OutsideTouches(FS, hover_tau_s=0.01)
    head, wall, client = 1.0, 100.0, 500.0
    for k in range(21):  # a slide sent live over 2 s while the stream renders half speed
        touches.add({1: Fingertip(50.0, 20.0 + 4 * k, 1.5)}, client + 0.1 * k,
                    head + 0.05 * k, wall + 0.1 * k)  # fmt: skip
    times = [sample.t for sample in touches.timeline if sample.touches]
    assert times[-1] - times[0] == pytest.approx(2.0)


def test_samples_that_arrive_together_keep_their_spacing():
    touches = OutsideTouches(FS, hover_tau_s=0.01)
    for k in range(41):  # 0.4 s of drawing delivered at one instant
        touches.add({1: Fingertip(50.0, 20.0 + k, 1.5)}, 500.0 + 0.01 * k, 1.0, 100.0)
    times = [sample.t for sample in touches.timeline]
    assert times[-1] - times[0] == pytest.approx(0.4)


def test_a_lift_off_after_a_rest_plays_at_once_whatever_the_play_out_delay():
    """The delay keeps a motion's shape; a finger that rests, then lifts, stops the arm as
    soon as the lift arrives, not a play-out delay later."""
    touches = OutsideTouches(FS, hover_tau_s=0.01)
    touches.jitter_s = MAX_TOUCH_JITTER_S  # a sender that was late before: 0.3 s behind
    tip = Fingertip(50.0, 50.0, 1.5)
    head, client = 1.0, 500.0
    touches.add({1: tip}, client, head)
    touches.tracks(int(head * FS), int(0.5 * FS))  # it landed and rests
    head += 0.5
    for k in range(1, 6):  # resting samples, queued MAX_TOUCH_JITTER_S behind
        touches.add({1: tip}, client + 0.5 + 0.01 * k, head)
    touches.add({}, client + 0.56, head)
    assert touches.timeline[-1].t == pytest.approx(head)
    assert [sample.touches for sample in touches.timeline] == [{}]  # the rests are dropped


def test_a_lift_off_right_after_a_motion_plays_the_motion_first():
    touches = OutsideTouches(FS, hover_tau_s=0.01)
    head, client = 1.0, 500.0
    for k in range(21):  # a slide sent over 0.2 s, all of it still queued
        touches.add({1: Fingertip(50.0, 20.0 + 2 * k, 1.5)}, client + 0.01 * k, head)
    touches.add({}, client + 0.21, head)
    moving = [sample for sample in touches.timeline if sample.touches]
    assert moving[-1].touches[1].y_mm == pytest.approx(60.0)  # the whole slide plays
    assert moving[-1].t - moving[0].t == pytest.approx(0.2)
    assert touches.timeline[-1].t == pytest.approx(moving[-1].t)  # then the lift, at once


def test_a_lift_off_after_a_rest_drops_the_motion_a_late_sender_left_queued():
    """A busy page sends a slide late and sparse, and each stretched segment puts the
    stream further behind the hand; the hand then rests longer than the play-out delay and
    lifts: the lift plays at once, the stale rest of the slide is dropped."""
    touches = OutsideTouches(FS, hover_tau_s=0.01)
    head, client = 1.0, 500.0
    for k in range(21):  # a slide drawn over 0.2 s, still queued 0.4 s deep
        touches.add({1: Fingertip(50.0, 20.0 + 2 * k, 1.5)}, client + 0.01 * k, head)
    touches.timeline = type(touches.timeline)(
        type(sample)(head + 2 * (sample.t - head), sample.touches) for sample in touches.timeline
    )  # as stretched by a starved sender: the queue reaches 0.4 s past head
    for k in range(1, 4):  # the hand rests: the page's heartbeat repeats the last sample
        touches.add({1: Fingertip(50.0, 60.0, 1.5)}, client + 0.2 + 0.1 * k, head)
    touches.add({}, client + 0.55, head)  # it lifts 0.35 s after the slide ended
    assert touches.timeline[-1].t == pytest.approx(head)
    assert [sample.touches for sample in touches.timeline] == [{}]


def test_a_lift_off_plays_at_once():
    """The sender reports a lift when the fingertip has left: its force is gone in the
    next frame, and its fringe field a few frames later (no 20 ms ramp, no hover tail)."""
    touches = OutsideTouches(FS, hover_tau_s=0.05)
    touches.add({1: Fingertip(50.0, 50.0, 1.5)}, None, 0.0)
    track = touches.tracks(0, 40)[0]
    assert track.force_n[-1] == pytest.approx(1.5)
    touches.add({}, None, 40 / FS)
    after = touches.tracks(40, 20)
    assert after[0].force_n[0] == 0.0
    assert after[0].presence[4] < 0.5 and not touches.active
