"""A control session for input tests: the simulated arm clocked by a contact-free replayed
skin, a scripted input, and the per-tick trace of the arm."""

from __future__ import annotations

import io

import numpy as np
from stand_ins import ContactMeans

from wovenskin.control.session import ControlSession
from wovenskin.control.session_inputs import InputEvent
from wovenskin.control.trace import TraceWriter
from wovenskin.recording.formats import LabelledStream, write_labelled_stream
from wovenskin.runtime.session import open_session
from wovenskin.sim.stream import simulate_stream


class ScriptedInput:
    """Events at fixed session times: ``[(t, InputEvent), ...]``."""

    def __init__(self, script: list[tuple[float, InputEvent]]) -> None:
        self.script = sorted(script, key=lambda item: item[0])

    def poll(self, t: float) -> list[InputEvent]:
        due = [event for when, event in self.script if when <= t]
        self.script = [(when, event) for when, event in self.script if when > t]
        return due


def idle_session(tmp_path, seconds: float = 4.0, inputs=(), mapping=None) -> ControlSession:
    """A session on the simulated arm clocked by a contact-free replayed skin stream."""
    stream = simulate_stream(1.0, seed=3, gestures=["swipe_up"], invalid_fraction=0.0)
    rate = stream.sample_rate_hz
    quiet = stream.frames[: int(0.5 * rate)]  # the stream starts with a second of rest
    n = int(seconds * rate)
    frames = quiet[np.arange(n) % len(quiet)]
    path = tmp_path / "idle.npz"
    write_labelled_stream(path, LabelledStream(frames, np.arange(n) / rate, rate))
    session = open_session(
        f"replay:{path}", "sim", recognizer=ContactMeans("swipe_up"), fast_replay=True,
        trace=TraceWriter(io.StringIO()), poses=tmp_path / "poses.toml", mapping=mapping,
    )  # fmt: skip
    for source in inputs:
        session.add_input(source)
    return session


def untouched_session(tmp_path) -> ControlSession:
    """A started session on the simulated arm and a simulated skin that nobody touches."""
    session = open_session(
        "sim:auto=0,speed=0,seed=4", "sim", recognizer=ContactMeans("swipe_up"),
        poses=tmp_path / "poses.toml",
    )  # fmt: skip
    session.start()
    return session


def run_traced(session: ControlSession) -> list[dict]:
    records: list[dict] = []
    session._on_tick = lambda s: records.append(
        {
            "t": s.state.t,
            "tcp": np.asarray(s.state.robot.tcp.position, dtype=float),
            "R": s.state.robot.tcp.rotation(),
            "q": np.asarray(s.state.robot.q, dtype=float),
            "speed": s.state.robot.tcp_speed,
            "action": s.state.action,
        }
    )
    result = session.run()
    session.close()
    assert result.errors == 0, session.state.last_error
    return records


def at(records: list[dict], t: float) -> dict:
    return min(records, key=lambda r: abs(r["t"] - t))
