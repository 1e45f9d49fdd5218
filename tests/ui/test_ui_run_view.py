"""Tests of wovenskin.ui.run_view: the screen's content, the keys, and a whole viewed run."""

from __future__ import annotations

import io

import numpy as np
from rich.console import Console
from session_helpers import idle_session
from stand_ins import ContactMeans

from wovenskin.control.safety_limits import SafetyLimits
from wovenskin.recording.formats import write_labelled_stream
from wovenskin.runtime.session import open_session
from wovenskin.sim.stream import simulate_stream
from wovenskin.teleop.keyboard import TerminalKeyboard
from wovenskin.ui.run_view import handle_keys, render_run, run_with_view, terminal_keys


def session_on_replay(tmp_path, **kwargs):
    stream = simulate_stream(5.0, seed=4, gestures=["swipe_left"], invalid_fraction=0.0)
    path = tmp_path / "s.npz"
    write_labelled_stream(path, stream, overwrite=True)  # a test may open two sessions
    return open_session(
        f"replay:{path}", "sim", recognizer=ContactMeans("swipe_left"), fast_replay=True,
        poses=tmp_path / "poses.toml", **kwargs,
    )  # fmt: skip


def screen_text(renderable) -> str:
    console = Console(record=True, width=160, file=io.StringIO(), color_system=None)
    console.print(renderable)
    return console.export_text()


def test_the_screen_shows_command_robot_and_stops(tmp_path) -> None:
    session = session_on_replay(tmp_path)
    session.start()
    while session.state.gesture is None and not session.state.ended:
        session.step()
    text = screen_text(render_run(session))
    assert "command" in text and "swipe_left" in text
    assert "TCP" in text and " mm" in text and "joints" in text and "stops" in text
    x_mm = 1000 * session.state.robot.tcp.position[0]
    assert f"x {x_mm:7.1f}" in text  # the TCP in millimetres
    assert "space: stop" in text
    session.emergency_stop("stop key pressed")
    text = screen_text(render_run(session))
    assert "STOPPED" in text and "stop key pressed" in text
    session.close()


def test_keys_stop_resume_and_quit(tmp_path) -> None:
    session = session_on_replay(tmp_path)
    session.start()
    handle_keys(session, " ")
    assert session.safety.stopped and session.state.stops[-1].reason == "stop key pressed"
    handle_keys(session, " ")
    assert not session.safety.stopped
    handle_keys(session, "xq")  # unknown keys are ignored
    assert session.run().ended == "quit with the q key"
    session.close()


def test_no_terminal_no_keys() -> None:
    with terminal_keys(io.StringIO()) as read:
        assert read() == ""


def test_a_viewed_run_to_the_end_and_one_quit_by_key(tmp_path) -> None:
    console = Console(record=True, width=160, file=io.StringIO(), color_system=None)
    session = session_on_replay(tmp_path)
    result = run_with_view(session, console, fps=1000.0, read_keys=lambda: "")
    session.close()
    assert result.ended == "the skin stream ended" and result.ticks > 500
    assert "swipe_left" in console.export_text()

    presses = iter(["", "", "q"])
    session = session_on_replay(tmp_path)
    result = run_with_view(session, console, read_keys=lambda: next(presses, ""))
    session.close()
    assert result.ended == "quit with the q key"


def test_the_screen_says_what_holds_the_arm_back_and_when_the_recogniser_is_unsure(
    tmp_path,
) -> None:
    import numpy as np

    home_tcp = np.array([0.5175, -0.1223, 0.32105])  # the simulated TM5-900's starting TCP
    limits = SafetyLimits(workspace_lower=home_tcp - 0.002, workspace_upper=home_tcp + 0.002)
    seen: list[str] = []

    def look(s) -> None:  # the screen as a view would draw it between two ticks
        if not seen and s.holding():
            seen.append(screen_text(render_run(s)))

    # any swipe meets a face at once; a fast replay brings whole seconds a step, so the
    # screen is drawn from the tick where the arm is held back
    session = session_on_replay(tmp_path, limits=limits, on_tick=look)
    session.start()
    while not session.state.ended and not seen:
        session.step()
    session.close()
    held = seen[0] if seen else ""
    assert "held back" in held and "workspace box" in held
    session.state.unsure = "unsure: swipe_left 0.55 / swipe_left_2f 0.40"
    assert "unsure: swipe_left 0.55 / swipe_left_2f 0.40" in screen_text(render_run(session))


def test_keys_drive_the_arm_with_the_keyboard_input(tmp_path) -> None:
    session = idle_session(tmp_path, seconds=3.0)
    keyboard = TerminalKeyboard(clock=lambda: session.now)  # repeats timed on the skin clock
    start: list = []

    def read() -> str:
        if session.now >= 1.2 and not start:
            start.append(session.state.robot.tcp)
        return "r" if 1.2 <= session.now < 2.0 else ""  # held: the auto-repeat sends "r"

    console = Console(record=True, width=160, file=io.StringIO(), color_system=None)
    result = run_with_view(session, console, fps=1000.0, read_keys=read, keyboard=keyboard)
    session.close()
    assert result.errors == 0
    moved = session.state.robot.tcp.position - start[0].position
    tool_z = start[0].rotation()[:, 2]  # r is swipe_up: translate +z of the tool
    assert moved @ tool_z > 0.98 * np.linalg.norm(moved) > 0.015
    assert [(c.source, c.name) for c in session.command_log] == [("keyboard", "swipe_up")]
    text = console.export_text()
    assert "r: translate +z" in text and "g: gripper" in text and "commands" in text
