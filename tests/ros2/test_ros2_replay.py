"""``wovenskin run --robot ros2: --skin replay:`` against the stand-in Servo in another
process, on loopback: every twist checked on the wire (``wovenskin bench ros2`` runs the
same with the timing figures; here only what does not depend on a machine's speed)."""

from __future__ import annotations

import math

import pytest

pytest.importorskip("cyclonedds", reason="needs wovenskin[ros2]")

from wovenskin.bench.ros2 import replay_through_ros2  # noqa: E402
from wovenskin.bench.ros2_checks import silence_report, wire_report  # noqa: E402
from wovenskin.control.mapping import ActionMapping  # noqa: E402
from wovenskin.recording.formats import write_labelled_stream  # noqa: E402
from wovenskin.recording.native import read_recording  # noqa: E402
from wovenskin.robots.sim import tm5_900  # noqa: E402
from wovenskin.sim.stream import simulate_stream  # noqa: E402

pytestmark = pytest.mark.slow  # two pairs of processes and 12 s of real-time replay


@pytest.fixture(scope="module")
def stream(tmp_path_factory):
    path = tmp_path_factory.mktemp("ros2") / "stream.npz"
    gestures = ["swipe_up", "swipe_left_2f", "circle_cw_2f", "push"]
    write_labelled_stream(path, simulate_stream(8.0, 5, gestures=gestures, invalid_fraction=0.0))
    return path


def test_every_twist_on_the_wire_is_what_the_session_meant(stream, tmp_path, ros2_domain):
    log, record, run = replay_through_ros2(stream, tmp_path, ros2_domain)
    assert run.returncode == 0, run.stderr
    assert "left to the arm's controller: collision checking" in run.stderr
    report = wire_report(log, read_recording(record), tm5_900.urdf_chain(), ActionMapping.load())
    assert report.twists > 100
    assert report.decoded == report.twists  # rosbags reads every one as TwistStamped
    assert all(math.isfinite(lag) and abs(lag) < 1000 for lag in report.stamp_lag_ms)
    assert report.moving > 0 and report.moving_outside_commands == 0
    assert report.aligned == report.moving - report.moving_in_nudges
    assert report.misaligned == 0
    assert report.lift_offs >= 2  # each was followed by a zero twist
    assert len(report.lift_to_zero_ms) + len(report.nudge_lift_to_zero_ms) == report.lift_offs


def test_the_arm_stops_when_the_joint_states_stop(stream, tmp_path, ros2_domain):
    log, _, run = replay_through_ros2(stream, tmp_path, ros2_domain, silence_after_s=0.2,
                                      seconds=5.0)  # fmt: skip
    assert "no joint states on /joint_states" in run.stderr
    silence = silence_report(log)
    assert silence.to_zero_ms is not None  # a zero twist came after the last joint state
    assert silence.moving_after_zero == 0
    assert silence.moved_after_zero_rad < 1e-9
