"""The action mapping: which gesture drives which twist or named pose, and how fast.

A TOML file (the packaged ``default_mapping.toml`` is docs/gestures.md's table) holds a
``[motion]`` table (frame, speeds, acceleration and jerk limits; angles in degrees; its
``[motion.profile]`` is the gestures' :class:`~wovenskin.control.profile.SpeedProfile`), a
``[poses]`` table (``hold_to_run``) and a ``[gestures]`` table mapping each gesture name to
``"translate <axis>"``, ``"rotate <axis>"``, ``"pose initial|home"`` or ``"none"``.
A ``[custom_gestures.NAME]`` table defines a gesture of the user's own
(:class:`~wovenskin.custom_gestures.CustomGesture`, ``docs/custom-gestures.md``), which
``[gestures]`` may then map like a built-in one; a name in ``[gestures]`` that is neither
built-in nor defined there is an error.
:meth:`ActionMapping.load` validates it and reports the first problem as one line naming
the file and the key; :meth:`ActionMapping.target_twist` turns a gesture into the
base-frame twist the robot should move with at full speed.

The axes of the ``[gestures]`` table are those of ``motion.frame``: ``tool`` (the paper's
mapping: the end effector's frame), ``base``, or ``skin``: the skin patch as it is
mounted on the end link (docs/interfaces.md), with x its outward normal, y its "right"
(toward higher columns) and z its "up" (toward row 0), so the default table moves the
tool the way the finger moved on the skin (``swipe_right`` = ``translate +y``).  The
patch's up and right axes in the tool frame are ``motion.skin_up`` / ``motion.skin_right``
(default: the simulated TM5-900's ``skin_patch`` site, :data:`SKIN_UP_IN_TOOL`).
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np

from wovenskin.control.mapping_defaults import (
    DEFAULT_MAPPING_FILE,
    HOLD_TO_RUN,
    MOTION,
    packaged_mapping_text,
)
from wovenskin.control.profile import SpeedProfile, profile_from_table
from wovenskin.custom_gestures import CustomGesture, parse_custom_gestures
from wovenskin.errors import ConfigError
from wovenskin.gestures import INVALID, known_classes
from wovenskin.robots.base import Pose

POSE_NAMES = ("initial", "home")
AXES = {"x": 0, "y": 1, "z": 2}
FRAMES = ("tool", "base", "skin")
# The skin patch on the simulated TM5-900's end link (robots/sim/tm5_900.xml: the
# "skin_patch" site has the tool's orientation; the skin's up is the site's x, its right
# the site's z), in the tool frame.  tests/control/test_control_mapping_skin.py checks them
# against the MuJoCo model.
SKIN_UP_IN_TOOL = (1.0, 0.0, 0.0)
SKIN_RIGHT_IN_TOOL = (0.0, 0.0, 1.0)


@dataclass(frozen=True)
class MotionSettings:
    """Speeds and smoothing of velocity commands (SI units: m, rad, s).

    The defaults are the packaged mapping file's ``[motion]`` table, its one home
    (:mod:`~wovenskin.control.mapping_defaults`; angles there in degrees)."""

    frame: Literal["tool", "base", "skin"] = MOTION["frame"]
    linear_speed: float = MOTION["linear_speed"]  # m/s
    angular_speed: float = math.radians(MOTION["angular_speed"])  # rad/s
    linear_accel: float = MOTION["linear_accel"]  # m/s^2
    angular_accel: float = math.radians(MOTION["angular_accel"])  # rad/s^2
    linear_jerk: float = MOTION["linear_jerk"]  # m/s^3
    angular_jerk: float = math.radians(MOTION["angular_jerk"])  # rad/s^3
    skin_up: tuple[float, float, float] = SKIN_UP_IN_TOOL  # the patch's up, tool frame
    skin_right: tuple[float, float, float] = SKIN_RIGHT_IN_TOOL  # its right, tool frame
    profile: SpeedProfile = field(default_factory=SpeedProfile)  # a gesture's speed in time

    def __post_init__(self) -> None:
        if self.frame not in FRAMES:
            raise ConfigError(f"frame must be 'tool', 'base' or 'skin', got {self.frame!r}")
        up = _unit(self.skin_up, "skin_up")
        right = _unit(self.skin_right, "skin_right")
        if abs(float(up @ right)) > 1e-3:
            raise ConfigError("skin_up and skin_right must be perpendicular")
        object.__setattr__(self, "skin_up", tuple(float(v) for v in up))
        object.__setattr__(self, "skin_right", tuple(float(v) for v in right))
        for name in (
            "linear_speed",
            "angular_speed",
            "linear_accel",
            "angular_accel",
            "linear_jerk",
            "angular_jerk",
        ):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise ConfigError(f"{name} must be a number, got {value!r}")
            if not (math.isfinite(value) and value > 0.0):
                raise ConfigError(f"{name} must be a positive finite number, got {value!r}")

    def skin_rotation(self) -> np.ndarray:
        """3x3 rotation tool <- skin; the skin frame's axes are its outward normal (x),
        right (y) and up (z), as columns in the tool frame."""
        up = np.asarray(self.skin_up, dtype=float)
        right = np.asarray(self.skin_right, dtype=float)
        right = right - (right @ up) * up
        right /= np.linalg.norm(right)
        return np.column_stack([np.cross(right, up), right, up])


@dataclass(frozen=True)
class TwistAction:
    """Move along (``translate``) or about (``rotate``) a unit axis while the command lasts."""

    kind: Literal["translate", "rotate"]
    axis: np.ndarray  # (3,) unit vector in the mapping's frame

    def __str__(self) -> str:
        index = int(np.flatnonzero(self.axis)[0])
        sign = "+" if self.axis[index] > 0 else "-"
        return f"{self.kind} {sign}{'xyz'[index]}"


@dataclass(frozen=True)
class PoseAction:
    """Go to a stored named pose; hold-to-run stops the move when the command ends."""

    name: Literal["initial", "home"]
    hold_to_run: bool = HOLD_TO_RUN

    def __str__(self) -> str:
        return f"pose {self.name}"


Action = TwistAction | PoseAction


@dataclass(frozen=True)
class ActionMapping:
    """Gesture name -> action, plus the motion settings; build it with :meth:`load`.

    ``gestures`` lists the names of the file's ``[gestures]`` table in file order (those
    mapped to ``"none"`` too); ``custom`` holds its ``[custom_gestures]`` definitions.
    """

    actions: dict[str, Action] = field(default_factory=dict)
    settings: MotionSettings = field(default_factory=MotionSettings)
    source: str = "<built-in>"
    gestures: tuple[str, ...] = ()
    custom: dict[str, CustomGesture] = field(default_factory=dict)

    @property
    def class_names(self) -> tuple[str, ...]:
        """The class names this mapping knows: the 15 built-in ones, then its custom ones."""
        return known_classes(self.custom)

    def prompted(self) -> list[str]:
        """The gestures ``wovenskin record --mapping`` prompts: every name in ``[gestures]``
        but ``invalid`` (a session prompts its invalid trials apart)."""
        return [name for name in self.gestures if name != INVALID]

    @classmethod
    def load(cls, path: str | Path | None = None) -> ActionMapping:
        """Read and validate a mapping file (default: the packaged default mapping)."""
        if path is None:
            return cls.from_text(packaged_mapping_text(), f"<package>/{DEFAULT_MAPPING_FILE}")
        path = Path(path)
        try:
            text = path.read_text(encoding="utf-8")
        except OSError as exc:
            raise ConfigError(f"{path}: cannot read the mapping file ({exc.strerror})") from None
        return cls.from_text(text, str(path))

    @classmethod
    def from_text(cls, text: str, source: str = "<string>") -> ActionMapping:
        """Parse mapping TOML; ``source`` names the file in error messages."""
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise ConfigError(f"{source}: not valid TOML ({exc})") from None
        _check_keys(data, {"motion", "poses", "gestures", "custom_gestures"}, "", source)
        motion = _table(data, "motion", source)
        poses = _table(data, "poses", source)
        gestures = _table(data, "gestures", source)
        custom = parse_custom_gestures(_table(data, "custom_gestures", source), source)
        known = known_classes(custom)
        settings = _motion_settings(motion, source)
        _check_keys(poses, {"hold_to_run"}, "poses.", source)
        hold_to_run = poses.get("hold_to_run", HOLD_TO_RUN)
        if not isinstance(hold_to_run, bool):
            raise ConfigError(f"{source}: poses.hold_to_run must be true or false")
        actions: dict[str, Action] = {}
        for gesture, spec in gestures.items():
            key = f"gestures.{gesture}"
            if gesture not in known:
                raise ConfigError(
                    f"{source}: {key}: unknown gesture {gesture!r} (neither built-in nor "
                    f"defined under [custom_gestures.{gesture}])"
                )
            action = _parse_action(spec, hold_to_run, key, source)
            if action is not None and gesture == INVALID:
                raise ConfigError(f"{source}: {key}: 'invalid' never starts an action; use 'none'")
            if action is not None:
                actions[gesture] = action
        return cls(actions, settings, source, tuple(gestures), custom)

    def action_for(self, gesture: str | None) -> Action | None:
        """The action of ``gesture`` (``None`` for no command, ``invalid`` or unmapped)."""
        if gesture is None:
            return None
        return self.actions.get(gesture)

    def resolve(self, name: str) -> Action | None:
        """The action of a gesture name, or an action written as in the mapping file
        (``"translate +x"``, ``"rotate -z"``, ``"pose home"``); ``ConfigError`` otherwise."""
        if name in self.class_names:
            return self.action_for(name)
        return _parse_action(name, self.hold_to_run, "action", "input")

    @property
    def hold_to_run(self) -> bool:
        """Whether pose actions stop when their command ends (``poses.hold_to_run``)."""
        poses = [a for a in self.actions.values() if isinstance(a, PoseAction)]
        return poses[0].hold_to_run if poses else HOLD_TO_RUN

    def target_twist(self, gesture: str | None, tcp: Pose) -> np.ndarray:
        """Base-frame twist ``[vx, vy, vz, wx, wy, wz]`` of ``gesture`` at full speed.

        Tool- and skin-frame axes are turned into the base frame with the TCP's
        orientation. Pose actions and no action give a zero twist.
        """
        return self.twist_of(self.action_for(gesture), tcp)

    def twist_of(self, action: Action | None, tcp: Pose, frame: str | None = None) -> np.ndarray:
        """Base-frame twist of ``action`` at full speed, its axis read in ``frame``
        (``tool``, ``base`` or ``skin``; default: the mapping's ``motion.frame``)."""
        twist = np.zeros(6)
        if not isinstance(action, TwistAction):
            return twist
        frame = self.settings.frame if frame is None else frame
        if frame not in FRAMES:
            raise ConfigError(f"unknown frame {frame!r}: use tool, base or skin")
        axis = action.axis
        if frame == "skin":
            axis = tcp.rotation() @ (self.settings.skin_rotation() @ axis)
        elif frame == "tool":
            axis = tcp.rotation() @ axis
        if action.kind == "translate":
            twist[:3] = axis * self.settings.linear_speed
        else:
            twist[3:] = axis * self.settings.angular_speed
        return twist


# -- parsing helpers -------------------------------------------------------------------

_LINEAR_KEYS = ("linear_speed", "linear_accel", "linear_jerk")
_ANGULAR_KEYS = ("angular_speed", "angular_accel", "angular_jerk")  # degrees in the file


def _table(data: dict[str, Any], key: str, source: str) -> dict[str, Any]:
    value = data.get(key, {})
    if not isinstance(value, dict):
        raise ConfigError(f"{source}: {key} must be a table")
    return value


def _check_keys(table: dict[str, Any], allowed: set[str], prefix: str, source: str) -> None:
    for key in table:
        if key not in allowed:
            expected = ", ".join(sorted(allowed))
            raise ConfigError(f"{source}: {prefix}{key}: unknown key (expected one of {expected})")


def _unit(values: Any, name: str) -> np.ndarray:
    """``values`` as a unit 3-vector; else a one-line ``ConfigError`` naming ``name``."""
    try:
        vector = np.array(values, dtype=float).reshape(-1)
    except (TypeError, ValueError):
        raise ConfigError(f"{name} must be three numbers, got {values!r}") from None
    norm = float(np.linalg.norm(vector)) if vector.shape == (3,) else 0.0
    if vector.shape != (3,) or not (math.isfinite(norm) and norm > 1e-9):
        raise ConfigError(f"{name} must be three finite numbers, not all zero, got {values!r}")
    return vector / norm


def _motion_settings(motion: dict[str, Any], source: str) -> MotionSettings:
    allowed = {"frame", "skin_up", "skin_right", "profile", *_LINEAR_KEYS, *_ANGULAR_KEYS}
    _check_keys(motion, allowed, "motion.", source)
    values: dict[str, Any] = {}
    if "profile" in motion:
        values["profile"] = profile_from_table(motion["profile"], f"{source}: motion.profile")
    if "frame" in motion:
        frame = motion["frame"]
        if frame not in FRAMES:
            raise ConfigError(
                f"{source}: motion.frame must be 'tool', 'base' or 'skin', got {frame!r}"
            )
        values["frame"] = frame
    for key in ("skin_up", "skin_right"):
        if key in motion:
            try:
                values[key] = tuple(_unit(motion[key], f"motion.{key}"))
            except ConfigError as exc:
                raise ConfigError(f"{source}: {exc}") from None
    for key in (*_LINEAR_KEYS, *_ANGULAR_KEYS):
        if key not in motion:
            continue
        value = motion[key]
        number = isinstance(value, int | float) and not isinstance(value, bool)
        if not (number and math.isfinite(value) and value > 0.0):
            raise ConfigError(f"{source}: motion.{key} must be a positive number, got {value!r}")
        values[key] = math.radians(value) if key in _ANGULAR_KEYS else float(value)
    try:
        return MotionSettings(**values)
    except ConfigError as exc:
        raise ConfigError(f"{source}: motion: {exc}") from None


def _parse_action(spec: Any, hold_to_run: bool, key: str, source: str) -> Action | None:
    if not isinstance(spec, str):
        raise ConfigError(f"{source}: {key} must be a string such as 'translate +z'")
    words = spec.split()
    if words == ["none"]:
        return None
    if len(words) == 2 and words[0] in ("translate", "rotate"):
        return TwistAction(words[0], _parse_axis(words[1], key, source))  # type: ignore[arg-type]
    if len(words) == 2 and words[0] == "pose":
        if words[1] not in POSE_NAMES:
            raise ConfigError(
                f"{source}: {key}: unknown pose {words[1]!r} (expected initial or home)"
            )
        return PoseAction(words[1], hold_to_run)  # type: ignore[arg-type]
    raise ConfigError(
        f"{source}: {key}: cannot read {spec!r} "
        "(expected 'translate <axis>', 'rotate <axis>', 'pose initial|home' or 'none')"
    )


def _parse_axis(text: str, key: str, source: str) -> np.ndarray:
    sign = -1.0 if text.startswith("-") else 1.0
    name = text[1:] if text[:1] in "+-" and len(text) > 1 else text
    if name not in AXES:
        raise ConfigError(f"{source}: {key}: bad axis {text!r} (expected +x, -x, +y, -y, +z or -z)")
    axis = np.zeros(3)
    axis[AXES[name]] = sign
    return axis
