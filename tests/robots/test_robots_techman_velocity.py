"""Tests for the velocity-mode timeouts and the messages that explain a refusal."""

from __future__ import annotations

import pytest

from wovenskin.robots.techman.velocity import VelocityTimeouts, enter_refused, stream_refused


def test_default_timeouts_and_the_line_that_enters_the_mode() -> None:
    timeouts = VelocityTimeouts()
    assert (timeouts.zero_velocity_ms, timeouts.stop_ms) == (300, 2000)
    assert timeouts.enter_script() == "ContinueVLine(300,2000)"  # two timeouts in ms
    assert timeouts.zero_velocity_s == 0.3 and timeouts.stop_s == 2.0
    assert timeouts.reenter_after_s == 1.0
    assert timeouts.keepalive_s * 1000 <= timeouts.zero_velocity_ms / 2


@pytest.mark.parametrize(
    ("zero", "stop", "keep", "words"),
    [
        (300, 300, 0.1, "zero-velocity < stop"),
        (20, 2000, 0.005, "50 <= zero-velocity"),
        (300, 90_000, 0.1, "stop <= 60000"),
        (300, 2000, 0.2, "at most half"),
        (300, 2000, 0.0, "positive"),
        (300.5, 2000, 0.1, "whole milliseconds"),
    ],
)
def test_unsafe_or_inconsistent_timeouts_are_refused(zero, stop, keep, words) -> None:
    with pytest.raises(ValueError, match=words):
        VelocityTimeouts(zero, stop, keep)


def test_refusals_name_their_cause_in_one_line() -> None:
    first = enter_refused((1,), entered_before=False)
    assert "licence" in first and "ContinueVLine" in first and "script line 1" in first
    later = enter_refused((1,), entered_before=True)
    assert "licence" not in later and "forbids motion" in later
    stream = stream_refused("SetContinueVLine", (1,), 2000)
    assert "no longer in velocity mode" in stream and "2000 ms" in stream
    assert "re-enters" in stream
    for message in (first, later, stream, enter_refused((), False)):
        assert "\n" not in message
    assert "script line ?" in enter_refused((), False)
