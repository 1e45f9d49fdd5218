"""The ``ros2:`` robot spec: where the arm is on ROS 2, its URDF, and the timeouts.

``ros2:?twist=/servo_node/delta_twist_cmds&joints=/joint_states&frame=base&domain=0``
(every option has a default, so plain ``ros2`` drives a TM5-900 under a Servo node called
``servo_node`` on the ROS domain of ``ROS_DOMAIN_ID``). ``urdf=PATH`` with ``base=`` and
``tip=`` gives another arm: ``base`` must be Servo's planning frame and ``tip`` its
``ee_frame``, the link whose motion the twists command.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

from pydantic import BeforeValidator

from wovenskin.robots.base import Robot
from wovenskin.robots.ros2.settings import Ros2Settings
from wovenskin.robots.sim import tm5_900
from wovenskin.robots.spec import Backend, RobotOptions, RobotSpec
from wovenskin.robots.urdf import load_urdf_chain
from wovenskin.ros2.node import dds_topic_name, domain_id

DEFAULTS = Ros2Settings()


def ros_name(value: object) -> str:
    """A fully qualified ROS 2 name (``/a/b``), else a one-line ``ValueError``."""
    text = str(value).strip()
    dds_topic_name(text)
    return text


def servo_node(value: object) -> str:
    """A Servo node's fully qualified name, or ``none`` (do not call its service: Servo
    on another RMW, or already taking twists), kept as empty."""
    text = str(value).strip()
    return "" if text.lower() in ("", "none") else ros_name(text)


def seconds(value: object) -> float:
    """A timeout in seconds, 0.01-10."""
    number = float(str(value))
    if not 0.01 <= number <= 10.0:
        raise ValueError(f"timeout {value!r} s is not in 0.01-10")
    return number


@dataclass(frozen=True)
class Ros2Options(RobotOptions):
    """``twist``, ``joints``: topics; ``frame``: the twists' frame_id (default: the mapping's
    frame, the ``tip`` for a tool-frame mapping, the ``base`` for a base-frame one);
    ``urdf``, ``base``, ``tip``: the arm's chain (default: the TM5-900's, ``base`` to
    ``tcp``); ``domain``: the ROS domain id; ``servo``: the Servo node whose
    ``~/switch_command_type`` is called on connect (``none``: no call); ``joint_timeout``: the
    longest silence of the joint states before the arm is stopped, s."""

    twist: Annotated[str, BeforeValidator(ros_name)] = DEFAULTS.twist_topic
    joints: Annotated[str, BeforeValidator(ros_name)] = DEFAULTS.joints_topic
    frame: str | None = None
    urdf: Path | None = None
    base: str | None = None
    tip: str | None = None
    domain: Annotated[int | None, BeforeValidator(domain_id)] = None
    servo: Annotated[str, BeforeValidator(servo_node)] = DEFAULTS.servo
    joint_timeout: Annotated[float, BeforeValidator(seconds)] = DEFAULTS.joint_timeout_s


def build_ros2(spec: RobotSpec) -> Robot:
    """The arm the spec names; a URDF that cannot give the chain is one line. The backend
    (and ``cyclonedds`` with it) is imported here, so specs of other kinds never load it."""
    from wovenskin.robots.ros2.robot import Ros2Robot

    options = spec.settings
    assert isinstance(options, Ros2Options)
    if options.urdf is None:
        if options.base is not None or options.tip is not None:
            raise ValueError("gives base=/tip= without urdf= (the TM5-900's are base and tcp)")
        chain = tm5_900.urdf_chain()
    else:
        if options.base is None or options.tip is None:
            raise ValueError(
                "gives urdf= without base= and tip= (Servo's planning frame and ee_frame)"
            )
        chain = load_urdf_chain(options.urdf, options.base, options.tip)
    settings = Ros2Settings(
        twist_topic=options.twist,
        joints_topic=options.joints,
        frame=options.frame,
        domain=options.domain,
        servo=options.servo,
        joint_timeout_s=options.joint_timeout,
    )
    return Ros2Robot(chain, settings, is_default_arm=options.urdf is None)


ROS2 = Backend(
    "ros2[:?twist=/topic&joints=/topic&frame=LINK&urdf=PATH&base=LINK&tip=LINK&domain=N]",
    build_ros2,
    Ros2Options,
    address=False,
    colon_optional=True,
)
