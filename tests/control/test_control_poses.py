"""PoseStore: named poses in a TOML file, the default location, and storing the robot's pose."""

from __future__ import annotations

import math
import tomllib

import numpy as np
import pytest

from wovenskin.control.poses import (
    NamedPose,
    PoseStore,
    default_poses_path,
    set_pose_from_robot,
)
from wovenskin.robots import sim
from wovenskin.robots.base import JointLimits, Pose, Robot, RobotError, RobotState

Q = np.array([0.1, -0.2, 1.5, 0.0, 1.4, -0.3])
TCP = Pose([0.5, -0.12, 0.32], [0.0, math.sqrt(0.5), math.sqrt(0.5), 0.0])


def test_a_missing_file_is_an_empty_store(tmp_path) -> None:
    store = PoseStore.load(tmp_path / "none.toml")
    assert store.get("initial") is None and store.get("home") is None and store.names == []


def test_poses_round_trip_through_the_file(tmp_path) -> None:
    path = tmp_path / "sub" / "poses.toml"
    store = PoseStore.load(path)
    store.set("initial", Q, TCP)
    store.set("home", np.zeros(6), Pose([0.0, -0.37, 1.09], [1, 0, 0, 0]))
    assert store.save() == path
    data = tomllib.loads(path.read_text())  # plain TOML that people can edit
    assert data["initial"]["q"] == pytest.approx(list(Q))
    again = PoseStore.load(path)
    assert again.names == ["initial", "home"]
    pose = again.get("initial")
    assert isinstance(pose, NamedPose)
    np.testing.assert_array_equal(pose.q, Q)  # exact: floats are written with repr
    np.testing.assert_array_equal(pose.tcp.position, TCP.position)
    np.testing.assert_allclose(pose.tcp.quat, TCP.quat, rtol=0, atol=1e-15)


def test_set_replaces_and_save_keeps_the_other_pose(tmp_path) -> None:
    path = tmp_path / "poses.toml"
    store = PoseStore.load(path)
    store.set("home", np.zeros(6), TCP)
    store.set("initial", Q, TCP)
    store.save()
    store = PoseStore.load(path)
    store.set("initial", Q * 0.5, TCP)
    store.save()
    again = PoseStore.load(path)
    np.testing.assert_array_equal(again.get("initial").q, Q * 0.5)
    np.testing.assert_array_equal(again.get("home").q, np.zeros(6))


def test_the_default_path_follows_wovenskin_home(monkeypatch, tmp_path) -> None:
    monkeypatch.setenv("WOVENSKIN_HOME", str(tmp_path))
    assert default_poses_path() == tmp_path / "poses.toml"
    assert PoseStore.load().path == tmp_path / "poses.toml"
    monkeypatch.delenv("WOVENSKIN_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "me"))
    assert default_poses_path() == tmp_path / "me" / ".config" / "wovenskin" / "poses.toml"


@pytest.mark.parametrize(
    ("q", "tcp", "match"),
    [
        (Q[:5], TCP, "6 finite"),
        (np.full(6, np.nan), TCP, "6 finite"),
        (Q, "here", "Pose"),
    ],
)
def test_bad_poses_are_refused(tmp_path, q, tcp, match) -> None:
    store = PoseStore.load(tmp_path / "poses.toml")
    with pytest.raises(ValueError, match=match):
        store.set("initial", q, tcp)
    assert store.get("initial") is None


def test_unknown_names_are_refused(tmp_path) -> None:
    store = PoseStore.load(tmp_path / "poses.toml")
    with pytest.raises(ValueError, match="unknown pose name 'start'"):
        store.set("start", Q, TCP)
    with pytest.raises(ValueError, match="unknown pose name"):
        store.get("start")


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("[initial]\nq = [0, 0, 0]\nposition = [0, 0, 0]\nquat = [1, 0, 0, 0]\n", "initial.q"),
        (
            "[initial]\nq = [0, 0, 0, 0, 0, 0]\nposition = [0, 0, nan]\nquat = [1, 0, 0, 0]\n",
            "initial.position",
        ),
        (
            "[initial]\nq = [0, 0, 0, 0, 0, 0]\nposition = [0, 0, 0]\nquat = [0, 0, 0, 0]\n",
            "zero norm",
        ),
        ("[start]\nq = [0, 0, 0, 0, 0, 0]\n", "start"),
        ("[initial]\nq = [0, 0, 0, 0, 0, 0]\ncolour = 1\n", "initial.colour"),
        ("initial = 3\n", "must be a table"),
        ("[initial\n", "not valid TOML"),
    ],
)
def test_bad_files_give_one_line_naming_the_file(tmp_path, text: str, match: str) -> None:
    path = tmp_path / "poses.toml"
    path.write_text(text)
    with pytest.raises(ValueError) as info:
        PoseStore.load(path)
    message = str(info.value)
    assert "\n" not in message and message.startswith(str(path)) and match in message


class StillRobot(Robot):
    """A robot standing at ``Q`` and ``TCP``; it counts commands so tests can see none."""

    def __init__(self, fault: str | None = None) -> None:
        self.fault = fault
        self.commands = 0

    def connect(self) -> None: ...

    def disconnect(self) -> None: ...

    def state(self) -> RobotState:
        return RobotState(1.0, Q.copy(), np.zeros(6), TCP, fault=self.fault)

    def joint_limits(self) -> JointLimits:
        return JointLimits(-np.full(6, 3.0), np.full(6, 3.0), np.full(6, 1.0))

    def send_twist(self, twist) -> None:
        self.commands += 1

    def move_to_joints(self, q, speed_fraction=0.2) -> None:
        self.commands += 1

    def move_to_pose(self, pose, speed=0.05) -> None:
        self.commands += 1

    def stop(self) -> None:
        self.commands += 1


def test_set_pose_from_robot_stores_and_saves_the_current_pose(tmp_path) -> None:
    path = tmp_path / "poses.toml"
    robot = StillRobot()
    pose = set_pose_from_robot(PoseStore.load(path), "initial", robot)
    assert pose.name == "initial" and robot.commands == 0  # reading only
    stored = PoseStore.load(path).get("initial")
    np.testing.assert_array_equal(stored.q, Q)
    np.testing.assert_array_equal(stored.tcp.position, TCP.position)


def test_set_pose_from_a_faulted_robot_is_refused(tmp_path) -> None:
    path = tmp_path / "poses.toml"
    with pytest.raises(RobotError, match="protective stop"):
        set_pose_from_robot(PoseStore.load(path), "initial", StillRobot("protective stop"))
    assert not path.exists()


def test_set_pose_from_the_simulated_arm(tmp_path) -> None:
    robot = sim.SimRobot()
    robot.connect()
    pose = set_pose_from_robot(PoseStore.load(tmp_path / "p.toml"), "home", robot)
    np.testing.assert_allclose(pose.q, sim.tm5_900.INITIAL_Q)
    expected = sim.tm5_900.forward_kinematics(sim.tm5_900.INITIAL_Q)[:3, 3]
    np.testing.assert_allclose(pose.tcp.position, expected, atol=1e-6)
