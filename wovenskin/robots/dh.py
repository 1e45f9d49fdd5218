"""Standard Denavit-Hartenberg kinematics, shared by every arm whose table we know.

A :class:`DHLink` is one row of a standard DH table; :func:`dh_transform` is that row's
transform at a joint angle, :func:`chain_frames` the base <- frame i transforms of a
whole table and :func:`chain_jacobian` its geometric Jacobian.  :func:`mjcf_from_dh`
writes a kinematic MuJoCo body tree from a table (each link body's frame is DH frame i-1
turned by joint i about its z axis), so a display or simulation model and the DH
equations cannot drift apart: tests compare the two.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.spatial.transform import Rotation


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
