"""The gestures' speed profile (control/profile.py) and its nudge (control/gesture_motion.py).

The session tests script the command changes (a stand-in pipeline) on a contact-free
replayed stream, so they measure the control chain alone: profile, shaper, safety and the
simulated TM5-900.
"""

from __future__ import annotations

import math
from importlib import resources

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from paths import is_png
from stand_ins import ContactMeans

from wovenskin.control.mapping import ActionMapping
from wovenskin.control.profile import SpeedProfile
from wovenskin.errors import ConfigError
from wovenskin.recognition.arbiter import CommandChange
from wovenskin.recording.formats import write_labelled_stream
from wovenskin.runtime.session import open_session
from wovenskin.sim.stream import simulate_stream

DEFAULT = ActionMapping.load().settings.profile


def test_the_default_profile_is_graded_as_documented() -> None:
    # docs/gestures.md "Speed profile": a changed default must change the docs and this test
    assert SpeedProfile("graded", 0.2, 0.2, 0.5, 1.0, 0.5) == DEFAULT
    assert DEFAULT.fraction(0.0) == DEFAULT.fraction(0.2) == pytest.approx(0.2)
    assert DEFAULT.fraction(0.7) == DEFAULT.fraction(5.0) == 1.0


@given(st.floats(0.0, 3.0), st.floats(0.0, 3.0))
def test_the_fraction_never_falls_with_hold_time(a: float, b: float) -> None:
    early, late = sorted((a, b))
    assert DEFAULT.fraction(early) <= DEFAULT.fraction(late) + 1e-12
    assert 0.2 - 1e-12 <= DEFAULT.fraction(early) <= 1.0


def test_distance_is_the_integral_of_the_fraction_and_hold_for_its_inverse() -> None:
    times = np.linspace(0.0, 2.0, 40001)
    speeds = np.array([DEFAULT.fraction(t) for t in times]) * 0.05
    integral = np.concatenate([[0.0], np.cumsum((speeds[1:] + speeds[:-1]) / 2 * np.diff(times))])
    for k in (0, 4000, 12000, 20000, 40000):
        assert DEFAULT.distance(times[k], 0.05) == pytest.approx(integral[k], abs=1e-7)
    for way in (0.001, 0.01, 0.1):
        assert DEFAULT.distance(DEFAULT.hold_for(way, 0.05), 0.05) == pytest.approx(way, rel=1e-6)


def test_the_constant_profile_is_the_papers() -> None:
    constant = SpeedProfile(kind="constant")
    assert constant.fraction(0.0) == constant.fraction(3.0) == 1.0
    assert constant.nudge("translate") == constant.nudge("rotate") == 0.0
    assert constant.distance(2.0, 0.05) == pytest.approx(0.1)


def test_profiles_are_read_from_the_mapping_file() -> None:
    text = '[motion.profile]\nkind = "constant"\n[gestures]\nswipe_up = "translate +z"\n'
    assert ActionMapping.from_text(text).settings.profile.kind == "constant"
    text = "[motion.profile]\nfine_s = 0.1\nnudge_deg = 1.0\n"
    profile = ActionMapping.from_text(text).settings.profile
    assert profile.fine_s == 0.1 and profile.nudge("rotate") == pytest.approx(math.radians(1.0))


@pytest.mark.parametrize(
    ("table", "message"),
    [
        ('kind = "fast"', "profile kind must be 'graded' or 'constant'"),
        ("start_fraction = 0.0", "start_fraction must lie in (0, 1]"),
        ("ramp_s = -1", "ramp_s must be a finite number >= 0"),
        ("nudge_mm = true", "nudge_mm must be a number"),
        ("speed = 1", "motion.profile.speed: unknown key"),
    ],
)
def test_a_bad_profile_is_one_line_naming_the_key(table: str, message: str) -> None:
    with pytest.raises(ConfigError) as error:
        ActionMapping.from_text(f"[motion.profile]\n{table}\n", "m.toml")
    assert message in str(error.value) and "\n" not in str(error.value)
    assert str(error.value).startswith("m.toml: ")


@pytest.fixture(scope="module")
def blank_stream(tmp_path_factory):
    """Six seconds of a skin nobody touches: the session's clock, nothing to recognise."""
    stream = simulate_stream(6.0, seed=1, gestures=["swipe_up"], invalid_fraction=0.0)
    stream.frames[:] = stream.frames[:1]
    path = tmp_path_factory.mktemp("blank") / "blank.npz"
    write_labelled_stream(path, stream)
    return path


def scripted_command(path, gesture: str, held_s: float, reason: str = "dwell", mapping=None):
    """Run one command of ``held_s`` (from 2 s, ended by a lift-off) through a session;
    returns (TCP way in mm, turn in deg, last time moving after the end in s)."""
    samples = []

    def sample(session) -> None:
        robot = session.state.robot
        samples.append((session.now, robot.tcp.position.copy(), robot.tcp.rotation().copy(),
                        robot.tcp_speed, np.linalg.norm(session.state.twist)))  # fmt: skip

    session = open_session(f"replay:{path}", "sim", recognizer=ContactMeans(gesture),
                           fast_replay=True, mapping=mapping, on_tick=sample)  # fmt: skip
    start = 2.0
    changes = [CommandChange(start, gesture, reason), CommandChange(start + held_s, None,
                                                                    "lift-off")]  # fmt: skip
    feed = session.pipeline.feed

    def scripted(block):
        feed(block)
        t = np.asarray(block.t).reshape(-1)
        return [c for c in changes if t[0] - 1e-9 < c.t <= t[-1] + 1e-9]

    session.pipeline.feed = scripted
    session.run()
    session.close()
    t = np.array([s[0] for s in samples])
    before = int(t.searchsorted(start)) - 1
    way = float(np.linalg.norm(samples[-1][1] - samples[before][1])) * 1000
    turn = samples[-1][2] @ samples[before][2].T
    angle = math.degrees(math.acos(np.clip((np.trace(turn) - 1) / 2, -1, 1)))
    moving = [s[0] for s in samples if s[3] > 1e-3 or s[4] > 1e-9]
    return way, angle, (moving[-1] - start - held_s) if moving else -1.0


def test_a_flick_is_a_one_millimetre_nudge_at_rest_within_110_ms(blank_stream) -> None:
    way, _, rest = scripted_command(blank_stream, "swipe_up", 0.0, reason="flick")
    assert 0.95 <= way <= 1.2
    assert rest <= 0.11


def test_a_short_command_is_finished_to_the_nudge_and_a_long_one_runs_far(blank_stream) -> None:
    way, _, rest = scripted_command(blank_stream, "swipe_right", 0.05)
    assert 0.95 <= way <= 1.2 and rest <= 0.1
    way, _, rest = scripted_command(blank_stream, "swipe_up", 2.5)
    assert way >= 100.0  # a long move speeds up to full speed
    assert rest <= 0.06  # from 50 mm/s the release brake takes 50 ms
    way, angle, _ = scripted_command(blank_stream, "circle_cw_2f", 0.0)
    assert way < 0.5 and 0.45 <= angle <= 0.7  # a turn's nudge is half a degree


def test_the_constant_profile_has_no_nudge_and_full_speed_at_once(blank_stream, tmp_path):
    mapping = tmp_path / "constant.toml"
    default = resources.files("wovenskin.control").joinpath("default_mapping.toml").read_text()
    mapping.write_text(default.replace('kind = "graded"', 'kind = "constant"'))
    way, _, _ = scripted_command(blank_stream, "swipe_up", 0.0, mapping=mapping)
    assert way < 0.05  # no command time, no motion
    way, _, _ = scripted_command(blank_stream, "swipe_up", 0.5, mapping=mapping)
    assert way > 18.0  # 0.5 s at 50 mm/s less the start's ramp


def test_wovenskin_profile_prints_and_draws_the_mapping_profile(tmp_path) -> None:
    from typer.testing import CliRunner

    from wovenskin.cli import app

    plot = tmp_path / "profile.png"
    result = CliRunner().invoke(app, ["profile", "--plot", str(plot)])
    assert result.exit_code == 0, result.output
    assert "graded" in result.output and "107.0" in result.output  # 2.5 s held: 107 mm
    assert is_png(plot)
    bad = tmp_path / "bad.toml"
    bad.write_text('[motion.profile]\nkind = "fast"\n')
    result = CliRunner().invoke(app, ["profile", "--mapping", str(bad)])
    assert result.exit_code == 2 and "profile kind" in result.output
