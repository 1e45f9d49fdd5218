"""The simulated hands on a live session: each act moves the arm the way it was asked."""

import numpy as np
import pytest

from wovenskin.operators.hands import KeyboardHand, PendantHand, SkinHand, flip, tool_command
from wovenskin.operators.independent_skin import IndependentSkin
from wovenskin.operators.profiles import sample_profile
from wovenskin.operators.script import ScriptRunner
from wovenskin.operators.skin_hand import OperatorSkin
from wovenskin.runtime.session import open_session
from wovenskin.tasks import make_task


def _session(skin="none:speed=0"):
    session = open_session(skin, "sim", None, task=make_task("pick_place", objects=("cube",)))
    session.run(seconds=0.6)
    return session


def _act(session, plan, seconds: float) -> ScriptRunner:
    runner = ScriptRunner()
    runner.start(plan, session.now)
    end = session.now + seconds
    while session.now < end:
        session.run(seconds=0.02)
        runner.tick(session.now)
    return runner


def test_flip_and_the_tool_command_of_a_base_axis():
    assert flip("translate +y") == "translate -y" and flip("rotate -z") == "rotate +z"
    session = _session()
    try:
        for axis in ("x", "y", "z"):
            for sign in (1, -1):
                command = tool_command(session, axis, sign)
                twist = session.mapping.twist_of(session.mapping.resolve(command),
                                                 session.state.robot.tcp)  # fmt: skip
                assert sign * twist["xyz".index(axis)] > 0.9 * np.abs(twist[:3]).max()
    finally:
        session.close()


@pytest.mark.parametrize("kind", ["keyboard", "pendant"])
def test_a_press_moves_along_the_base_axis_until_released(kind):
    session = _session()
    profile = sample_profile("E", "expert", 2)
    rng = np.random.default_rng(0)
    hand = KeyboardHand(session, profile, rng) if kind == "keyboard" else PendantHand(
        session, profile, rng)  # fmt: skip
    hand.profile = type(profile)(**{**profile.to_dict(), "wrong_direction": 0.0})
    session.add_input(hand)
    try:
        y0 = session.state.robot.tcp.position[1]
        runner = _act(session, hand.press("y", +1), 2.0)
        assert runner.result >= 1
        moved = session.state.robot.tcp.position[1] - y0
        assert moved > 0.02, moved
        hand.release_now()
        session.run(seconds=1.0)
        y1 = session.state.robot.tcp.position[1]
        session.run(seconds=1.0)
        assert abs(session.state.robot.tcp.position[1] - y1) < 1e-4  # stopped
    finally:
        session.close()


def test_pendant_nudges_step_by_its_increments_and_count_the_mode_change():
    session = _session()
    hand = PendantHand(session, sample_profile("E", "expert", 3), np.random.default_rng(0))
    session.add_input(hand)
    try:
        z0 = session.state.robot.tcp.position[2]
        runner = _act(session, hand.nudge("z", -1, 0.0052), 4.0)
        assert runner.result == 2  # step mode 5 mm, one step
        assert session.state.robot.tcp.position[2] - z0 == pytest.approx(-0.005, abs=0.0007)
    finally:
        session.close()


@pytest.mark.parametrize(
    "make_skin", [lambda: OperatorSkin(11), lambda: IndependentSkin(0)], ids=["sim", "independent"]
)
def test_a_skin_gesture_is_recognised_held_and_lifted(make_skin):
    skin = make_skin()
    session = _session(skin)
    profile = type(sample_profile("E", "expert", 4))(
        **{**sample_profile("E", "expert", 4).to_dict(), "wrong_direction": 0.0}
    )
    hand = SkinHand(session, profile, np.random.default_rng(0), skin)
    session.add_input(hand)
    try:
        z0 = session.state.robot.tcp.position[2]
        runner = _act(session, hand.press("z", -1), 3.0)
        assert runner.result == 1 and skin.touching
        assert session.state.gesture == hand.gestures[tool_command(session, "z", -1)]
        assert session.state.robot.tcp.position[2] < z0 - 0.02
        hand.release_now()
        session.run(seconds=1.5)
        assert not skin.touching and session.state.gesture is None
    finally:
        session.close()
