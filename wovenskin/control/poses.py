"""Named robot poses ("initial", "home"): joint angles plus TCP pose, kept in a TOML file.

The default file is ``$WOVENSKIN_HOME/poses.toml`` when ``WOVENSKIN_HOME`` is set, else
``~/.config/wovenskin/poses.toml``. Each pose is a table::

    [initial]
    q = [0.0, 0.0, 1.5708, 0.0, 1.5708, 0.0]   # rad
    position = [0.5175, -0.1223, 0.321]         # m, base frame
    quat = [0.0, 0.7071, 0.7071, 0.0]           # [w, x, y, z]

:func:`set_pose_from_robot` stores the arm's current pose (``wovenskin pose set initial``).
"""

from __future__ import annotations

import math
import os
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from wovenskin.errors import ConfigError
from wovenskin.io import atomic_write_text
from wovenskin.robots.base import N_JOINTS, Pose, Robot, RobotError

POSE_NAMES = ("initial", "home")
POSES_FILE = "poses.toml"


def default_poses_path() -> Path:
    """``$WOVENSKIN_HOME/poses.toml``, else ``~/.config/wovenskin/poses.toml``."""
    home = os.environ.get("WOVENSKIN_HOME")
    folder = Path(home).expanduser() if home else Path.home() / ".config" / "wovenskin"
    return folder / POSES_FILE


@dataclass(frozen=True)
class NamedPose:
    """A stored pose: joint angles (rad) and the TCP pose they give (base frame)."""

    name: str
    q: np.ndarray
    tcp: Pose


class PoseStore:
    """The named poses of one file; :meth:`load` it, :meth:`set` poses, :meth:`save` it."""

    def __init__(self, path: str | Path | None = None) -> None:
        self.path = Path(path) if path is not None else default_poses_path()
        self._poses: dict[str, NamedPose] = {}

    @classmethod
    def load(cls, path: str | Path | None = None) -> PoseStore:
        """Read ``path`` (default: :func:`default_poses_path`); a missing file is empty."""
        store = cls(path)
        if not store.path.exists():
            return store
        try:
            data = tomllib.loads(store.path.read_text(encoding="utf-8"))
        except OSError as exc:
            raise ConfigError(f"{store.path}: cannot read the pose file ({exc.strerror})") from None
        except tomllib.TOMLDecodeError as exc:
            raise ConfigError(f"{store.path}: not valid TOML ({exc})") from None
        for name, table in data.items():
            store._poses[name] = _parse_pose(name, table, store.path)
        return store

    @property
    def names(self) -> list[str]:
        """The names with a stored pose."""
        return [name for name in POSE_NAMES if name in self._poses]

    def get(self, name: str) -> NamedPose | None:
        """The pose stored under ``name``, or ``None``."""
        _check_name(name)
        return self._poses.get(name)

    def set(self, name: str, q: np.ndarray, tcp: Pose) -> NamedPose:
        """Store (in memory; :meth:`save` writes the file) the pose ``name``."""
        _check_name(name)
        joints = np.array(q, dtype=float)
        if joints.shape != (N_JOINTS,) or not np.all(np.isfinite(joints)):
            raise ConfigError(f"pose {name!r}: q must be {N_JOINTS} finite joint angles")
        if not isinstance(tcp, Pose):
            raise ConfigError(f"pose {name!r}: tcp must be a Pose, got {type(tcp).__name__}")
        pose = NamedPose(name, joints, tcp)
        self._poses[name] = pose
        return pose

    def save(self) -> Path:
        """Write every stored pose to :attr:`path` (folders are created); returns the path."""
        lines = ["# wovenskin named poses: q in rad, position in m, quat [w, x, y, z]"]
        for name in self.names:
            pose = self._poses[name]
            lines += [
                "",
                f"[{name}]",
                f"q = {_toml_floats(pose.q)}",
                f"position = {_toml_floats(pose.tcp.position)}",
                f"quat = {_toml_floats(pose.tcp.quat)}",
            ]
        self.path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_text(self.path, "\n".join(lines) + "\n")
        return self.path


def set_pose_from_robot(store: PoseStore, name: str, robot: Robot) -> NamedPose:
    """Store the connected ``robot``'s current pose as ``name`` and save the file."""
    _check_name(name)
    state = robot.state()
    if state.fault is not None:
        raise RobotError(f"cannot store {name!r}: the robot reports a fault ({state.fault})")
    pose = store.set(name, state.q, state.tcp)
    store.save()
    return pose


def _check_name(name: str) -> None:
    if name not in POSE_NAMES:
        raise ConfigError(f"unknown pose name {name!r} (expected initial or home)")


def _parse_pose(name: str, table: object, path: Path) -> NamedPose:
    if name not in POSE_NAMES:
        raise ConfigError(f"{path}: {name}: unknown pose name (expected initial or home)")
    if not isinstance(table, dict):
        raise ConfigError(f"{path}: {name} must be a table with q, position and quat")
    sizes = {"q": N_JOINTS, "position": 3, "quat": 4}
    values: dict[str, np.ndarray] = {}
    for key in table:
        if key not in sizes:
            raise ConfigError(f"{path}: {name}.{key}: unknown key (expected q, position, quat)")
    for key, size in sizes.items():
        raw = table.get(key)
        numbers = isinstance(raw, list) and all(
            isinstance(v, int | float) and not isinstance(v, bool) for v in raw
        )
        if not (numbers and len(raw) == size and all(math.isfinite(v) for v in raw)):
            raise ConfigError(f"{path}: {name}.{key} must be a list of {size} finite numbers")
        values[key] = np.array(raw, dtype=float)
    try:
        tcp = Pose(values["position"], values["quat"])
    except ValueError as exc:
        raise ConfigError(f"{path}: {name}: {exc}") from None
    return NamedPose(name, values["q"], tcp)


def _toml_floats(values: np.ndarray) -> str:
    return "[" + ", ".join(repr(float(v)) for v in np.asarray(values).reshape(-1)) + "]"
