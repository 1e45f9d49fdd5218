"""Safety limits, stop records, and the speed-cap and workspace-box rules every twist obeys."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from wovenskin.errors import ConfigError


def _vector(values: object, size: int) -> np.ndarray:
    return np.asarray(values, dtype=float).reshape(size).copy()


@dataclass(frozen=True)
class SafetyLimits:
    """What the safety layer enforces (SI units, base frame)."""

    max_linear_speed: float = 0.25  # m/s, TCP
    max_angular_speed: float = math.radians(60.0)  # rad/s
    workspace_lower: np.ndarray = field(default_factory=lambda: np.array([-0.8, -0.8, 0.05]))
    workspace_upper: np.ndarray = field(default_factory=lambda: np.array([0.8, 0.8, 1.2]))
    joint_margin: float = math.radians(5.0)  # rad, kept clear of every joint limit
    watchdog_s: float = 0.1  # longest silence of the skin or command stream
    box_horizon_s: float = 0.1  # the TCP must stay in the box this far ahead
    joint_horizon_s: float = 0.02  # joints are checked this far ahead
    arm_reach: float = 1.2  # m, bounds any joint axis's distance to the TCP (no Jacobian)
    assumed_stop_time_s: float = 0.3  # s, to rest after stop() when a backend declares none

    def __post_init__(self) -> None:
        lower = _vector(self.workspace_lower, 3)
        upper = _vector(self.workspace_upper, 3)
        if not (np.all(np.isfinite(lower)) and np.all(np.isfinite(upper))):
            raise ConfigError("workspace box bounds must be finite")
        if not np.all(lower < upper):
            raise ConfigError("workspace box: every lower bound must be below its upper bound")
        object.__setattr__(self, "workspace_lower", lower)
        object.__setattr__(self, "workspace_upper", upper)
        for name in ("max_linear_speed", "max_angular_speed", "watchdog_s", "box_horizon_s",
                     "joint_horizon_s", "arm_reach", "assumed_stop_time_s"):  # fmt: skip
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ConfigError(f"{name} must be a positive number, got {value!r}")
        if not (math.isfinite(self.joint_margin) and self.joint_margin >= 0.0):
            raise ConfigError(f"joint_margin must be >= 0, got {self.joint_margin!r}")

    def in_box(self, position: np.ndarray, tolerance: float = 0.0) -> bool:
        """Whether ``position`` lies in the workspace box (grown by ``tolerance``)."""
        p = np.asarray(position, dtype=float)
        lower, upper = self.workspace_lower - tolerance, self.workspace_upper + tolerance
        return bool(np.all(p >= lower) and np.all(p <= upper))


@dataclass(frozen=True)
class StopEvent:
    """One safety stop: when (the layer's clock), why (one line) and which check fired.

    ``source`` is one of ``"command"`` (a bad twist), ``"skin watchdog"``,
    ``"command watchdog"`` and ``"emergency"`` -- these latch until
    :meth:`SafetyLayer.clear_stop` -- or ``"joint limit"``, ``"workspace"`` and ``"speed"``,
    which stop or refuse one command and leave the arm free to move away.
    """

    t: float
    reason: str
    source: str


def cap_speeds(twist: np.ndarray, max_linear: float, max_angular: float) -> np.ndarray:
    """``twist`` with each part scaled down (direction kept) to its cap; huge values are safe."""
    out = np.asarray(twist, dtype=float).copy()
    for part, cap in ((slice(0, 3), max_linear), (slice(3, 6), max_angular)):
        vector = out[part]
        largest = float(np.max(np.abs(vector)))
        if largest == 0.0:
            continue
        unit = vector / largest  # no overflow in the norm below
        norm = float(np.linalg.norm(unit))
        if norm * largest > cap:
            out[part] = unit * (cap / norm)
    return out


def keep_in_box(
    velocity: np.ndarray,
    position: np.ndarray,
    limits: SafetyLimits,
    horizon: float,
    standoff: float = 0.0,
) -> np.ndarray:
    """Reduce each component of ``velocity`` so ``position + velocity * horizon`` stays in
    the workspace box less ``standoff`` (m); outside the box only motion back toward it is
    left. Within ``standoff`` of a wall the component is turned back inward, at most at
    ``standoff / horizon``: a backend that drifts off the commanded direction by that much
    (its tracking error) is pushed back before it reaches the wall."""
    p = np.asarray(position, dtype=float)
    push = standoff / horizon
    room_up = np.maximum((limits.workspace_upper - standoff - p) / horizon, -push)
    room_down = np.minimum((limits.workspace_lower + standoff - p) / horizon, push)
    return np.clip(np.asarray(velocity, dtype=float), room_down, room_up)


def held_back(
    asked: np.ndarray, sent: np.ndarray, refusing: str | None, limits: SafetyLimits
) -> tuple[str, ...]:
    """What changed the twist ``asked`` into ``sent`` on its way to the backend, one line
    each, for the views (``SafetyLayer.limiting``): a joint margin's refusal still in
    force; the speed caps, which scale the whole twist; an axis cut further than that,
    which met a workspace box face."""
    if not np.any(asked):
        return ()
    if refusing is not None:
        return (f"joint margin: {refusing}",)
    held: list[str] = []
    asked, sent = np.asarray(asked, dtype=float), np.asarray(sent, dtype=float)
    capped = cap_speeds(asked, limits.max_linear_speed, limits.max_angular_speed)
    moving = np.abs(asked[:3]) > 1e-9
    ratios = np.where(moving, sent[:3] / np.where(moving, asked[:3], 1.0), 1.0)
    largest = float(np.max(np.abs(asked[:3])))
    scale = float(np.max(np.abs(capped[:3]))) / largest if largest > 0 else 1.0
    if scale < 1.0 - 1e-6:
        held.append(f"speed cap: TCP speed limited to {1000 * limits.max_linear_speed:.0f} mm/s")
    if not np.allclose(capped[3:], asked[3:], rtol=1e-9, atol=1e-12):
        cap = math.degrees(limits.max_angular_speed)
        held.append(f"speed cap: rotation limited to {cap:.0f} deg/s")
    for axis, name in enumerate("xyz"):
        if moving[axis] and ratios[axis] < 0.98 * scale:  # (2 %: a backend's headroom)
            lower = asked[axis] < 0
            face = limits.workspace_lower if lower else limits.workspace_upper
            held.append(
                f"workspace box: {name} at its {'lower' if lower else 'upper'} limit "
                f"({1000 * face[axis]:.0f} mm)"
            )
    return tuple(held)
