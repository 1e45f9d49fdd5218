"""Tests for make_robot: robot specs from the command line."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

import wovenskin
from wovenskin import specs
from wovenskin.errors import ConfigError
from wovenskin.robots import registry
from wovenskin.robots.registry import SpecError, make_robot, parse_robot_spec
from wovenskin.robots.sim import SimRobot
from wovenskin.robots.spec import Backend, RobotOptions, RobotSpec
from wovenskin.robots.techman import TechmanRobot
from wovenskin.robots.ur import URRobot

VALID_FORMS = r"valid forms: sim, tm:HOST\[:PORT\]\[\?listen_port=N&state_port=N\], ur:HOST"


def test_techman_specs() -> None:
    robot = make_robot("tm:192.168.10.2")
    assert isinstance(robot, TechmanRobot)
    assert (robot.host, robot.port, robot.state_port) == ("192.168.10.2", 5890, 5891)
    robot = make_robot("TM:arm.local:6000")
    assert isinstance(robot, TechmanRobot)
    assert (robot.host, robot.port, robot.state_port) == ("arm.local", 6000, 5891)


def test_techman_spec_sets_both_ports() -> None:
    robot = make_robot("tm:127.0.0.1?listen_port=6001&state_port=6002")
    assert isinstance(robot, TechmanRobot)
    assert (robot.host, robot.port, robot.state_port) == ("127.0.0.1", 6001, 6002)
    robot = make_robot("tm:10.0.0.9?state_port=7000")
    assert (robot.port, robot.state_port) == (5890, 7000)
    robot = make_robot("tm:10.0.0.9:6000?state_port=7000&safety=degraded")
    assert (robot.port, robot.state_port, robot.degraded_safety) == (6000, 7000, True)


@pytest.mark.parametrize(
    ("spec", "why"),
    [
        ("tm:h?listen_port=0", "bad port '0'"),
        ("tm:h?state_port=70000", "bad port '70000'"),
        ("tm:h?state_port=x", "bad port 'x'"),
        ("tm:h?state_port=", "no value for option 'state_port'"),
        ("tm:h?listen_port=1&listen_port=2", "option 'listen_port' twice"),
        ("tm:h:6000?listen_port=6001", "Listen Node port twice"),
        ("tm:h?listen_port=5891", "port 5891 for both"),
        ("tm:h?port=5890", "unknown option 'port=5890'"),
    ],
)
def test_bad_techman_ports_are_one_line(spec: str, why: str) -> None:
    with pytest.raises(ValueError, match="valid forms") as info:
        make_robot(spec)
    assert why in str(info.value) and "\n" not in str(info.value)


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
    assert isinstance(make_robot("sim"), SimRobot)


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
    with pytest.raises(ValueError, match=VALID_FORMS) as info:
        make_robot(spec)
    assert "\n" not in str(info.value)


# -- one place, one line -------------------------------------------------------------------


def test_specs_are_parsed_without_building_anything() -> None:
    spec = parse_robot_spec(" UR:10.0.0.5?model=UR5e&safety=degraded ")
    assert (spec.kind, spec.host, spec.port) == ("ur", "10.0.0.5", None)
    assert spec.options == {"model": "ur5e", "safety": "degraded"} and spec.degraded_safety
    spec = parse_robot_spec("tm:arm.local:6000")
    assert (spec.kind, spec.host, spec.port) == ("tm", "arm.local", 6000)
    assert not spec.degraded_safety
    assert parse_robot_spec("sim?safety=full").options == {"safety": "full"}


def test_the_degraded_safety_opt_in_travels_with_the_backend() -> None:
    assert make_robot("ur:10.0.0.5?safety=degraded").degraded_safety
    assert not make_robot("ur:10.0.0.5").degraded_safety
    assert make_robot("tm:10.0.0.5?safety=DEGRADED").degraded_safety


@pytest.mark.parametrize(
    ("spec", "why"),
    [
        ("tm:host?speed=2", "unknown option 'speed=2'"),  # was taken for the host 'host?speed=2'
        ("tm:host?", "empty option list"),
        ("tm:ho/st", "no valid host"),
        ("ur:h?model=ur5e&model=ur10e", "option 'model' twice"),
        ("ur:h?model=", "no value for option 'model'"),
        ("ur:h?model", "no value for option 'model'"),
        ("sim?safety=off", "spec 'sim?safety=off' has bad sim options: safety: unknown safety"),
        ("tm:h?state_port=x", "spec 'tm:h?state_port=x' has bad tm options: state_port: bad port"),
        ("sim:?safety=degraded", "not understood"),
        ("ur:h?model=ur99", "unknown UR model 'ur99'"),
    ],
)
def test_bad_options_are_one_line_naming_the_problem(spec: str, why: str) -> None:
    for parse in (parse_robot_spec, make_robot):
        with pytest.raises(ValueError, match="valid forms") as info:
            parse(spec)
        assert why in str(info.value) and "\n" not in str(info.value)


def test_no_other_module_parses_robot_specs() -> None:
    """Robot spec strings are taken apart in robots/registry.py only (other modules pass
    them on to make_robot or parse_robot_spec)."""
    root = Path(wovenskin.__file__).parent
    offenders = []
    for path in root.rglob("*.py"):
        if path.name == "registry.py" and path.parent.name == "robots":
            continue
        text = path.read_text(encoding="utf-8")
        for needle in ('"tm:"', "'tm:'", '"ur:"', "'ur:'", 'startswith("tm', 'startswith("ur'):
            if needle in text:
                offenders.append(f"{path.relative_to(root)}: {needle}")
    assert offenders == []


def test_spec_errors_are_config_errors() -> None:
    with pytest.raises(SpecError) as info:
        make_robot("kuka:1.2.3.4")
    assert isinstance(info.value, specs.SpecError) and isinstance(info.value, ConfigError)


def test_a_backend_registered_with_one_line_is_reachable_by_its_spec(monkeypatch) -> None:
    """A new backend: its options dataclass, its build function and one registry line."""

    @dataclass(frozen=True)
    class ToyOptions(RobotOptions):
        speed: float = 1.0

    built: list[RobotSpec] = []

    def build_toy(spec: RobotSpec) -> SimRobot:
        built.append(spec)
        return SimRobot()

    toy = Backend("toy:HOST[?speed=X]", build_toy, ToyOptions)
    monkeypatch.setitem(registry.BACKENDS, "toy", toy)  # the one registry line

    robot = make_robot("toy:arm.local?speed=2.5&safety=degraded")
    assert isinstance(robot, SimRobot) and robot.degraded_safety
    assert built[0].host == "arm.local" and built[0].settings == ToyOptions("degraded", 2.5)
    assert parse_robot_spec("toy:h").settings == ToyOptions()
    with pytest.raises(SpecError, match=r"unknown option 'gain=2'.*valid forms: .*toy:HOST"):
        make_robot("toy:h?gain=2")
    with pytest.raises(SpecError, match="speed"):
        make_robot("toy:h?speed=fast")
