"""The ``ros2:`` backend against the stand-in MoveIt Servo, both in this process on a
loopback-only DDS domain of the test's own (the end-to-end run in separate processes is
tests/ros2/test_ros2_replay.py)."""

from __future__ import annotations

import io
import json
import threading
import time

import numpy as np
import pytest

pytest.importorskip("cyclonedds", reason="needs wovenskin[ros2]")

from wovenskin.robots.base import Pose, RobotError  # noqa: E402
from wovenskin.robots.registry import SpecError, make_robot  # noqa: E402
from wovenskin.robots.ros2.standin import StandinServo, StandinSettings  # noqa: E402
from wovenskin.robots.sim import tm5_900  # noqa: E402


class Standin:
    """The stand-in Servo serving in a thread; its log is kept in memory."""

    def __init__(self, domain: int, **settings) -> None:
        self.log = io.StringIO()
        self.servo = StandinServo(
            tm5_900.urdf_chain(), tm5_900.INITIAL_Q, StandinSettings(**settings),
            domain=domain, log=self.log,
        )  # fmt: skip
        self.thread = threading.Thread(target=self.servo.run, daemon=True)
        self.thread.start()

    def records(self, event: str) -> list[dict]:
        lines = self.log.getvalue().splitlines()
        return [r for r in map(json.loads, lines) if r["event"] == event]

    def close(self) -> None:
        self.servo.stop()
        self.thread.join(timeout=5)
        self.servo.close()


@pytest.fixture
def standin(ros2_domain):
    made: list[Standin] = []

    def make(**settings) -> Standin:
        made.append(Standin(ros2_domain, **settings))
        return made[-1]

    yield make
    for one in made:
        one.close()


def wait_until(condition, timeout: float = 5.0) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError("timed out waiting")
        time.sleep(0.01)


def robot(domain: int, options: str = ""):
    arm = make_robot(f"ros2:?domain={domain}{options}")
    arm.settings = type(arm.settings)(**{**arm.settings.__dict__, "connect_timeout_s": 5.0})
    return arm


def test_connect_switches_servo_to_twists_and_reads_the_joints(standin, ros2_domain):
    servo = standin()
    with robot(ros2_domain) as arm:
        assert servo.servo.twist_mode
        assert servo.records("switch_command_type")[0]["type"] == 1  # TWIST
        state = arm.state()
        assert np.allclose(state.q, tm5_900.INITIAL_Q)
        assert np.allclose(state.tcp.position, tm5_900.forward_kinematics(tm5_900.INITIAL_Q)[:3, 3])
        assert state.fault is None


def test_twists_arrive_stamped_in_the_base_frame_and_move_the_arm(standin, ros2_domain):
    servo = standin()
    with robot(ros2_domain) as arm:
        start = arm.state().tcp.position
        for _ in range(40):  # 0.2 s at 200 Hz, 2 cm/s along +x
            arm.send_twist(np.array([0.02, 0, 0, 0, 0, 0]))
            time.sleep(0.005)
        arm.stop()
        wait_until(lambda: not np.any(servo.records("twist")[-1]["twist"]))
        time.sleep(0.05)
        moved = arm.state().tcp.position - start
    twists = servo.records("twist")
    assert {r["frame_id"] for r in twists} == {"base"}
    assert all(abs(r["wall_ns"] - r["stamp_ns"]) < 5e9 for r in twists)  # system clock
    assert moved[0] > 0.001 and abs(moved[1]) < 1e-4 and abs(moved[2]) < 1e-4


def test_a_tool_frame_twist_is_turned_into_that_frames_axes(standin, ros2_domain):
    servo = standin()
    with robot(ros2_domain, "&frame=tcp") as arm:
        q = arm.state().q
        arm.send_twist(np.array([0.0, 0.0, 0.01, 0.0, 0.0, 0.0]))
        wait_until(lambda: servo.records("twist"))
        arm.stop()
    sent = servo.records("twist")[0]
    assert sent["frame_id"] == "tcp"
    rotation = tm5_900.forward_kinematics(q)[:3, :3]  # base <- tcp
    assert np.allclose(rotation @ np.array(sent["twist"][:3]), [0, 0, 0.01], atol=1e-6)


def test_the_arm_stops_and_says_why_when_joint_states_stop(standin, ros2_domain):
    servo = standin(silence_after_s=0.1)
    with robot(ros2_domain) as arm:
        for _ in range(100):
            try:
                arm.send_twist(np.array([0.0, 0.02, 0, 0, 0, 0]))
            except RobotError as exc:
                assert "no joint states on /joint_states" in str(exc)
                break
            time.sleep(0.005)
        else:
            raise AssertionError("the arm kept taking twists without joint states")
        assert "no joint states" in arm.state().fault
        silenced = servo.servo.silenced_at_ns
        assert silenced is not None
    after = [r for r in servo.records("twist") if r["wall_ns"] > silenced]
    first_zero = next(i for i, r in enumerate(after) if not any(r["twist"]))
    assert not any(any(r["twist"]) for r in after[first_zero:])


def test_a_stalled_control_loop_gets_a_zero_twist(standin, ros2_domain):
    servo = standin()
    with robot(ros2_domain) as arm:
        arm.send_twist(np.array([0.0, 0.0, 0.01, 0, 0, 0]))
        wait_until(lambda: servo.records("twist"))
        wait_until(lambda: not any(servo.records("twist")[-1]["twist"]))  # the watchdog's zero
        assert any(servo.records("twist")[0]["twist"])


def test_joint_and_pose_moves_are_streamed_to_their_targets(standin, ros2_domain):
    standin()
    with robot(ros2_domain) as arm:
        target = tm5_900.INITIAL_Q + np.deg2rad([5.0, -4.0, 3.0, 0.0, 4.0, -5.0])
        arm.move_to_joints(target, 0.5)
        wait_until(lambda: not arm.state().moving, timeout=20)
        assert np.max(np.abs(arm.state().q - target)) < np.deg2rad(0.3)
        pose = arm.state().tcp
        goal = Pose(pose.position + np.array([0.0, 0.02, -0.01]), pose.quat)
        arm.move_to_pose(goal, 0.05)
        wait_until(lambda: not arm.state().moving, timeout=20)
        assert np.linalg.norm(arm.state().tcp.position - goal.position) < 0.001


def test_no_arm_is_one_line_naming_topic_and_domain(ros2_domain):
    arm = robot(ros2_domain, "&servo=none")
    arm.settings = type(arm.settings)(**{**arm.settings.__dict__, "connect_timeout_s": 0.3})
    with pytest.raises(RobotError) as info:
        arm.connect()
    message = str(info.value)
    assert "\n" not in message and "/joint_states" in message and f"domain {ros2_domain}" in message


def test_a_servo_that_does_not_answer_is_one_line(standin, ros2_domain):
    standin(servo="/other_servo")
    arm = robot(ros2_domain)
    arm.settings = type(arm.settings)(**{**arm.settings.__dict__, "connect_timeout_s": 0.5})
    with pytest.raises(RobotError, match="switch_command_type service is not there"):
        arm.connect()


def test_joint_states_without_the_chains_joints_are_refused_with_the_reason(ros2_domain):
    from wovenskin.ros2 import messages
    from wovenskin.ros2.node import Ros2Node

    with Ros2Node(ros2_domain) as node:
        joints = node.publisher("/joint_states", messages.JointState)
        arm = robot(ros2_domain, "&servo=none")
        arm.settings = type(arm.settings)(**{**arm.settings.__dict__, "connect_timeout_s": 1.0})
        done = threading.Event()

        def publish() -> None:
            while not done.is_set():
                joints.publish(messages.JointState(name=["shoulder_pan_joint"], position=[0.0]))
                time.sleep(0.02)

        thread = threading.Thread(target=publish, daemon=True)
        thread.start()
        try:
            with pytest.raises(RobotError, match="lacks joint_1"):
                arm.connect()
        finally:
            done.set()
            thread.join()


@pytest.mark.parametrize(
    "spec, why",
    [
        ("ros2:?twist=servo/cmds", "not a fully qualified ROS 2 name"),
        ("ros2:?domain=500", "domain id must be 0-232"),
        ("ros2:?frame=tool0", "not on the chain"),
        ("ros2:?urdf=/no/such.urdf", "without base= and tip="),
        ("ros2:?joint_timeout=0", "not in 0.01-10"),
        ("ros2:host", "not understood"),
    ],
)
def test_bad_specs_are_one_line(spec, why):
    with pytest.raises(SpecError, match=why) as info:
        make_robot(spec)
    assert "\n" not in str(info.value)


def test_the_capabilities_leave_collisions_and_singularities_to_servo():
    arm = make_robot("ros2")
    caps = arm.capabilities()
    assert caps.kinematics is not None and caps.scene is not None
    assert caps.release_stop_s is not None and caps.release_stop_s < 0.005
    assert caps.stop_time_s is None and caps.stop_deceleration is None  # Servo's own setting
    assert any("collision" in line for line in caps.left_to_controller)
    assert any("singularit" in line for line in caps.left_to_controller)
    q = tm5_900.INITIAL_Q
    assert np.allclose(caps.kinematics.forward(q), tm5_900.forward_kinematics(q))
    assert arm.joint_limits().lower == pytest.approx(tm5_900.JOINT_LIMITS.lower)


def test_cyclone_dds_takes_its_configuration_from_cyclonedds_uri(
    monkeypatch, tmp_path, ros2_domain
):
    from wovenskin.ros2.node import Ros2Error, Ros2Node

    config = tmp_path / "one-interface.xml"
    config.write_text(
        '<CycloneDDS xmlns="https://cdds.io/config"><Domain Id="any"><General><Interfaces>'
        '<NetworkInterface name="no_such_interface0" /></Interfaces></General></Domain>'
        "</CycloneDDS>"
    )
    monkeypatch.setenv("CYCLONEDDS_URI", config.as_uri())
    with pytest.raises(Ros2Error, match="CYCLONEDDS_URI") as info:
        Ros2Node(231)  # a domain no other test uses: its configuration is read now
    assert "\n" not in str(info.value)
    arm = make_robot("ros2:?domain=231")
    with pytest.raises(RobotError, match="cannot join ROS 2 domain 231"):
        arm.connect()


def test_twists_go_out_in_the_mappings_frame_unless_the_spec_names_one():
    arm = make_robot("ros2")
    assert arm.frame == "base"
    arm.use_mapping_frame("tool")
    assert arm.frame == "tcp"  # the tip: Servo's end-effector frame
    arm.use_mapping_frame("base")
    assert arm.frame == "base"
    named = make_robot("ros2:?frame=flange")
    named.use_mapping_frame("tool")
    assert named.frame == "flange"


def test_a_headless_replay_reaches_a_real_arm_in_real_time(tmp_path):
    from wovenskin.recording.formats import write_labelled_stream
    from wovenskin.runtime.session import open_session
    from wovenskin.sim.stream import simulate_stream

    stream = tmp_path / "s.npz"
    write_labelled_stream(stream, simulate_stream(2.0, 1))
    real = open_session(f"replay:{stream}", make_robot("ros2"), fast_replay=True)
    simulated = open_session(f"replay:{stream}", "sim", fast_replay=True)
    assert real.live_skin.source.speed == 1.0  # an arm that moves on its own: real time
    assert simulated.live_skin.source.speed == 0.0  # the simulated arm: as fast as read
