"""Tests for make_robot: robot specs from the command line."""

from __future__ import annotations

import numpy as np
import pytest

from wovenskin.robots.registry import make_robot
from wovenskin.robots.techman import TechmanRobot
from wovenskin.robots.ur import URRobot


def test_techman_specs() -> None:
    robot = make_robot("tm:192.168.10.2")
    assert isinstance(robot, TechmanRobot)
    assert (robot.host, robot.port, robot.state_port) == ("192.168.10.2", 5890, 5891)
    robot = make_robot("TM:arm.local:6000")
    assert isinstance(robot, TechmanRobot)
    assert (robot.host, robot.port) == ("arm.local", 6000)


def test_ur_spec_builds_without_touching_the_network() -> None:
    robot = make_robot("ur:10.0.0.5")
    assert isinstance(robot, URRobot)
    assert robot.host == "10.0.0.5"


def test_ur_spec_names_the_arms_model() -> None:
    robot = make_robot("ur:10.0.0.5?model=UR10e")
    assert isinstance(robot, URRobot) and robot.model is not None
    assert robot.model.name == "ur10e"
    assert np.rad2deg(robot.joint_limits().max_speed).tolist() == pytest.approx(
        [120, 120, 180, 180, 180, 180]
    )
    assert make_robot("ur:10.0.0.5").model is None  # then the conservative limits
    assert np.allclose(make_robot("ur:h").joint_limits().max_speed, np.deg2rad(120.0))
    for spec, why in (("ur:h?model=ur99", "unknown UR model"), ("ur:h?speed=2", "unknown option")):
        with pytest.raises(ValueError, match=why):
            make_robot(spec)


def test_sim_spec() -> None:
    sim = pytest.importorskip("wovenskin.robots.sim")
    assert isinstance(make_robot("sim"), sim.SimRobot)


@pytest.mark.parametrize(
    "spec",
    [
        "",
        "simulator",
        "tm",
        "tm:",
        "tm:host:0",
        "tm:host:99999",
        "tm:host:x",
        "ur:h:30004",
        "kuka:1.2.3.4",
        "sim:1",
    ],
)
def test_bad_specs_list_the_valid_forms(spec: str) -> None:
    with pytest.raises(ValueError, match=r"valid forms: sim, tm:HOST\[:PORT\], ur:HOST") as info:
        make_robot(spec)
    assert "\n" not in str(info.value)
