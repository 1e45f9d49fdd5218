"""An arm's kinematics read from a URDF: the serial chain of six joints from a base to a tip.

:func:`load_urdf_chain` parses a URDF (its text, or a file) with :mod:`xml.etree` and
extracts the chain of joints from a ``base`` link down to a ``tip`` link; the result, a
:class:`UrdfChain`, gives the tip's pose and geometric Jacobian in the base frame, the pose
of any link on the chain, the joint limits, and the :class:`~wovenskin.robots.base.
Kinematics` a backend declares to the safety layer.

The conventions are the URDF specification's (https://wiki.ros.org/urdf/XML/joint):

- a joint's child frame is its parent frame times ``<origin xyz rpy>`` times the joint's
  motion; ``rpy`` is roll, pitch, yaw about the *fixed* axes x, y, z, so the rotation is
  ``Rz(yaw) @ Ry(pitch) @ Rx(roll)`` (:func:`rpy_matrix`, :func:`matrix_rpy`); both
  attributes default to zeros;
- a revolute or continuous joint turns by ``q`` about ``<axis xyz>``, given in the joint
  (= child) frame; the axis defaults to ``1 0 0`` and is normalised (a zero axis is
  refused); ``fixed`` joints do not move;
- a revolute joint needs ``<limit lower upper velocity>`` (``lower``/``upper`` default to
  0, and ``lower < upper`` is required here); a continuous joint has no position limits and
  is given ``-2 pi .. 2 pi``.  ``velocity`` (rad/s) is required on every moving joint of the
  chain, continuous ones too: the safety layer caps joint speeds with it, so a missing
  velocity is refused rather than guessed.  ``effort``, ``<dynamics>``, ``<calibration>``
  and ``<safety_controller>`` are ignored.

Only the joints on the chain are read in detail: a gripper's prismatic finger hanging off
the flange does no harm, but a prismatic, floating or planar joint *on* the chain, a
``<mimic>`` joint on it, or a chain with other than six moving joints is refused.  The
file as a whole must be a tree: links and joints uniquely named, every joint with a
``parent`` and ``child`` naming declared links, no link the child of two joints, no loop.
Every problem is one :class:`UrdfError` line (a :class:`~wovenskin.errors.ConfigError`,
so a ``ValueError``: robot specs print it as one line).  Files are capped at
:data:`MAX_URDF_BYTES`; xacro files must be expanded first.
"""

from __future__ import annotations

import math
import os
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType

import numpy as np

from wovenskin.errors import ConfigError
from wovenskin.robots.base import N_JOINTS, JointLimits, Kinematics, finite_vector

MAX_URDF_BYTES = 8 * 2**20
"""The largest URDF read (8 MiB): kinematic URDFs are kilobytes, meshes live elsewhere."""

MOVING = ("revolute", "continuous")
JOINT_TYPES = (*MOVING, "fixed", "prismatic", "floating", "planar")
CONTINUOUS_RANGE = 2.0 * math.pi  # rad either side of zero for a continuous joint
_XACRO = "{http://www.ros.org/wiki/xacro}"
_MAX_PATH = 4096
_LEADING = " \t\r\n\ufeff"  # before the text's first "<": white space, a byte order mark


class UrdfError(ConfigError):
    """A URDF that cannot be used as an arm's kinematics; the message is one line."""


def _quote(name: object) -> str:
    """A name from the file, quoted and cut short, safe inside a one-line message."""
    text = str(name)
    return repr(text if len(text) <= 60 else text[:57] + "...")


def rpy_matrix(rpy: object) -> np.ndarray:
    """The 3x3 rotation of URDF's ``rpy``: ``Rz(yaw) @ Ry(pitch) @ Rx(roll)`` (fixed axes)."""
    roll, pitch, yaw = finite_vector(rpy, 3, "rpy")
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


def matrix_rpy(rotation: object) -> np.ndarray:
    """URDF's ``(roll, pitch, yaw)`` of a 3x3 rotation matrix, the inverse of
    :func:`rpy_matrix`: pitch in ``[-pi/2, pi/2]``, roll and yaw in ``(-pi, pi]``.  At
    pitch +-pi/2 (gimbal lock) only roll - yaw (or roll + yaw) is defined; yaw is set to 0."""
    r = np.asarray(rotation, dtype=float)
    if r.shape != (3, 3) or not np.all(np.isfinite(r)):
        raise ValueError("rotation must be a finite 3x3 matrix")
    cos_pitch = math.hypot(r[0, 0], r[1, 0])
    pitch = math.atan2(-r[2, 0], cos_pitch)
    if cos_pitch > 1e-12:
        return np.array([math.atan2(r[2, 1], r[2, 2]), pitch, math.atan2(r[1, 0], r[0, 0])])
    return np.array([math.atan2(-r[1, 2], r[1, 1]), pitch, 0.0])


def _transform(xyz: np.ndarray, rpy: np.ndarray) -> np.ndarray:
    transform = np.eye(4)
    transform[:3, :3] = rpy_matrix(rpy)
    transform[:3, 3] = xyz
    return transform


@dataclass(frozen=True, eq=False)
class UrdfChain:
    """The serial chain of a URDF from ``base_link`` to ``tip_link``: six moving joints.

    ``links`` lists the chain's links, base first and tip last (fixed joints' links too);
    :meth:`link_pose` gives any of them.  Joint vectors ``q`` are in ``joint_names`` order
    (the chain's order, base to tip), radians.
    """

    name: str  # the <robot name>
    base_link: str
    tip_link: str
    joint_names: tuple[str, ...]
    limits: JointLimits
    links: tuple[str, ...]
    _before: np.ndarray = field(repr=False)  # (6, 4, 4): previous moving child <- joint k
    _axes: np.ndarray = field(repr=False)  # (6, 3): unit axis of joint k, its own frame
    _cross: np.ndarray = field(repr=False)  # (6, 3, 3): [axis]x, for Rodrigues' formula
    _cross2: np.ndarray = field(repr=False)  # (6, 3, 3): [axis]x squared
    _offsets: Mapping[str, tuple[int, np.ndarray]] = field(repr=False)  # link -> (k, offset)

    def _frames(self, q: object) -> np.ndarray:
        """Base <- child link of moving joint k, ``(6, 4, 4)``: the rotations are built
        at once (Rodrigues), then chained with the precomputed fixed transforms."""
        joints = finite_vector(q, N_JOINTS, "joint vector")
        sin, cos = np.sin(joints)[:, None, None], np.cos(joints)[:, None, None]
        turns = np.eye(3) + sin * self._cross + (1.0 - cos) * self._cross2
        frames = np.empty((N_JOINTS, 4, 4))
        current = np.eye(4)
        for k in range(N_JOINTS):
            joint = current @ self._before[k]
            current = joint.copy()
            current[:3, :3] = joint[:3, :3] @ turns[k]
            frames[k] = current
        return frames

    def link_pose(self, q: object, link: str) -> np.ndarray:
        """The 4x4 pose of ``link`` (one of :attr:`links`) in the base frame at ``q``."""
        if link not in self._offsets:
            raise UrdfError(
                f"link {_quote(link)} is not on the chain from {_quote(self.base_link)} to "
                f"{_quote(self.tip_link)} (links: {', '.join(self.links)})"
            )
        k, offset = self._offsets[link]
        if k < 0:
            finite_vector(q, N_JOINTS, "joint vector")
            return offset.copy()
        return self._frames(q)[k] @ offset

    def forward(self, q: object) -> np.ndarray:
        """The 4x4 pose of the tip in the base frame (base <- tip) at ``q``."""
        return self.link_pose(q, self.tip_link)

    def jacobian(self, q: object) -> np.ndarray:
        """The 6x6 geometric Jacobian of the tip in the base frame: ``[v; w] = J @ dq``,
        ``v`` the linear velocity of the tip's origin, ``w`` the angular velocity."""
        frames = self._frames(q)
        tip = frames[-1] @ self._offsets[self.tip_link][1]
        axes = np.einsum("kij,kj->ki", frames[:, :3, :3], self._axes)
        linear = np.cross(axes, tip[:3, 3] - frames[:, :3, 3])
        return np.vstack((linear.T, axes.T))

    def kinematics(self) -> Kinematics:
        """The tip's kinematics as a backend declares it (``RobotCapabilities``)."""
        return Kinematics(forward=self.forward, jacobian=self.jacobian)


def _read(source: str | os.PathLike[str]) -> tuple[bytes | str, str]:
    """The URDF's content and a label for messages (``URDF 'path'`` or ``URDF text``)."""
    if isinstance(source, str) and source.lstrip(_LEADING).startswith("<"):
        if len(source) > MAX_URDF_BYTES:
            raise UrdfError(f"URDF text is larger than {MAX_URDF_BYTES} bytes")
        return source.lstrip(_LEADING), "URDF text"
    if not isinstance(source, str | os.PathLike):
        raise UrdfError(f"URDF must be text or a file path, not {type(source).__name__}")
    text = os.fspath(source)
    if not isinstance(text, str) or not text.strip() or len(text) > _MAX_PATH:
        raise UrdfError("URDF is neither XML text nor a file path")
    try:
        path = Path(text).expanduser()  # a quoted spec leaves ~ to us
    except RuntimeError:  # no home directory to expand ~ to
        path = Path(text)
    label = f"URDF {_quote(text)}"
    problem = ""
    try:
        if not path.exists():
            problem = "does not exist"
        elif not path.is_file():
            problem = "is not a regular file"
        else:
            with path.open("rb") as file:
                data = file.read(MAX_URDF_BYTES + 1)
    except (OSError, ValueError) as exc:  # ValueError: a NUL in the path
        reason = getattr(exc, "strerror", None) or " ".join(str(exc).split())
        problem = f"cannot be read: {reason}"
    if problem:
        raise UrdfError(f"{label} {problem}")
    if len(data) > MAX_URDF_BYTES:
        raise UrdfError(f"{label} is larger than {MAX_URDF_BYTES} bytes")
    return data, label


def _parse(content: bytes | str, label: str) -> ET.Element:
    entity = b"<!ENTITY" if isinstance(content, bytes) else "<!ENTITY"
    if entity in content:  # type: ignore[operator]
        raise UrdfError(f"{label} declares XML entities, which URDF does not use")
    try:
        root = ET.fromstring(content)
    except ET.ParseError as exc:
        raise UrdfError(f"{label} is not well-formed XML: {exc}") from None
    if any(str(element.tag).startswith(_XACRO) for element in root.iter()):
        raise UrdfError(f"{label} is a xacro file: expand it first (xacro FILE > FILE.urdf)")
    if root.tag != "robot":
        raise UrdfError(f"{label}: the root element is <{_quote(root.tag)[1:-1]}>, not <robot>")
    return root


def _numbers(text: str | None, default: str, count: int, what: str) -> np.ndarray:
    """``count`` finite numbers from an attribute's text; else a one-line UrdfError."""
    raw = default if text is None else text
    try:
        values = np.array([float(part) for part in raw.split()])
    except ValueError:
        values = np.array([])
    if values.shape != (count,) or not np.all(np.isfinite(values)):
        plural = "s" if count > 1 else ""
        raise UrdfError(f"{what} {_quote(raw)} is not {count} finite number{plural}")
    return values


@dataclass(frozen=True)
class _Joint:
    name: str
    kind: str
    parent: str
    child: str
    element: ET.Element


def _new_name(element: ET.Element, seen: set[str], kind: str, label: str) -> str:
    """The ``name`` of a ``<link>`` or ``<joint>``, which must be given and not yet seen."""
    name = element.get("name", "")
    if not name.strip():
        raise UrdfError(f"{label}: a <{kind}> has no name")
    if name in seen:
        raise UrdfError(f"{label}: two {kind}s are named {_quote(name)}")
    return name


def _tree(root: ET.Element, label: str) -> tuple[set[str], dict[str, _Joint]]:
    """The declared links and each child link's joint, checked to form a tree."""
    links: set[str] = set()
    for element in root.findall("link"):
        links.add(_new_name(element, links, "link", label))
    names: set[str] = set()
    parent_joint: dict[str, _Joint] = {}
    for element in root.findall("joint"):
        name = _new_name(element, names, "joint", label)
        names.add(name)
        kind = element.get("type", "")
        if kind not in JOINT_TYPES:
            raise UrdfError(f"{label}: joint {_quote(name)} has unknown type {_quote(kind)}")
        ends = {}
        for end in ("parent", "child"):
            tag = element.find(end)
            link = "" if tag is None else tag.get("link", "")
            if not link:
                raise UrdfError(f"{label}: joint {_quote(name)} has no {end} link")
            if link not in links:
                raise UrdfError(f"{label}: joint {_quote(name)} names an undeclared link "
                                f"{_quote(link)}")  # fmt: skip
            ends[end] = link
        if ends["child"] in parent_joint:
            other = parent_joint[ends["child"]].name
            raise UrdfError(f"{label}: link {_quote(ends['child'])} is the child of two joints "
                            f"({_quote(other)} and {_quote(name)}); a URDF is a tree")  # fmt: skip
        parent_joint[ends["child"]] = _Joint(name, kind, ends["parent"], ends["child"], element)
    return links, parent_joint


def _chain(
    label: str, links: set[str], parent_joint: dict[str, _Joint], base: str, tip: str
) -> list[_Joint]:
    """The joints from ``base`` down to ``tip``, base first."""
    for what, link in (("base", base), ("tip", tip)):
        if link not in links:
            known = ", ".join(sorted(links)[:12]) + (", ..." if len(links) > 12 else "")
            raise UrdfError(f"{label} has no {what} link {_quote(link)} (links: {known})")
    chain: list[_Joint] = []
    seen = {tip}
    link = tip
    while link != base:
        joint = parent_joint.get(link)
        if joint is None:
            raise UrdfError(f"{label}: {_quote(tip)} does not hang below {_quote(base)} "
                            f"(its chain goes up to {_quote(link)})")  # fmt: skip
        if joint.parent in seen:
            raise UrdfError(f"{label}: the joints form a loop through link {_quote(joint.parent)}")
        seen.add(joint.parent)
        chain.append(joint)
        link = joint.parent
    return chain[::-1]


def _limits(joint: _Joint, what: str) -> tuple[float, float, float]:
    """Lower, upper (rad) and velocity (rad/s) of a moving joint."""
    limit = joint.element.find("limit")
    if limit is None or limit.get("velocity") is None:
        raise UrdfError(f"{what} has no <limit velocity=...>: the safety layer needs its "
                        "speed limit (rad/s)")  # fmt: skip
    (velocity,) = _numbers(limit.get("velocity"), "", 1, f"{what} limit velocity")
    if velocity <= 0.0:
        raise UrdfError(f"{what} limit velocity {velocity:g} is not positive")
    if joint.kind == "continuous":
        return -CONTINUOUS_RANGE, CONTINUOUS_RANGE, velocity
    (lower,) = _numbers(limit.get("lower"), "0", 1, f"{what} limit lower")
    (upper,) = _numbers(limit.get("upper"), "0", 1, f"{what} limit upper")
    if not lower < upper:
        raise UrdfError(f"{what} limit lower {lower:g} is not below upper {upper:g}")
    return lower, upper, velocity


def _build(name: str, label: str, chain: list[_Joint], base: str, tip: str) -> UrdfChain:
    moving = [joint for joint in chain if joint.kind in MOVING]
    for joint in chain:
        if joint.kind not in (*MOVING, "fixed"):
            raise UrdfError(f"{label}: joint {_quote(joint.name)} on the chain is {joint.kind}; "
                            "only revolute, continuous and fixed joints are supported")  # fmt: skip
    if len(moving) != N_JOINTS:
        listed = ", ".join(joint.name for joint in moving) or "none"
        raise UrdfError(f"{label}: the chain from {_quote(base)} to {_quote(tip)} has "
                        f"{len(moving)} moving joints ({listed}); an arm needs exactly "
                        f"{N_JOINTS}")  # fmt: skip
    before, axes, bounds = [], [], []
    offsets: dict[str, tuple[int, np.ndarray]] = {base: (-1, np.eye(4))}
    current, k = np.eye(4), -1
    for joint in chain:
        what = f"{label}: joint {_quote(joint.name)}"
        if joint.element.find("mimic") is not None and joint.kind in MOVING:
            raise UrdfError(f"{what} mimics another joint; the chain's joints must be independent")
        origin = joint.element.find("origin")
        attrs = {} if origin is None else origin.attrib
        xyz = _numbers(attrs.get("xyz"), "0 0 0", 3, f"{what} origin xyz")
        rpy = _numbers(attrs.get("rpy"), "0 0 0", 3, f"{what} origin rpy")
        current = current @ _transform(xyz, rpy)
        if joint.kind in MOVING:
            tag = joint.element.find("axis")
            axis = _numbers(None if tag is None else tag.get("xyz"), "1 0 0", 3, f"{what} axis")
            norm = float(np.linalg.norm(axis))
            if norm < 1e-9:
                raise UrdfError(f"{what} has a zero axis")
            before.append(current)
            axes.append(axis / norm)
            bounds.append(_limits(joint, what))
            current, k = np.eye(4), k + 1
        offsets[joint.child] = (k, current.copy())
    unit = np.array(axes)
    cross = np.zeros((N_JOINTS, 3, 3))
    cross[:, 0, 1], cross[:, 0, 2], cross[:, 1, 2] = -unit[:, 2], unit[:, 1], -unit[:, 0]
    cross -= cross.transpose(0, 2, 1)
    lower, upper, velocity = (np.array(column) for column in zip(*bounds, strict=True))
    arrays = [*map(np.array, (before, unit, cross, cross @ cross)), lower, upper, velocity]
    arrays += [offset for _, offset in offsets.values()]
    for array in arrays:
        array.setflags(write=False)
    return UrdfChain(
        name=name,
        base_link=base,
        tip_link=tip,
        joint_names=tuple(joint.name for joint in moving),
        limits=JointLimits(lower=lower, upper=upper, max_speed=velocity),
        links=(base, *(joint.child for joint in chain)),
        _before=arrays[0],
        _axes=arrays[1],
        _cross=arrays[2],
        _cross2=arrays[3],
        _offsets=MappingProxyType(offsets),
    )


def load_urdf_chain(source: str | os.PathLike[str], base: str, tip: str) -> UrdfChain:
    """The chain from link ``base`` to link ``tip`` of a URDF, given as its text (a string
    starting with ``<``) or as a file path; any problem is one :class:`UrdfError` line."""
    content, label = _read(source)
    root = _parse(content, label)
    links, parent_joint = _tree(root, label)
    chain = _chain(label, links, parent_joint, str(base), str(tip))
    return _build(root.get("name", ""), label, chain, str(base), str(tip))
