"""Tests of wovenskin.bench.control: IK, loop and latency figures, and the CLI command."""

from __future__ import annotations

import io
import json

import numpy as np
import pytest
from rich.console import Console
from stand_ins import ContactMeans
from typer.testing import CliRunner

from wovenskin.bench import control as bench_control
from wovenskin.bench.control import (
    LATENCY_TARGET_S,
    ControlBenchResult,
    GestureLatency,
    _summarise_latencies,
    bench_ik,
    run_control_benchmark,
)
from wovenskin.bench.stops import (
    STOP_SAFETY_TARGET_S,
    STOP_TARGET_MEDIAN_S,
    STOP_TARGET_WORST_S,
    FakeTechmanArms,
    StopCase,
    StopMeasurement,
    bench_stops,
    measure_stop,
    stop_cases,
    summarise_stops,
)
from wovenskin.cli import app
from wovenskin.recognition import shipped
from wovenskin.robots.base import JointLimits, Pose, Robot, RobotCapabilities, RobotState
from wovenskin.robots.sim import tm5_900


def test_ik_steps_are_timed() -> None:
    times, rate = bench_ik(steps=60)
    assert rate == 250.0 and times.shape == (60,)
    assert np.all(times > 0) and np.median(times) < 0.05


@pytest.mark.slow
def test_all_figures_with_a_stand_in_recogniser() -> None:
    result = run_control_benchmark(
        loop_seconds=1.0, streams=1, stream_seconds=10.0, ik_steps=50,
        recognizer=ContactMeans("push"), gestures=["push"], stops=False,
    )  # fmt: skip
    assert result.ik_steps == 50 and result.ik_step_p99_ms >= result.ik_step_median_ms > 0
    assert 0 < result.loop_rate_hz < 250  # paced by the 200 Hz skin: never faster (a load-
    # dependent lower bound would make the test depend on the machine: the figure is the bench's)
    assert result.loop_ticks > 20 and result.loop_interval_p99_ms >= 0  # 1 s of ticks, slowed
    assert result.loop_compute_p99_ms >= result.loop_compute_median_ms > 0
    assert result.latency_gestures >= 4  # every event of the stream counts
    assert result.latency_moved >= 3  # every push, recognised, from rest
    # contact, conditioning, the 0.1 s dwell and a jerk-limited start: 0.1 s to 0.5 s
    assert 100 <= result.latency_median_ms <= 500
    assert result.latency_max_ms >= result.latency_p90_ms >= result.latency_median_ms
    assert result.command_median_ms <= result.latency_median_ms
    assert 0.0 <= result.latency_within_target <= 1.0
    document = json.loads(json.dumps(result.to_dict()))
    assert document["latency_per_gesture_ms"]
    console = Console(record=True, width=200, file=io.StringIO())
    console.print(result.table())
    text = console.export_text()
    assert "IK step" in text and "first contact -> first motion" in text


def test_latency_summary_counts_only_gestures_that_moved_from_rest() -> None:
    result = ControlBenchResult(ik_steps=1, ik_step_median_ms=1, ik_step_p99_ms=1, ik_rate_hz=250)
    latencies = [
        GestureLatency("push", 1.0, 1.12, 1.15, True, "push"),
        GestureLatency("push", 3.0, 3.13, 3.25, True, "push"),
        GestureLatency("swipe_up", 5.0, 5.11, None, False, "swipe_up"),  # the arm still moved
        GestureLatency("swipe_up", 7.0, None, None, True),  # never recognised
        GestureLatency("swipe_up", 9.0, 9.05, 9.06, True, "push"),  # the wrong command
    ]
    _summarise_latencies(result, latencies)
    assert (result.latency_gestures, result.latency_moved) == (5, 2)
    assert result.latency_median_ms == pytest.approx(200.0)
    assert result.latency_max_ms == pytest.approx(250.0)
    assert result.latency_within_target == pytest.approx(0.5)  # 150 ms yes, 250 ms no
    assert result.command_median_ms == pytest.approx(120.0)  # 120, 130, 110 ms
    assert result.latency_per_gesture_ms == {"push": pytest.approx(200.0)}
    assert LATENCY_TARGET_S == 0.2
    assert any("still moved" in note for note in result.notes)
    assert any("1 gesture(s) started another command" in note for note in result.notes)


def test_without_a_model_only_ik_is_measured(monkeypatch) -> None:
    def missing(path=None):
        raise shipped.ModelNotFoundError("the shipped default model is missing")

    monkeypatch.setattr(bench_control, "load_recognizer", missing)
    result = run_control_benchmark(loop_seconds=1.0, ik_steps=20, stops=False)
    assert result.ik_steps == 20 and result.loop_ticks == 0 and result.latency_gestures == 0
    assert "not measured: the shipped default model is missing" in result.notes[0]


@pytest.mark.slow
def test_cli_prints_figures(monkeypatch) -> None:
    seen = {}

    def fake(model, loop_seconds, streams, stream_seconds, ik_steps, stops=True, stop_robot="sim"):
        seen.update(loop_seconds=loop_seconds, streams=streams, ik_steps=ik_steps, stops=stops)
        result = run_control_benchmark(
            loop_seconds=0, streams=1, stream_seconds=6.0, ik_steps=ik_steps,
            recognizer=ContactMeans("push"), gestures=["push"], stops=False,
        )  # fmt: skip
        if stops:
            case = StopCase("translate", "+x", 0.05, 0.2)
            result.stop_times = summarise_stops([StopMeasurement(case, 0.04, True, 0.1)])
        return result

    monkeypatch.setattr(bench_control, "run_control_benchmark", fake)
    runner = CliRunner()
    result = runner.invoke(app, ["bench", "control", "--ik-steps", "30", "--loop-seconds", "0"])
    assert result.exit_code == 0, result.output
    assert "IK step (30 steps at 250 Hz)" in result.stdout and "median" in result.stdout
    assert seen == {"loop_seconds": 0.0, "streams": 2, "ik_steps": 30, "stops": True}
    assert "release -> TCP at rest" in result.stdout
    result = runner.invoke(app, ["bench", "control", "--json", "--ik-steps", "30"])
    document = json.loads(result.stdout)
    assert document["ik_steps"] == 30 and document["latency_gestures"] >= 1
    assert document["stop_times"]["release"]["median_ms"] == pytest.approx(100.0)
    result = runner.invoke(app, ["bench", "control", "--no-stops", "--ik-steps", "30"])
    assert result.exit_code == 0 and seen["stops"] is False


# -- stop times


@pytest.mark.slow
def test_stop_times_on_the_simulated_arm_meet_the_targets() -> None:
    """The issue's targets, on a subset of the benchmark's commands (every direction, speeds
    up to the caps, three endings). A release used to take 0.37 s after a 0.2 s command and
    1 s from the 250 mm/s cap."""
    cases = stop_cases(durations=(0.2, 0.5))
    assert {c.axis for c in cases} == {"+x", "-x", "+y", "-y", "+z", "-z"}
    measurements = bench_stops(cases=cases)
    assert all(m.moving_at_end for m in measurements)
    summary = summarise_stops(measurements)
    release = summary["release"]
    assert release["never_stopped"] == 0 and release["cases"] == 12
    assert release["median_ms"] <= 1000 * STOP_TARGET_MEDIAN_S
    assert release["worst_ms"] <= 1000 * STOP_TARGET_WORST_S
    for ending in ("stop", "watchdog"):
        assert summary[ending]["never_stopped"] == 0
        assert summary[ending]["worst_ms"] <= 1000 * STOP_SAFETY_TARGET_S
    stall = summary["watchdog"]["stall_to_rest_worst_ms"]  # the watchdog fires after 0.1 s
    assert 100 < stall <= 1000 * (0.1 + STOP_SAFETY_TARGET_S) + 10


class InstantArm(Robot):
    """A stand-in real-time arm (no ``step``): it moves at the last twist it was sent."""

    name = "instant"

    def __init__(self) -> None:
        self.twist = np.zeros(6)
        self.received: list[np.ndarray] = []

    def connect(self) -> None: ...

    def disconnect(self) -> None: ...

    def state(self) -> RobotState:
        pose = Pose(np.array([0.4, 0.0, 0.5]), np.array([0.0, 1.0, 0.0, 0.0]))
        moving = bool(np.any(self.twist))
        return RobotState(0.0, tm5_900.INITIAL_Q.copy(), np.zeros(6), pose, self.twist, moving)

    def joint_limits(self) -> JointLimits:
        return tm5_900.JOINT_LIMITS

    def capabilities(self) -> RobotCapabilities:
        # a TM5-900 as far as the safety layer's checks go; it obeys stop() at once
        return RobotCapabilities(kinematics=tm5_900.kinematics(), stop_time_s=0.0)

    def send_twist(self, twist) -> None:
        self.twist = np.asarray(twist, dtype=float).copy()
        self.received.append(self.twist)

    def move_to_joints(self, q, speed_fraction=0.2) -> None: ...

    def move_to_pose(self, pose, speed=0.05) -> None: ...

    def stop(self) -> None:
        self.twist = np.zeros(6)


def test_a_real_time_robot_is_measured_through_the_same_chain() -> None:
    """A robot without ``step`` (a real or emulated controller) runs paced to the tick; the
    times come from the tick schedule, so they do not depend on the machine's load."""
    arms: list[InstantArm] = []

    def make() -> InstantArm:
        arms.append(InstantArm())
        return arms[-1]

    release = measure_stop(make, StopCase("translate", "+z", 0.25, 0.1), observe_s=0.2)
    # 13 mm/s after 0.1 s: braked at the 0.25 m/s^2 acceleration limit, 52 ms
    assert release.moving_at_end and release.stop_s == pytest.approx(0.05, abs=1e-6)
    sent = np.linalg.norm(np.array(arms[-1].received)[:, :3], axis=1)
    assert 0 < sent.max() <= 0.25  # within the cap, shaped (a 0.1 s start is slow)
    stop = measure_stop(make, StopCase("rotate", "-x", 1.0, 0.1, "stop"), observe_s=0.1)
    assert stop.stop_s == pytest.approx(0.005)  # the arm obeys stop() at once


def test_stop_times_through_the_fake_techman_controller() -> None:
    """The same measurement runs on the Techman client against a fresh fake controller per
    case (real time over loopback): the arm moved at the end and came to rest."""
    cases = [StopCase("translate", "+x", 0.05, 0.3, "release")]
    with FakeTechmanArms() as arms:
        (measured,) = bench_stops(arms, cases)
        assert arms._fake is not None  # the last fake runs until the factory closes
    assert arms._fake is None
    assert measured.moving_at_end and measured.speed_at_end > 0.01
    assert measured.stop_s is not None  # at rest within the 0.6 s watched


def test_unknown_stop_robot_is_refused() -> None:
    with pytest.raises(ValueError, match="neither 'sim' nor 'techman-fake'"):
        run_control_benchmark(loop_seconds=0, streams=0, ik_steps=2, stop_robot="ur")
