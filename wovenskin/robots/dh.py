"""Standard Denavit-Hartenberg kinematics, shared by every arm whose table we know.

A :class:`DHLink` is one row of a standard DH table; :func:`dh_transform` is that row's
transform at a joint angle, :func:`chain_frames` the base <- frame i transforms of a
whole table and :func:`chain_jacobian` its geometric Jacobian.  :func:`mjcf_from_dh`
writes a kinematic MuJoCo body tree from a table (each link body's frame is DH frame i-1
turned by joint i about its z axis), so a display or simulation model and the DH
equations cannot drift apart: tests compare the two.  :func:`urdf_from_dh` writes the
same tree as a kinematic URDF (links ``base``, ``link_1``..``link_n``, ``flange`` and a
tool tip), which :func:`wovenskin.robots.urdf.load_urdf_chain` reads back.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache
from xml.sax.saxutils import quoteattr

import numpy as np
from scipy.spatial.transform import Rotation

from wovenskin.robots.base import JointLimits
from wovenskin.robots.urdf import matrix_rpy


@dataclass(frozen=True)
class DHLink:
    """One row of a standard DH table: Rz(theta + offset) Tz(d) Tx(a) Rx(alpha)."""

    d: float  # m
    a: float  # m
    alpha: float  # rad
    theta_offset: float  # rad


def dh_transform(link: DHLink, theta: float) -> np.ndarray:
    """The 4x4 transform of one DH row at joint angle ``theta`` (frame i-1 <- frame i)."""
    ct, st = np.cos(theta + link.theta_offset), np.sin(theta + link.theta_offset)
    ca, sa = np.cos(link.alpha), np.sin(link.alpha)
    return np.array(
        [
            [ct, -st * ca, st * sa, link.a * ct],
            [st, ct * ca, -ct * sa, link.a * st],
            [0.0, sa, ca, link.d],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


def chain_frames(table: Sequence[DHLink], q: np.ndarray) -> list[np.ndarray]:
    """Base <- DH frame i for i = 0..n (frame 0 is the base, frame n the flange)."""
    joints = np.asarray(q, dtype=float).reshape(-1)
    if joints.shape[0] != len(table):
        raise ValueError(f"expected {len(table)} joint angles, got {joints.shape[0]}")
    if not np.all(np.isfinite(joints)):
        raise ValueError("joint vector has non-finite values")
    frames = [np.eye(4)]
    for row in _row_transforms(table, joints):
        frames.append(frames[-1] @ row)
    return frames


@lru_cache(maxsize=16)
def _columns(table: tuple[DHLink, ...]) -> np.ndarray:
    """The table's d, a, alpha and theta offset as four arrays (tables are immutable)."""
    columns = np.array([(link.d, link.a, link.alpha, link.theta_offset) for link in table]).T
    columns.setflags(write=False)
    return columns


def _row_transforms(table: Sequence[DHLink], joints: np.ndarray) -> np.ndarray:
    """Every row's :func:`dh_transform` at once, ``(n, 4, 4)``: the safety layer asks for
    a Jacobian on every control substep, so the rows are built in one vectorised pass."""
    d, a, alpha, offset = _columns(tuple(table))
    ct, st = np.cos(joints + offset), np.sin(joints + offset)
    ca, sa = np.cos(alpha), np.sin(alpha)
    rows = np.zeros((len(table), 4, 4))
    rows[:, 0, 0], rows[:, 0, 1], rows[:, 0, 2], rows[:, 0, 3] = ct, -st * ca, st * sa, a * ct
    rows[:, 1, 0], rows[:, 1, 1], rows[:, 1, 2], rows[:, 1, 3] = st, ct * ca, -ct * sa, a * st
    rows[:, 2, 1], rows[:, 2, 2], rows[:, 2, 3] = sa, ca, d
    rows[:, 3, 3] = 1.0
    return rows


def chain_jacobian(
    table: Sequence[DHLink], q: np.ndarray, tool: np.ndarray | None = None
) -> np.ndarray:
    """The ``(6, n)`` geometric Jacobian, base frame, of the point ``tool`` (4x4 flange <-
    tool; None: the flange) for a chain of revolute joints: ``[v; w] = J @ dq``."""
    frames = chain_frames(table, q)
    end = frames[-1] if tool is None else frames[-1] @ np.asarray(tool, dtype=float)
    stacked = np.stack(frames[:-1])  # base <- frame i-1, whose z is joint i's axis
    axes, origins = stacked[:, :3, 2], stacked[:, :3, 3]
    linear = np.cross(axes, end[:3, 3] - origins)
    return np.vstack((linear.T, axes.T))


def _quat_wxyz(rotation: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a rotation matrix (MJCF's order)."""
    return Rotation.from_matrix(rotation).as_quat()[[3, 0, 1, 2]]


def _fmt(values: Sequence[float]) -> str:
    return " ".join(f"{float(v):.10g}" for v in values)


@dataclass(frozen=True)
class LinkLook:
    """How :func:`mjcf_from_dh` draws the links: radii (m) and colours (RGBA)."""

    link_radius: Sequence[float]  # one per joint: the capsules along d and a of that row
    housing_rgba: str = "0.25 0.27 0.3 1"
    link_rgba: str = "0.85 0.85 0.88 1"


def mjcf_from_dh(
    name: str,
    table: Sequence[DHLink],
    limits_lower: Sequence[float],
    limits_upper: Sequence[float],
    look: LinkLook,
    end_link: str = "",
) -> str:
    """A kinematic MJCF of the arm (no contacts, no gravity): joints ``joint1..n``, capsules
    along each row's ``d`` and ``a``, a cylinder housing at each joint, and a body
    ``flange`` (DH frame n) with a site ``flange``.  ``end_link`` is extra MJCF placed in
    the last link's body (the frame of joint n, z along the tool axis): a skin patch, say.
    """
    n = len(table)
    if not (len(limits_lower) == len(limits_upper) == len(look.link_radius) == n):
        raise ValueError("limits and radii need one value per DH row")
    lines = [
        f'<mujoco model="{name}">',
        '  <compiler angle="radian" autolimits="true"/>',
        '  <option gravity="0 0 0"/>',
        "  <default>",
        '    <geom contype="0" conaffinity="0" density="1000"/>',
        '    <joint type="hinge" axis="0 0 1" damping="0"/>',
        "  </default>",
        "  <worldbody>",
        '    <light pos="0 0 2.5" dir="0 0 -1"/>',
        '    <geom name="floor" type="plane" size="1.5 1.5 0.01" rgba="0.9 0.9 0.9 1"/>',
        '    <body name="base">',
        f'      <geom name="base" type="cylinder" size="{look.link_radius[0] * 1.2:.4g} 0.03"'
        f' pos="0 0 0.03" rgba="{look.housing_rgba}"/>',
    ]
    indent = "      "
    pos, quat = np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0])
    for i, link in enumerate(table):
        r = float(look.link_radius[i])
        lines.append(f'{indent}<body name="link{i + 1}" pos="{_fmt(pos)}" quat="{_fmt(quat)}">')
        indent += "  "
        joint_range = f"{limits_lower[i]:.10g} {limits_upper[i]:.10g}"
        lines.append(f'{indent}<joint name="joint{i + 1}" range="{joint_range}"/>')
        housing = f"{r * 1.15:.4g} {r * 1.2:.4g}"
        lines.append(f'{indent}<geom type="cylinder" size="{housing}" rgba="{look.housing_rgba}"/>')
        # the fixed part of the row, in this body's frame: Rz(offset), then d along z, a along x'
        offset = link.theta_offset
        corner = np.array([0.0, 0.0, link.d])
        tip = corner + link.a * np.array([np.cos(offset), np.sin(offset), 0.0])
        for start, end in ((np.zeros(3), corner), (corner, tip)):
            if np.linalg.norm(end - start) > 1e-4:  # shorter: nothing to draw (MuJoCo refuses)
                lines.append(
                    f'{indent}<geom type="capsule" size="{r:.4g}" fromto="{_fmt([*start, *end])}"'
                    f' rgba="{look.link_rgba}"/>'
                )
        c, s = np.cos(offset), np.sin(offset)
        ca, sa = np.cos(link.alpha), np.sin(link.alpha)
        rz = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        rx = np.array([[1.0, 0.0, 0.0], [0.0, ca, -sa], [0.0, sa, ca]])
        pos, quat = tip, _quat_wxyz(rz @ rx)
        if i == n - 1:
            if end_link:
                lines.extend(indent + line for line in end_link.strip().splitlines())
            lines.append(f'{indent}<body name="flange" pos="{_fmt(pos)}" quat="{_fmt(quat)}">')
            lines.append(f'{indent}  <site name="flange" size="0.005"/>')
            lines.append(f"{indent}</body>")
    for _ in range(n):
        indent = indent[:-2]
        lines.append(f"{indent}</body>")
    lines += ["    </body>", "  </worldbody>", "</mujoco>"]
    return "\n".join(lines) + "\n"


def _row_fixed_part(link: DHLink) -> np.ndarray:
    """The row's transform at zero joint angle, without the joint's turn about z:
    ``Rz(offset) Tz(d) Tx(a) Rx(alpha)`` (link frame i <- DH frame i, see below)."""
    return dh_transform(link, 0.0)


def _num(value: float) -> str:
    """A number as the shortest text that reads back to the same float (tiny values: 0)."""
    number = float(value)
    if abs(number) < 1e-15:
        return "0"
    text = repr(number)
    return text[:-2] if text.endswith(".0") else text


def _origin(transform: np.ndarray) -> str:
    xyz = " ".join(_num(v) for v in transform[:3, 3])
    rpy = " ".join(_num(v) for v in matrix_rpy(transform[:3, :3]))
    return f'<origin xyz="{xyz}" rpy="{rpy}"/>'


def urdf_from_dh(
    name: str,
    table: Sequence[DHLink],
    limits: JointLimits,
    joint_names: Sequence[str],
    tool: np.ndarray | None = None,
    tip_link: str = "tcp",
    effort: Sequence[float] | None = None,
) -> str:
    """A kinematic URDF of the arm (no meshes, no inertias), per the URDF specification
    (https://wiki.ros.org/urdf/XML/joint).

    Links ``base``, ``link_1``..``link_n``, ``flange`` (DH frame n) and ``tip_link``
    (``tool``: flange <- tip, 4x4; None: the flange itself).  Link ``link_i`` is DH frame
    i-1 turned by joint i about its z axis, as in :func:`mjcf_from_dh`, so revolute joint
    i (named ``joint_names[i-1]``, axis ``0 0 1``) has as origin the fixed part of row i-1,
    ``Rz(offset) Tz(d) Tx(a) Rx(alpha)`` (joint 1: none), and the fixed joints
    ``flange_fixed_joint`` and ``<tip_link>_fixed_joint`` carry row n's and the tool.
    Position limits and velocities come from ``limits``; ``effort`` (N m per joint, which
    the specification requires and wovenskin ignores) defaults to 0.
    """
    n = len(table)
    lower, upper, speed = (np.asarray(v, dtype=float).reshape(-1) for v in
                           (limits.lower, limits.upper, limits.max_speed))  # fmt: skip
    efforts = np.zeros(n) if effort is None else np.asarray(effort, dtype=float).reshape(-1)
    if not (len(joint_names) == lower.size == upper.size == speed.size == efforts.size == n):
        raise ValueError("joint names, limits and efforts need one value per DH row")
    if not (np.all(lower < upper) and np.all(speed > 0.0)):
        raise ValueError("joint limits need lower < upper and positive speeds")
    links = ["base", *(f"link_{i + 1}" for i in range(n)), "flange", tip_link]
    joints = [*joint_names, "flange_fixed_joint", f"{tip_link}_fixed_joint"]
    if len(set(links)) != len(links) or len(set(joints)) != len(joints) or not all(joints):
        raise ValueError("link and joint names must be unique and not empty")
    tool_transform = np.eye(4) if tool is None else np.asarray(tool, dtype=float)
    if tool_transform.shape != (4, 4) or not np.all(np.isfinite(tool_transform)):
        raise ValueError("tool must be a finite 4x4 transform")
    origins = [np.eye(4), *(_row_fixed_part(link) for link in table), tool_transform]
    lines = [
        '<?xml version="1.0"?>',
        "<!-- A kinematic model written by wovenskin.robots.dh.urdf_from_dh from a standard",
        "     DH table: no meshes, no inertias. Link i is DH frame i-1 turned by joint i. -->",
        f"<robot name={quoteattr(name)}>",
        f"  <link name={quoteattr(links[0])}/>",
    ]
    for i, joint in enumerate(joints):
        moving = i < n
        lines.append(
            f'  <joint name={quoteattr(joint)} type="{"revolute" if moving else "fixed"}">'
        )
        lines.append(f"    <parent link={quoteattr(links[i])}/>")
        lines.append(f"    <child link={quoteattr(links[i + 1])}/>")
        lines.append(f"    {_origin(origins[i])}")
        if moving:
            lines.append('    <axis xyz="0 0 1"/>')
            lines.append(
                f'    <limit lower="{_num(lower[i])}" upper="{_num(upper[i])}"'
                f' velocity="{_num(speed[i])}" effort="{_num(efforts[i])}"/>'
            )
        lines.append("  </joint>")
        lines.append(f"  <link name={quoteattr(links[i + 1])}/>")
    lines.append("</robot>")
    return "\n".join(lines) + "\n"
