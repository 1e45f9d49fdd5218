"""TwistShaper: S-curve approach to a target twist within acceleration and jerk limits."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wovenskin.control.mapping import MotionSettings
from wovenskin.control.motion import TwistShaper, braking_acceleration

SETTINGS = MotionSettings()
LIMITS = {  # part -> (acceleration, jerk)
    "linear": (SETTINGS.linear_accel, SETTINGS.linear_jerk),
    "angular": (SETTINGS.angular_accel, SETTINGS.angular_jerk),
}
PARTS = {"linear": slice(0, 3), "angular": slice(3, 6)}


def run(shaper: TwistShaper, targets: list[np.ndarray], dts: list[float]) -> np.ndarray:
    """Commanded twists, starting with the state before the first update."""
    out = [shaper.twist.copy()]
    for target, dt in zip(targets, dts, strict=True):
        out.append(shaper.update(target, dt))
    return np.array(out)


def assert_within_limits(twists: np.ndarray, dts: np.ndarray, slack: float = 1e-9) -> None:
    for name, part in PARTS.items():
        accel_limit, jerk_limit = LIMITS[name]
        accel = np.diff(twists[:, part], axis=0) / dts[:, None]
        assert np.linalg.norm(accel, axis=1).max() <= accel_limit * (1 + slack)
        jerk = np.diff(np.vstack([np.zeros(3), accel]), axis=0) / dts[:, None]
        assert np.linalg.norm(jerk, axis=1).max() <= jerk_limit * (1 + slack)


def swipe_target() -> np.ndarray:
    return np.array([0.03, -0.04, 0.0, 0.0, 0.0, math.radians(15)])


def test_reaches_the_target_then_stops_on_release() -> None:
    shaper, dt = TwistShaper(SETTINGS), 0.005
    target = swipe_target()
    on = run(shaper, [target] * 120, [dt] * 120)
    np.testing.assert_array_equal(on[-1], target)  # within 0.6 s it runs at full speed
    reached = int(np.argmax(np.all(on == target, axis=1)))
    assert 0.2 < reached * dt < 0.4  # smoothly, not in one step
    off = run(shaper, [np.zeros(6)] * 120, [dt] * 120)
    np.testing.assert_array_equal(off[-1], np.zeros(6))
    speeds = np.linalg.norm(off[:, :3], axis=1)
    assert np.all(np.diff(speeds) <= 1e-15)  # from cruise, a release only slows down
    stopped = int(np.argmax(speeds == 0.0))
    assert stopped * dt <= 0.4  # the deceleration limit: at rest within 0.4 s
    assert_within_limits(np.vstack([on, off[1:]]), np.full(240, dt))


def test_direction_is_kept_while_starting_and_stopping() -> None:
    shaper, dt = TwistShaper(SETTINGS), 0.005
    target = swipe_target()
    twists = run(shaper, [target] * 40 + [np.zeros(6)] * 80, [dt] * 120)
    for part in PARTS.values():
        direction = target[part] / np.linalg.norm(target[part])
        for twist in twists[:, part]:
            assert np.linalg.norm(np.cross(twist, direction)) <= 1e-12  # parallel ...
            assert twist @ direction >= -1e-15  # ... and never reversed


def test_linear_and_angular_parts_are_limited_separately() -> None:
    shaper, dt = TwistShaper(SETTINGS), 0.01
    only_linear = np.array([0.05, 0, 0, 0, 0, 0])
    twists = run(shaper, [only_linear] * 30, [dt] * 30)
    assert not np.any(twists[:, 3:])
    first = twists[1, :3] / dt
    assert np.linalg.norm(first) == pytest.approx(SETTINGS.linear_jerk * dt)  # jerk-limited start


def test_zero_dt_changes_nothing_and_reset_forgets() -> None:
    shaper = TwistShaper(SETTINGS)
    shaper.update(swipe_target(), 0.05)
    before = shaper.twist.copy()
    np.testing.assert_array_equal(shaper.update(np.zeros(6), 0.0), before)
    shaper.reset()
    assert not np.any(shaper.twist) and not np.any(shaper.acceleration)


@pytest.mark.parametrize(
    ("target", "dt"),
    [(np.full(6, np.nan), 0.01), (np.zeros(5), 0.01), (np.zeros(6), -0.01), (np.zeros(6), np.inf)],
)
def test_bad_input_is_refused_and_changes_nothing(target, dt) -> None:
    shaper = TwistShaper(SETTINGS)
    shaper.update(swipe_target(), 0.05)
    before = shaper.twist.copy()
    with pytest.raises(ValueError):
        shaper.update(target, dt)
    np.testing.assert_array_equal(shaper.twist, before)


def test_braking_acceleration_lands_exactly() -> None:
    for remaining, step in [(0.3, 0.1), (1e-4, 0.01), (2.0, 0.0125), (0.1, 0.1)]:
        a = braking_acceleration(remaining, step)
        terms, total = a, 0.0
        while terms > 1e-12:
            total += terms
            terms -= step
        assert total == pytest.approx(remaining)


twist_values = st.floats(-0.5, 0.5, allow_nan=False)
targets = st.lists(
    st.tuples(st.lists(twist_values, min_size=6, max_size=6), st.integers(1, 60)),
    min_size=1,
    max_size=6,
)


@settings(max_examples=80, deadline=None)
@given(targets, st.sampled_from([0.002, 0.005, 0.01, 0.02]))
def test_limits_are_never_exceeded_and_the_target_is_reached(plan, dt: float) -> None:
    """Any sequence of held targets (rapid switches included) at a fixed tick."""
    shaper = TwistShaper(SETTINGS)
    goals: list[np.ndarray] = []
    for values, ticks in plan:
        goals += [np.array(values)] * ticks
    final = goals[-1]
    settle = 2.0 * np.sqrt(3.0) * 0.5 / SETTINGS.linear_accel + 1.0  # the longest change
    goals += [final] * int(settle / dt)  # then hold the last one long enough to settle
    twists = run(shaper, goals, [dt] * len(goals))
    assert_within_limits(twists, np.full(len(goals), dt))
    np.testing.assert_allclose(twists[-1], final, atol=1e-9)


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.tuples(st.lists(twist_values, min_size=6, max_size=6), st.floats(1e-4, 0.05)),
             min_size=2, max_size=80)
)  # fmt: skip
def test_limits_hold_with_an_irregular_tick(steps) -> None:
    shaper = TwistShaper(SETTINGS)
    goals = [np.array(values) for values, _ in steps]
    dts = [dt for _, dt in steps]
    twists = run(shaper, goals, dts)
    accel_limits = {"linear": SETTINGS.linear_accel, "angular": SETTINGS.angular_accel}
    for name, part in PARTS.items():
        accel = np.diff(twists[:, part], axis=0) / np.array(dts)[:, None]
        assert np.linalg.norm(accel, axis=1).max() <= accel_limits[name] * (1 + 1e-9)
        change = np.linalg.norm(np.diff(np.vstack([np.zeros(3), accel]), axis=0), axis=1)
        assert np.all(change <= LIMITS[name][1] * np.array(dts) * (1 + 1e-9))
