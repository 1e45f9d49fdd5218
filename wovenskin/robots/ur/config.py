"""The ``ur:HOST`` robot spec: the arm's model option, and the :class:`URRobot` it builds."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated

from pydantic import BeforeValidator

from wovenskin.robots.spec import Backend, RobotOptions, RobotSpec
from wovenskin.robots.ur.models import ur_model
from wovenskin.robots.ur.robot import URRobot


def model_name(value: object) -> str:
    """A known UR model's name (``ur3e``, ``ur5e``, ``ur10e``, ``ur16e``), in any case."""
    return ur_model(str(value).lower()).name


@dataclass(frozen=True)
class UROptions(RobotOptions):
    """``model``: the arm's model, which brings its kinematics (none: conservative limits)."""

    model: Annotated[str | None, BeforeValidator(model_name)] = None


def build_ur(spec: RobotSpec) -> URRobot:
    """The UR arm at the spec's host, of the model it names."""
    assert spec.host is not None and isinstance(spec.settings, UROptions)
    return URRobot(spec.host, model=spec.settings.model)


UR = Backend(
    "ur:HOST[?model=ur5e]",
    build_ur,
    UROptions,
    port="gives a port, but ur_rtde uses the robot's fixed RTDE port",
)
