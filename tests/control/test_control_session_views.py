"""Why the arm does not move, as views show it: the safety layer's report of the limits
holding the arm back (:attr:`SafetyLayer.limiting`, :meth:`ControlSession.holding`) and the
recogniser's hesitation (:func:`unsure_line`)."""

from __future__ import annotations

import numpy as np
from session_helpers import untouched_session
from stand_ins import ContactMeans

from wovenskin.control.safety import SafetyLayer
from wovenskin.control.safety_limits import SafetyLimits
from wovenskin.control.session import ControlSession
from wovenskin.control.session_state import unsure_line
from wovenskin.gestures import CLASS_NAMES
from wovenskin.recording.formats import write_labelled_stream
from wovenskin.robots.sim import SimRobot
from wovenskin.runtime.session import open_session
from wovenskin.sim.stream import simulate_stream


def _layer(**limits) -> tuple[SafetyLayer, np.ndarray]:
    robot = SimRobot()
    robot.connect()
    tcp = np.asarray(robot.state().tcp.position, dtype=float)
    return SafetyLayer(robot, SafetyLimits(**limits), clock=lambda: 0.0), tcp


def test_the_safety_layer_says_which_limit_holds_the_last_twist() -> None:
    layer, tcp = _layer(workspace_lower=np.array([-0.8, -0.8, 0.0]))
    layer.send_twist(np.array([0.0, 0.0, -0.05, 0, 0, 0]))
    assert layer.limiting == ()  # free: nothing to say
    layer.send_twist(np.array([0.0, 0.0, -1.0, 0, 0, 0]))
    assert layer.limiting == ("speed cap: TCP speed limited to 250 mm/s",)
    layer.send_twist(np.zeros(6))
    assert layer.limiting == ()

    floor, _ = _layer(workspace_lower=np.array([-0.8, -0.8, tcp[2] - 0.001]))
    floor.send_twist(np.array([0.02, 0.0, -0.05, 0, 0, 0]))
    assert floor.limiting == ("workspace box: z at its lower limit (320 mm)",)
    floor.emergency_stop("stop button")
    assert floor.limiting == ("emergency: stop button",)


def test_a_session_held_at_the_box_floor_says_so_while_the_gesture_lasts(tmp_path) -> None:
    """swipe_up lowers the tool from the home pose; with the box floor 15 mm below it the
    arm stops there and the session says why, for as long as the command holds."""
    stream = simulate_stream(6.0, seed=3, gestures=["swipe_up"], invalid_fraction=0.0)
    path = tmp_path / "up.npz"
    write_labelled_stream(path, stream)
    robot = SimRobot()
    robot.connect()
    floor = float(robot.state().tcp.position[2]) - 0.015
    robot.disconnect()
    seen: list[tuple[str | None, float, tuple[str, ...]]] = []

    def on_tick(session: ControlSession) -> None:
        robot_state = session.state.robot
        speed = robot_state.tcp_speed if robot_state is not None else 0.0
        seen.append((session.state.gesture, speed, session.holding()))

    session = open_session(
        f"replay:{path}", robot, recognizer=ContactMeans("swipe_up"), fast_replay=True,
        poses=tmp_path / "poses.toml", on_tick=on_tick,
        limits=SafetyLimits(workspace_lower=np.array([-0.8, -0.8, floor])),
    )  # fmt: skip
    session.run()
    session.close()
    held = [h for gesture, speed, h in seen if gesture == "swipe_up" and speed < 1e-3 and h]
    assert held, "the arm never reported being held at the floor"
    assert all(any(line.startswith("workspace box: z at its lower limit") for line in h)
               for h in held[5:])  # fmt: skip
    # while the command holds at the floor, every tick says why; without a command, nothing
    active = [h for gesture, _, h in seen if gesture == "swipe_up"]
    assert any(h for h in active[-20:])
    assert all(h == () for gesture, _, h in seen if gesture is None)


def test_a_latched_stop_says_how_it_ends(tmp_path) -> None:
    session = untouched_session(tmp_path)
    try:
        session.emergency_stop("stop button")
        assert session.holding() == ("STOP pressed: Resume (or space) to move again",)
        session.resume()
        assert session.holding() == ()
        session.safety.heartbeat_skin(session.now)
        session.safety.check(session.now + 1.0)  # then the skin went silent for a second
        lines = session.holding()
        assert lines[0].startswith("skin watchdog: skin stream stalled")
        assert "resumes by itself" in lines[-1]
    finally:
        session.close()


def _p(**values: float) -> np.ndarray:
    p = np.zeros(len(CLASS_NAMES))
    for name, value in values.items():
        p[CLASS_NAMES.index(name)] = value
    return p


def test_unsure_names_the_two_likeliest_gestures_when_nothing_would_fire() -> None:
    names = tuple(CLASS_NAMES)
    line = unsure_line(_p(swipe_left=0.55, swipe_left_2f=0.40, invalid=0.05), names, 0.85)
    assert line == "unsure: swipe_left 0.55 / swipe_left_2f 0.40"
    assert unsure_line(_p(swipe_left=0.9, swipe_left_2f=0.1), names, 0.85) == ""  # it fires
    assert unsure_line(_p(invalid=0.8, push=0.2), names, 0.0) == ""  # nothing gesture-like
    behind = unsure_line(_p(invalid=0.5, push=0.45, swipe_up=0.05), names, 0.0)
    assert behind == "unsure: push 0.45 / swipe_up 0.05"  # invalid ranks first: no command
    assert unsure_line(np.full(3, 0.3), names, 0.5) == ""  # not this model's classes
