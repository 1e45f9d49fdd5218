"""Arm kinematics read from a URDF, and the TM5-900's packaged URDF written from its DH table."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from wovenskin.errors import ConfigError
from wovenskin.robots import urdf
from wovenskin.robots.base import JointLimits
from wovenskin.robots.dh import DHLink, chain_frames, chain_jacobian, dh_transform, urdf_from_dh
from wovenskin.robots.sim import tm5_900
from wovenskin.robots.urdf import UrdfError, load_urdf_chain, matrix_rpy, rpy_matrix

LIMITS = tm5_900.JOINT_LIMITS
ANGLE = st.floats(-math.pi, math.pi)


@pytest.fixture(scope="module")
def chain() -> urdf.UrdfChain:
    return tm5_900.urdf_chain()


def random_q(rng: np.random.Generator) -> np.ndarray:
    return rng.uniform(LIMITS.lower, LIMITS.upper)


def test_the_packaged_urdf_is_what_urdf_from_dh_writes() -> None:
    assert tm5_900.urdf_text() == tm5_900.urdf_from_table(), (
        "wovenskin/robots/sim/tm5_900.urdf is stale: regenerate it (tm5_900.urdf_from_table)"
    )


def test_the_packaged_chain_has_techmans_names_and_the_arms_limits(chain) -> None:
    assert chain.joint_names == tm5_900.JOINT_NAMES_ROS
    assert (chain.base_link, chain.tip_link, chain.name) == ("base", "tcp", "tm5_900")
    assert chain.links == ("base", *(f"link_{i}" for i in range(1, 7)), "flange", "tcp")
    for got, want in zip(
        (chain.limits.lower, chain.limits.upper, chain.limits.max_speed),
        (LIMITS.lower, LIMITS.upper, LIMITS.max_speed),
        strict=True,
    ):
        np.testing.assert_array_equal(got, want)


def test_the_packaged_chain_equals_the_dh_kinematics(chain) -> None:
    rng = np.random.default_rng(24)
    kinematics = chain.kinematics()
    for _ in range(300):
        q = random_q(rng)
        np.testing.assert_allclose(kinematics.forward(q), tm5_900.forward_kinematics(q), atol=1e-9)
        np.testing.assert_allclose(kinematics.jacobian(q), tm5_900.jacobian(q), atol=1e-9)
        flange = tm5_900.frame_transforms(q)[-1]
        np.testing.assert_allclose(chain.link_pose(q, "flange"), flange, atol=1e-9)
    np.testing.assert_array_equal(chain.link_pose(q, "base"), np.eye(4))


def numeric_jacobian(forward, q: np.ndarray, h: float = 1e-6) -> np.ndarray:
    columns = []
    for k in range(q.size):
        step = np.zeros(q.size)
        step[k] = h
        plus, minus = forward(q + step), forward(q - step)
        linear = (plus[:3, 3] - minus[:3, 3]) / (2 * h)
        turn = plus[:3, :3] @ minus[:3, :3].T  # ~ I + [w]x (2h)
        angular = np.array([turn[2, 1] - turn[1, 2], turn[0, 2] - turn[2, 0],
                            turn[1, 0] - turn[0, 1]]) / (4 * h)  # fmt: skip
        columns.append(np.concatenate((linear, angular)))
    return np.array(columns).T


@settings(max_examples=40, deadline=None)
@given(fractions=st.lists(st.floats(0.0, 1.0), min_size=6, max_size=6))
def test_the_jacobian_is_the_derivative_of_forward(chain, fractions) -> None:
    q = LIMITS.lower + np.array(fractions) * (LIMITS.upper - LIMITS.lower)
    np.testing.assert_allclose(chain.jacobian(q), numeric_jacobian(chain.forward, q), atol=1e-6)


ROWS = st.lists(
    st.builds(DHLink, d=st.floats(-1, 1), a=st.floats(-1, 1), alpha=ANGLE, theta_offset=ANGLE),
    min_size=6, max_size=6,
)  # fmt: skip


@settings(max_examples=30, deadline=None)
@given(table=ROWS, tool_rpy=st.tuples(ANGLE, ANGLE, ANGLE), seed=st.integers(0, 2**31))
def test_a_urdf_written_from_any_table_reads_back_its_kinematics(table, tool_rpy, seed) -> None:
    tool = np.eye(4)
    tool[:3, :3], tool[:3, 3] = rpy_matrix(tool_rpy), [0.01, -0.02, 0.15]
    limits = JointLimits(np.full(6, -4.0), np.full(6, 4.0), np.full(6, 2.0))
    names = [f"j{i}" for i in range(6)]
    text = urdf_from_dh("arm", table, limits, names, tool, tip_link="tool0")
    arm = load_urdf_chain(text, "base", "tool0")
    q = np.random.default_rng(seed).uniform(-3, 3, 6)
    frames = chain_frames(table, q)
    np.testing.assert_allclose(arm.forward(q), frames[-1] @ tool, atol=1e-9)
    np.testing.assert_allclose(arm.jacobian(q), chain_jacobian(table, q, tool), atol=1e-9)
    for i in range(1, 7):  # link_i is DH frame i-1 turned by joint i about its z axis
        turned = frames[i - 1] @ dh_transform(DHLink(0.0, 0.0, 0.0, 0.0), q[i - 1])
        np.testing.assert_allclose(arm.link_pose(q, f"link_{i}"), turned, atol=1e-9)


@settings(max_examples=200, deadline=None)
@given(rpy=st.tuples(ANGLE, st.floats(-math.pi / 2, math.pi / 2), ANGLE))
def test_rpy_is_fixed_axis_xyz_and_round_trips(rpy) -> None:
    matrix = rpy_matrix(rpy)
    np.testing.assert_allclose(matrix, Rotation.from_euler("xyz", rpy).as_matrix(), atol=1e-12)
    back = matrix_rpy(matrix)
    np.testing.assert_allclose(rpy_matrix(back), matrix, atol=1e-9)
    assert -math.pi / 2 <= back[1] <= math.pi / 2


@pytest.mark.parametrize("pitch", [math.pi / 2, -math.pi / 2])
def test_rpy_at_gimbal_lock_keeps_the_rotation(pitch) -> None:
    matrix = rpy_matrix([0.7, pitch, -0.4])
    back = matrix_rpy(matrix)
    np.testing.assert_allclose(rpy_matrix(back), matrix, atol=1e-12)
    assert back[2] == 0.0


def test_rpy_of_known_rotations() -> None:
    np.testing.assert_allclose(rpy_matrix([0, 0, math.pi / 2]) @ [1, 0, 0], [0, 1, 0], atol=1e-15)
    np.testing.assert_allclose(rpy_matrix([math.pi / 2, 0, 0]) @ [0, 1, 0], [0, 0, 1], atol=1e-15)
    # roll first, then yaw, both about the fixed axes: x -> x -> y, and y -> z -> z
    both = rpy_matrix([math.pi / 2, 0, math.pi / 2])
    np.testing.assert_allclose(both @ [1, 0, 0], [0, 1, 0], atol=1e-15)
    np.testing.assert_allclose(both @ [0, 1, 0], [0, 0, 1], atol=1e-15)
    with pytest.raises(ValueError, match="finite 3x3"):
        matrix_rpy(np.full((3, 3), np.nan))


# A planar 3R arm (links L1, L2, L3 along x, axes z) on a mount turned 90 degrees about z and
# raised by H, with a spherical wrist at its end: axes z (continuous), y (given as 0 2 0),
# x (the default axis). A prismatic gripper finger hangs off the tip, off the chain.
L1, L2, L3, H = 0.4, 0.3, 0.2, 0.1
HAND = f"""<?xml version="1.0" encoding="utf-8"?>
<robot name="planar">
  <link name="world"/> <link name="mount"/> <link name="a"/> <link name="b"/> <link name="c"/>
  <link name="w1"/> <link name="w2"/> <link name="tip"/> <link name="finger"/>
  <joint name="mount_joint" type="fixed">
    <parent link="world"/> <child link="mount"/> <origin xyz="0 0 {H}" rpy="0 0 {math.pi / 2!r}"/>
  </joint>
  <joint name="shoulder" type="revolute">
    <parent link="mount"/> <child link="a"/> <axis xyz="0 0 1"/>
    <limit lower="-2" upper="2" velocity="1.5" effort="10"/>
  </joint>
  <joint name="elbow" type="revolute">
    <parent link="a"/> <child link="b"/> <origin xyz="{L1} 0 0"/> <axis xyz="0 0 1"/>
    <limit lower="-2.5" upper="2.5" velocity="1.5"/>
  </joint>
  <joint name="wrist" type="revolute">
    <parent link="b"/> <child link="c"/> <origin xyz="{L2} 0 0" rpy="0 0 0"/> <axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" velocity="2"/>
  </joint>
  <joint name="roll" type="continuous">
    <parent link="c"/> <child link="w1"/> <origin xyz="{L3} 0 0"/> <axis xyz="0 0 1"/>
    <limit velocity="3"/>
  </joint>
  <joint name="pitch" type="revolute">
    <parent link="w1"/> <child link="w2"/> <axis xyz="0 2 0"/>
    <limit lower="-1" upper="1" velocity="3"/>
  </joint>
  <joint name="yaw" type="revolute">
    <parent link="w2"/> <child link="tip"/> <limit lower="-1" upper="1" velocity="3"/>
  </joint>
  <joint name="finger_joint" type="prismatic">
    <parent link="tip"/> <child link="finger"/> <limit lower="0" upper="0.04" velocity="0.1"/>
  </joint>
</robot>
"""


def planar_forward(q: np.ndarray) -> np.ndarray:
    s1, s12, s123 = np.sin(np.cumsum(q[:3]))
    c1, c12, c123 = np.cos(np.cumsum(q[:3]))
    x, y = L1 * c1 + L2 * c12 + L3 * c123, L1 * s1 + L2 * s12 + L3 * s123
    pose = np.eye(4)
    pose[:3, 3] = [-y, x, H]  # the mount's 90 degree turn: (x, y) -> (-y, x)
    yaw = math.pi / 2 + q[0] + q[1] + q[2] + q[3]
    pose[:3, :3] = Rotation.from_euler("ZYX", [yaw, q[4], q[5]]).as_matrix()  # z, then y, x
    return pose


def test_a_hand_written_urdf_has_its_closed_form_kinematics(tmp_path: Path) -> None:
    file = tmp_path / "planar.urdf"
    file.write_text(HAND, encoding="utf-8")
    for source in (HAND, "\ufeff\n" + HAND, file, str(file)):
        arm = load_urdf_chain(source, "world", "tip")
        assert arm.joint_names == ("shoulder", "elbow", "wrist", "roll", "pitch", "yaw")
        assert arm.links == ("world", "mount", "a", "b", "c", "w1", "w2", "tip")
    np.testing.assert_array_equal(arm.limits.lower, [-2, -2.5, -3, -2 * math.pi, -1, -1])
    np.testing.assert_array_equal(arm.limits.upper, [2, 2.5, 3, 2 * math.pi, 1, 1])
    np.testing.assert_array_equal(arm.limits.max_speed, [1.5, 1.5, 2, 3, 3, 3])
    rng = np.random.default_rng(3)
    for _ in range(50):
        q = rng.uniform(-1, 1, 6)
        np.testing.assert_allclose(arm.forward(q), planar_forward(q), atol=1e-12)
        np.testing.assert_allclose(arm.jacobian(q), numeric_jacobian(arm.forward, q), atol=1e-7)
        elbow = arm.link_pose(q, "b")[:3, 3]
        np.testing.assert_allclose(elbow, [-L1 * np.sin(q[0]), L1 * np.cos(q[0]), H], atol=1e-12)
    # the chain can stop short of the tip, and start above the mount
    wrist = load_urdf_chain(HAND.replace('"finger_joint" type="prismatic"', '"f" type="fixed"'),
                            "mount", "finger")  # fmt: skip
    assert wrist.links[-2:] == ("tip", "finger")


def mutated(old: str, new: str, count: int = 1) -> str:
    text = tm5_900.urdf_text()
    assert old in text, old
    return text.replace(old, new, count)


J2 = '<joint name="joint_2" type="revolute">'
LOOP = """<robot name="loop"><link name="base"/><link name="a"/><link name="b"/>
<joint name="ab" type="fixed"><parent link="a"/><child link="b"/></joint>
<joint name="ba" type="fixed"><parent link="b"/><child link="a"/></joint></robot>"""
XACRO = """<robot xmlns:xacro="http://www.ros.org/wiki/xacro" name="x">
<xacro:macro name="arm"/></robot>"""
BAD = {
    "no such file": ("/nonexistent/arm.urdf", "does not exist"),
    "a directory": ("/tmp", "not a regular file"),
    "nul in path": ("arm\0.urdf", "does not exist"),
    "path too long": ("a" * 5000, "neither XML text nor a file path"),
    "empty": ("", "neither XML text nor a file path"),
    "not text": (42, "text or a file path"),
    "bad xml": ("<robot><link></robot>", "not well-formed XML: mismatched tag"),
    "not a robot": ("<sdf/>", "root element is <sdf>"),
    "xacro": (XACRO, "xacro file"),
    "entities": ('<!DOCTYPE r [<!ENTITY a "b">]><robot/>', "entities"),
    "unnamed link": (mutated('<link name="link_4"/>', "<link/>"), "a <link> has no name"),
    "two links": (mutated("<link name", '<link name="link_2"/><link name', 1), "two links"),
    "two joints": (mutated('"joint_3"', '"joint_2"'), "two joints are named 'joint_2'"),
    "no parent": (mutated('<parent link="link_1"/>', ""), "'joint_2' has no parent link"),
    "no child": (mutated('<child link="link_1"/>', "<child/>"), "'joint_1' has no child link"),
    "undeclared": (mutated('<parent link="link_1"/>', '<parent link="x"/>'), "undeclared link"),
    "unknown type": (mutated(J2, '<joint name="joint_2" type="ball">'), "unknown type 'ball'"),
    "two parents": (
        mutated(
            "</robot>",
            '<joint name="x" type="fixed"><parent link="base"/>'
            '<child link="link_3"/></joint></robot>',
        ),  # fmt: skip
        "child of two joints",
    ),
    "nan origin": (mutated('xyz="0 0 0.1452"', 'xyz="0 0 nan"'), "origin xyz '0 0 nan'"),
    "short rpy": (mutated('rpy="1.5707963267948966 0 0"', 'rpy="1 0"'), "not 3 finite numbers"),
    "prismatic": (mutated(J2, J2.replace("revolute", "prismatic")), "'joint_2' on the chain is"),
    "floating": (mutated(J2, J2.replace("revolute", "floating")), "is floating"),
    "planar": (mutated(J2, J2.replace("revolute", "planar")), "is planar"),
    "five joints": (mutated(J2, J2.replace("revolute", "fixed")), "has 5 moving joints"),
    "seven joints": (
        mutated('"flange_fixed_joint" type="fixed"', '"f" type="continuous"'),
        "has 7 moving joints",
    ),
    "zero axis": (mutated('<axis xyz="0 0 1"/>', '<axis xyz="0 0 0"/>'), "zero axis"),
    "no velocity": (mutated(' velocity="3.141592653589793"', ""), "has no <limit velocity"),
    "no limit": (mutated("<limit ", "<nolimit "), "'joint_1' has no <limit velocity"),
    "slow": (mutated('velocity="3.141592653589793"', 'velocity="0"'), "is not positive"),
    "no range": (mutated('lower="-4.71238898038469"', 'lower="5"'), "is not below upper"),
    "mimic": (mutated(J2, J2 + '<mimic joint="joint_1"/>'), "mimics another joint"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_every_malformed_urdf_is_one_line(case: str) -> None:
    source, message = BAD[case]
    with pytest.raises(UrdfError, match=message) as error:
        load_urdf_chain(source, "base", "tcp")
    assert isinstance(error.value, ConfigError | ValueError)
    assert "\n" not in str(error.value) and len(str(error.value)) < 300


@pytest.mark.parametrize(
    ("base", "tip", "message"),
    [
        ("link_3", "link_1", "'link_1' does not hang below 'link_3'"),
        ("nowhere", "tcp", "no base link 'nowhere'"),
        ("base", "tcp\n", "no tip link 'tcp\\\\n'"),
        ("base", "link_4", "has 4 moving joints"),
    ],
)
def test_a_chain_that_is_not_there_is_one_line(base: str, tip: str, message: str) -> None:
    with pytest.raises(UrdfError, match=message) as error:
        load_urdf_chain(tm5_900.urdf_text(), base, tip)
    assert "\n" not in str(error.value)


def test_a_loop_is_one_line() -> None:
    with pytest.raises(UrdfError, match="loop through link 'a'"):
        load_urdf_chain(LOOP, "base", "a")


def test_huge_urdfs_are_refused_unread(tmp_path: Path, monkeypatch) -> None:
    huge = tmp_path / "huge.urdf"
    with huge.open("wb") as file:
        file.truncate(2**30)  # 1 GiB, sparse: nothing is written
    with pytest.raises(UrdfError, match="larger than"):
        load_urdf_chain(huge, "base", "tcp")
    monkeypatch.setattr(urdf, "MAX_URDF_BYTES", 100)
    with pytest.raises(UrdfError, match="URDF text is larger than 100 bytes"):
        load_urdf_chain(tm5_900.urdf_text(), "base", "tcp")


def test_bad_joint_vectors_and_links_are_one_line(chain) -> None:
    with pytest.raises(ValueError, match="non-finite"):
        chain.jacobian([0.0, 0.0, np.nan, 0.0, 0.0, 0.0])
    with pytest.raises(ValueError, match=r"shape \(6,\)"):
        chain.forward(np.zeros(5))
    with pytest.raises(UrdfError, match="'link_9' is not on the chain"):
        chain.link_pose(np.zeros(6), "link_9")


def test_urdf_from_dh_refuses_bad_arguments() -> None:
    table, names = tm5_900.DH, tm5_900.JOINT_NAMES_ROS
    with pytest.raises(ValueError, match="one value per DH row"):
        urdf_from_dh("arm", table, LIMITS, names[:5])
    with pytest.raises(ValueError, match="unique"):
        urdf_from_dh("arm", table, LIMITS, ("j",) * 6)
    with pytest.raises(ValueError, match="unique"):
        urdf_from_dh("arm", table, LIMITS, names, tip_link="flange")
    with pytest.raises(ValueError, match="4x4"):
        urdf_from_dh("arm", table, LIMITS, names, tool=np.eye(3))
    odd = urdf_from_dh('a"<&>', table, LIMITS, names)  # names are escaped, not injected
    assert load_urdf_chain(odd, "base", "tcp").name == 'a"<&>'
