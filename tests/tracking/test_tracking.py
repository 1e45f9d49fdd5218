"""Fingertips, tracks and the touch so far, on synthetic frames whose fingers the test places."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.touch_synth import COLS, CP, RATE, ROWS, RP, active_of, frame_of
from wovenskin.errors import ConfigError
from wovenskin.tracking.fingertips import FingertipSettings, find_fingertips
from wovenskin.tracking.touch import TouchReader, TouchSettings
from wovenskin.tracking.tracker import ContactTracker


def test_two_fingertips_far_apart_are_found_where_they_are() -> None:
    frame = frame_of([(30.0, 20.0), (90.0, 70.0)])
    found = find_fingertips(frame, active_of(frame), RP, CP)
    assert len(found) == 2
    got = sorted(zip(found.y.tolist(), found.x.tolist(), strict=True))
    for (gy, gx), (ty, tx) in zip(got, [(30.0, 20.0), (90.0, 70.0)], strict=True):
        assert math.hypot(gy - ty, gx - tx) < 4.0  # sub-channel: pitches are 14 and 10 mm


def test_one_round_fingertip_is_one_and_a_pair_in_one_blob_is_split() -> None:
    one = frame_of([(63.0, 45.0)])
    assert len(find_fingertips(one, active_of(one), RP, CP)) == 1
    pair = frame_of([(51.0, 45.0), (75.0, 45.0)], sd_mm=6.0)  # 24 mm apart down the rows
    found = find_fingertips(pair, active_of(pair), RP, CP)
    assert found.peak_count == 1 and len(found) == 2  # one peak, a body shaped like a pair
    assert abs(abs(found.y[0] - found.y[1]) - 24.0) < 4.0
    no_split = FingertipSettings(split_sd_mm=100.0)
    assert len(find_fingertips(pair, active_of(pair), RP, CP, no_split)) == 1


def test_nothing_active_is_no_fingertip_and_bad_settings_are_one_line() -> None:
    assert len(find_fingertips(np.zeros((ROWS, COLS)), np.zeros((ROWS, COLS), bool), RP, CP)) == 0
    with pytest.raises(ConfigError):
        FingertipSettings(saddle_ratio=0.0)
    with pytest.raises(ConfigError):
        TouchSettings(steady_rate=-1.0)


def test_tracks_keep_their_identities_while_they_move_and_a_new_finger_gets_a_new_one() -> None:
    tracker = ContactTracker(RATE)
    ids = None
    for k in range(40):
        tips = [(30.0 + k, 20.0), (100.0 - k, 70.0)]
        frame = frame_of(tips)
        tracks = tracker.step(find_fingertips(frame, active_of(frame), RP, CP))
        assert len(tracks) == 2
        now = sorted((round(t.y), t.id) for t in tracks)
        ids = ids or [i for _, i in now]
        if k < 30:  # before they cross rows
            assert [i for _, i in sorted((t.y, t.id) for t in tracks)] == ids
    frame = frame_of([(70.0, 20.0), (60.0, 70.0), (20.0, 90.0)])
    tracks = tracker.step(find_fingertips(frame, active_of(frame), RP, CP))
    assert len(tracks) == 3 and max(t.id for t in tracks) == 3
    assert tracker.step(None) == []


def _read(path: list[list[tuple[float, float]]], amps=None, sd_mm: float = 5.0) -> TouchReader:
    reader = TouchReader(ROWS, COLS, RP, CP, RATE)
    for k, tips in enumerate(path):
        frame = frame_of(tips, sd_mm=sd_mm, amp=0.05 if amps is None else amps[k])
        reader.step(frame, active_of(frame), True)
    return reader


def test_a_straight_stroke_up_has_coherent_travel_and_no_turning() -> None:
    reader = _read([[(110.0 - 0.5 * k, 45.0)] for k in range(100)])  # 50 mm up at 100 mm/s
    st = reader.state
    assert -55.0 < st.dy < -40.0 and abs(st.dx) < 3.0
    assert st.straightness > 0.9 and abs(st.turning) < 0.3
    assert st.sustained_fingertips == 1 and st.major_sd < 8.3


def test_a_clockwise_circle_turns_positive_and_an_anticlockwise_one_negative() -> None:
    def circle(sign: float) -> list[list[tuple[float, float]]]:
        return [
            [(63.0 + 22.0 * math.sin(sign * a), 45.0 + 22.0 * math.cos(sign * a))]
            for a in np.linspace(0.0, 3.0 * math.pi, 200)
        ]  # y down: increasing angle from +x toward +y is clockwise as the user sees it

    cw = _read(circle(1.0), sd_mm=7.0).state.turning / (2 * math.pi)  # 1.5 turns drawn
    ccw = _read(circle(-1.0), sd_mm=7.0).state.turning / (2 * math.pi)
    assert 1.2 < cw < 1.6 and -1.6 < ccw < -1.2
    assert _read(circle(1.0), sd_mm=7.0).state.straightness < 0.5


def test_a_press_in_place_raises_the_pressure_ratio_and_a_lift_resets() -> None:
    amps = np.linspace(0.01, 0.06, 80)
    reader = _read([[(63.0, 45.0)] for _ in range(80)], amps=amps)
    assert reader.state.max_press_ratio > 1.3 and reader.state.max_travel < 2.0
    assert reader.step(np.zeros((ROWS, COLS)), np.zeros((ROWS, COLS), bool), False) is None
    assert reader.state.frames == 0


def test_a_slow_press_counts_its_whole_rise_and_a_landing_ramp_is_no_press() -> None:
    """The rise is taken against the least pressure of the last press_span_s (0.4 s): a
    press that takes 0.3 s to double reads about 2, where 0.1 s ago it was only 1.3."""
    settled = [0.03] * 40  # 0.2 s after the landing, steady
    slow = list(np.linspace(0.03, 0.06, 60))  # doubles over 0.3 s
    reader = _read([[(63.0, 45.0)]] * 100, amps=settled + slow)
    assert reader.state.press_ratio > 1.8 and reader.state.max_travel < 2.0
    # a finger landing: its ramp (the first press_settle_s) is left out of the rise
    landing = list(np.linspace(0.005, 0.05, 16)) + [0.05] * 40
    assert _read([[(63.0, 45.0)]] * 56, amps=landing).state.max_press_ratio < 1.1


def test_a_finger_joining_the_touch_restarts_its_coherent_motion() -> None:
    """The centroid jumps half-way toward a second fingertip that lands beside the first;
    none of that counts as motion, and the pair's stroke is measured from the join."""
    one = [[(100.0, 30.0)]] * 30
    pair = [[(100.0 - 0.4 * k, 30.0), (100.0 - 0.4 * k, 48.0)] for k in range(60)]  # 24 mm up
    ramp = list(np.linspace(0.005, 0.05, 10)) + [0.05] * 50

    def read(settings: TouchSettings | None = None) -> TouchReader:
        reader = TouchReader(ROWS, COLS, RP, CP, RATE, settings)
        for k, tips in enumerate(one + pair):
            if k < 30:
                frame = frame_of(tips)
            else:  # the second fingertip presses in over 50 ms
                frame = frame_of(tips[:1]) + frame_of(tips[1:], amp=ramp[k - 30])
            reader.step(frame, active_of(frame), True)
        return reader

    st, before = read().state, read(TouchSettings(rebase_fingers=0)).state
    assert st.sustained_fingertips == 2
    assert abs(st.dx) < 1.5 and abs(before.dx) > 3.0  # the jump toward the finger: no motion
    assert -26.0 < st.dy < -15.0
    assert abs(st.turning) < 0.2 < abs(before.turning)  # radians: the stroke turns no more


def test_a_blob_split_in_two_is_two_fingertips_but_one_peak() -> None:
    """The finger evidence counts distinct peaks: a broad fingertip split by its shape
    must not count as two fingers twice (its length already counts once)."""
    pair = [(51.0, 45.0), (75.0, 45.0)]  # 24 mm apart: one blob, one peak, split in two
    merged = _read([pair] * 20, sd_mm=6.0).state
    assert merged.sustained_fingertips == 2 and merged.sustained_peaks == 1
    apart = _read([[(30.0, 20.0), (90.0, 70.0)]] * 20).state  # two peaks of their own
    assert apart.sustained_fingertips == 2 and apart.sustained_peaks == 2
