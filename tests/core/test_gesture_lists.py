"""Every list of gestures outside the vocabulary follows it: a new gesture cannot be
silently left out of the keyboard's layout or of what the dashboard's mouse bench draws."""

from __future__ import annotations

from wovenskin.bench.dashboard import MOUSE_GESTURES
from wovenskin.gestures import GESTURE_NAMES, GESTURES
from wovenskin.teleop.keyboard import DEFAULT_LAYOUT, check_layout


def test_the_keyboard_has_a_key_for_every_gesture_and_no_other():
    assert sorted(check_layout(DEFAULT_LAYOUT).values()) == sorted(GESTURE_NAMES)


def test_the_mouse_bench_draws_every_gesture_but_the_pinches():
    pinches = {g.name for g in GESTURES if g.motion == "pinch"}
    assert pinches == {"pinch_in_2f", "pinch_in_5f", "pinch_out_5f"}
    assert set(MOUSE_GESTURES) == set(GESTURE_NAMES) - pinches
    assert list(MOUSE_GESTURES) == [n for n in GESTURE_NAMES if n not in pinches]  # doc order
