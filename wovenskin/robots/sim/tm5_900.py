"""The Techman TM5-900: its DH table, joint limits, named postures and DH kinematics.

The numbers are the arm's published standard-DH parameters; ``tm5_900.xml`` (the MuJoCo
model) and ``tm5_900.urdf`` (the kinematic URDF the ``ros2:`` backend reads by default,
with Techman's ROS joint names :data:`JOINT_NAMES_ROS`) are built from the same table and
the tests check that all agree. Frames: the
base frame sits at the bottom of the base, z up; the tool centre point (TCP) lies
:data:`TOOL_LENGTH` along the flange's z axis, between the gripper's fingertips.
"""

from __future__ import annotations

from importlib import resources
from typing import TYPE_CHECKING

import numpy as np

from wovenskin.robots.base import N_JOINTS, JointLimits, Kinematics, SceneModel
from wovenskin.robots.dh import (
    DHLink,
    chain_frames,
    chain_jacobian,
    urdf_from_dh,
)
from wovenskin.robots.urdf import UrdfChain, load_urdf_chain

if TYPE_CHECKING:
    import mujoco

DH: tuple[DHLink, ...] = (
    DHLink(d=0.1452, a=0.0, alpha=-np.pi / 2, theta_offset=0.0),
    DHLink(d=0.0, a=0.429, alpha=0.0, theta_offset=-np.pi / 2),
    DHLink(d=0.0, a=0.4115, alpha=0.0, theta_offset=0.0),
    DHLink(d=-0.1223, a=0.0, alpha=np.pi / 2, theta_offset=np.pi / 2),
    DHLink(d=0.106, a=0.0, alpha=np.pi / 2, theta_offset=0.0),
    DHLink(d=0.11315, a=0.0, alpha=0.0, theta_offset=0.0),
)

TOOL_LENGTH = 0.14  # m, flange -> TCP along the flange z axis (the gripper's fingertips)

JOINT_LIMITS = JointLimits(
    lower=np.deg2rad([-270.0, -180.0, -155.0, -180.0, -180.0, -270.0]),
    upper=np.deg2rad([270.0, 180.0, 155.0, 180.0, 180.0, 270.0]),
    max_speed=np.deg2rad([180.0, 180.0, 180.0, 225.0, 225.0, 225.0]),
)

JOINT_NAMES = ("joint1", "joint2", "joint3", "joint4", "joint5", "joint6")  # MuJoCo's
JOINT_NAMES_ROS = ("joint_1", "joint_2", "joint_3", "joint_4", "joint_5", "joint_6")
"""The joints' names on ROS: Techman's, as in its ``tmr_ros2`` driver and ``tm_description``."""

JOINT_EFFORT = (157.0, 157.0, 157.0, 43.0, 43.0, 43.0)
"""N m, the effort limits of Techman's ``tm_description`` URDF (the URDF spec requires one;
wovenskin does not use them)."""

HOME_Q = np.zeros(N_JOINTS)  # all joints at zero: the arm stands upright
INITIAL_Q = np.deg2rad([0.0, 0.0, 90.0, 0.0, 90.0, 0.0])  # TCP 0.52 m in front, tool down


def _joint_vector(q: np.ndarray) -> np.ndarray:
    joints = np.asarray(q, dtype=float)
    if joints.shape != (N_JOINTS,):
        raise ValueError(f"joint vector must have shape ({N_JOINTS},), got {joints.shape}")
    if not np.all(np.isfinite(joints)):
        raise ValueError("joint vector has non-finite values")
    return joints


def tool_transform() -> np.ndarray:
    """Flange <- TCP."""
    transform = np.eye(4)
    transform[2, 3] = TOOL_LENGTH
    return transform


def frame_transforms(q: np.ndarray) -> list[np.ndarray]:
    """Base <- DH frame i for i = 0..6 (frame 0 is the base, frame 6 the flange)."""
    return chain_frames(DH, _joint_vector(q))


def forward_kinematics(q: np.ndarray) -> np.ndarray:
    """The 4x4 pose of the TCP in the base frame (base <- tcp) at joint angles ``q``."""
    return frame_transforms(q)[-1] @ tool_transform()


def jacobian(q: np.ndarray) -> np.ndarray:
    """The 6x6 geometric Jacobian of the TCP in the base frame: ``[v; w] = J @ dq``.

    ``v`` is the linear velocity of the TCP point, ``w`` the angular velocity.
    """
    return chain_jacobian(DH, _joint_vector(q), tool_transform())


# Where the skin sits on the end link (the MJCF's "skin_patch" site), in that site's frame:
# the skin's "up" (toward row 0, docs/gestures.md) and "right" (toward higher columns) axes.
# The site is 140 mm along its x (the skin's 10 rows x 14 mm) and 100 mm along its z, the
# tool axis (10 columns x 10 mm); its y axis is the outward normal.
SKIN_SITE = "skin_patch"
SKIN_UP_AXIS = np.array([1.0, 0.0, 0.0])
SKIN_RIGHT_AXIS = np.array([0.0, 0.0, 1.0])


def kinematics() -> Kinematics:
    """The DH model's TCP kinematics, as a backend declares it (``RobotCapabilities``)."""
    return Kinematics(forward=forward_kinematics, jacobian=jacobian)


def scene() -> SceneModel:
    """The arm's MuJoCo model (``tm5_900.xml``) and its skin patch, for the 3D view."""
    return SceneModel(load_model, SKIN_SITE, SKIN_UP_AXIS, SKIN_RIGHT_AXIS)


MODEL_FILE = "tm5_900.xml"
"""The packaged MuJoCo model of the arm, in ``wovenskin.robots.sim``."""


def load_model() -> mujoco.MjModel:
    """The packaged MuJoCo model of the TM5-900."""
    import mujoco

    path = resources.files("wovenskin.robots.sim").joinpath(MODEL_FILE)
    with resources.as_file(path) as file:
        return mujoco.MjModel.from_xml_path(str(file))


URDF_FILE = "tm5_900.urdf"
"""The packaged kinematic URDF of the arm, in ``wovenskin.robots.sim``: :func:`urdf_from_table`'s
text (a test keeps them equal). Links ``base``, ``link_1``..``link_6``, ``flange`` and
``tcp``."""
URDF_BASE, URDF_FLANGE, URDF_TIP = "base", "flange", "tcp"


def urdf_from_table() -> str:
    """The URDF written from :data:`DH`, :data:`JOINT_LIMITS` and :data:`TOOL_LENGTH`; to
    regenerate the packaged file: ``python -c "from wovenskin.robots.sim import tm5_900;
    print(tm5_900.urdf_from_table(), end='')" > wovenskin/robots/sim/tm5_900.urdf``."""
    return urdf_from_dh(
        "tm5_900", DH, JOINT_LIMITS, JOINT_NAMES_ROS, tool_transform(), URDF_TIP, JOINT_EFFORT
    )


def urdf_text() -> str:
    """The packaged URDF of the TM5-900 (:data:`URDF_FILE`)."""
    return resources.files("wovenskin.robots.sim").joinpath(URDF_FILE).read_text("utf-8")


def urdf_chain() -> UrdfChain:
    """The packaged URDF's chain from ``base`` to ``tcp``."""
    return load_urdf_chain(urdf_text(), URDF_BASE, URDF_TIP)
