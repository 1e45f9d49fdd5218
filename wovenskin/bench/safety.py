"""The safety layer's adversarial probe on the simulated arm: do its margins hold as measured?

``wovenskin bench safety [--episodes N] [--seed S] [--json]`` (or ``python -m
wovenskin.bench.safety``) prints

- how close joint 6 comes to its limit when driven toward it through
  :class:`~wovenskin.control.safety.SafetyLayer` at 30-148 deg/s (5 deg margin), and
- over ``N`` episodes of random twists (random posture near the initial one, a workspace
  box of +-8 cm around it, ticks of 5-20 ms, commands held 0.02-0.4 s then released), the
  largest measured TCP linear and angular speeds over their caps, the furthest the TCP
  got outside the box and the deepest a joint got into its margin.

Everything runs on the simulated clock: the figures do not depend on the machine.
"""

from __future__ import annotations

import argparse
import logging
import math
from dataclasses import dataclass, field

import numpy as np
from rich.table import Table

from wovenskin.bench.results import BenchResult, figure_table
from wovenskin.control.safety import SafetyLayer
from wovenskin.control.safety_limits import SafetyLimits
from wovenskin.errors import ConfigError
from wovenskin.robots.sim import SimRobot, tm5_900


class _Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def joint_6_case(speed_deg: float) -> tuple[np.ndarray, SafetyLimits, np.ndarray]:
    """The joint-6 probe at ``speed_deg`` deg/s: the start posture (joint 6 at 230 deg,
    toward its upper limit), limits with a box the arm never reaches and an angular cap of
    at least ``speed_deg``, and the twist turning the tool about its own axis."""
    q0 = tm5_900.INITIAL_Q.copy()
    q0[5] = math.radians(230.0)
    limits = SafetyLimits(
        workspace_lower=[-2.0, -2.0, -2.0],
        workspace_upper=[2.0, 2.0, 2.0],
        max_angular_speed=math.radians(max(60.0, speed_deg)),
    )
    twist = np.r_[0.0, 0.0, 0.0, tm5_900.forward_kinematics(q0)[:3, 2] * math.radians(speed_deg)]
    return q0, limits, twist


def joint_6_clearance(speed_deg: float, tick: float = 0.005) -> float:
    """Smallest distance (deg) between joint 6 and its limit when driven at ``speed_deg``."""
    q0, limits, twist = joint_6_case(speed_deg)
    clock = _Clock()
    robot = SimRobot(q0=q0)
    safe = SafetyLayer(robot, limits, clock=clock)
    safe.connect()
    upper = tm5_900.JOINT_LIMITS.upper[5]
    closest = math.inf
    for i in range(round(2.5 / tick)):
        if i * tick < 2.0:
            safe.send_twist(twist)
        clock.now += tick
        safe.step(tick)
        closest = min(closest, upper - float(robot.state().q[5]))
    return math.degrees(closest)


@dataclass
class CapsProbe:
    """The worst figures over the random-twist episodes."""

    linear: float = 0.0  # measured TCP speed / cap
    angular: float = 0.0  # measured angular speed / cap
    outside_mm: float = -math.inf  # furthest outside the box (negative: always inside)
    into_margin_deg: float = -math.inf  # deepest into a joint margin (negative: never)


def probe_caps(episodes: int, seed: int) -> CapsProbe:
    """Random twists through the safety layer on the simulated arm (module docstring)."""
    rng = np.random.default_rng(seed)
    worst = CapsProbe()
    joints = tm5_900.JOINT_LIMITS
    for _ in range(episodes):
        q0 = tm5_900.INITIAL_Q + rng.uniform(-0.7, 0.7, 6)
        start = tm5_900.forward_kinematics(q0)[:3, 3]
        box = SafetyLimits(workspace_lower=start - 0.08, workspace_upper=start + 0.08)
        clock = _Clock()
        robot = SimRobot(q0=q0)
        safe = SafetyLayer(robot, box, clock=clock)
        safe.connect()
        for _ in range(6):
            if rng.random() < 0.5:
                twist = rng.uniform(-3.0, 3.0, 6)
            else:
                twist = rng.choice([0.0, 0.05, -0.3, 1.0, -3.0], 6)
            held, tick = rng.uniform(0.02, 0.4), float(rng.choice([0.005, 0.01, 0.02]))
            for i in range(round((held + 0.5) / tick)):
                if i * tick < held:
                    safe.send_twist(twist)
                clock.now += tick
                safe.step(tick)
                state = robot.state()
                p, q = state.tcp.position, state.q
                worst.linear = max(worst.linear, state.tcp_speed / box.max_linear_speed)
                angular = float(np.linalg.norm(state.tcp_twist[3:])) / box.max_angular_speed
                worst.angular = max(worst.angular, angular)
                out = max(np.max(box.workspace_lower - p), np.max(p - box.workspace_upper))
                worst.outside_mm = max(worst.outside_mm, 1000.0 * float(out))
                into = max(np.max(q - joints.upper), np.max(joints.lower - q)) + box.joint_margin
                worst.into_margin_deg = max(worst.into_margin_deg, math.degrees(float(into)))
    return worst


JOINT_6_SPEEDS_DEG = (30.0, 60.0, 100.0, 148.0)


@dataclass
class SafetyBenchResult(BenchResult):
    """The probe's figures: joint 6's clearance per speed and the random-twist worst case."""

    episodes: int
    seed: int
    joint_margin_deg: float
    joint_6_clearance_deg: dict[str, float] = field(default_factory=dict)  # speed -> clearance
    caps: CapsProbe = field(default_factory=CapsProbe)

    def table(self) -> Table:
        table = figure_table("wovenskin bench safety: the safety layer on the simulated arm")
        for speed, clearance in self.joint_6_clearance_deg.items():
            table.add_row(
                f"joint 6 driven at {speed} deg/s toward its limit: closest approach",
                f"{clearance:.2f} deg (margin {self.joint_margin_deg:g})",
            )
        what = f"random twists ({self.episodes} episodes, seed {self.seed})"
        table.add_row(f"{what}: measured TCP speed / cap", f"{self.caps.linear:.4f}")
        table.add_row(f"{what}: measured angular speed / cap", f"{self.caps.angular:.4f}")
        table.add_row(
            f"{what}: furthest outside the box (negative: inside)",
            f"{self.caps.outside_mm:+.4f} mm",
        )
        table.add_row(
            f"{what}: deepest into a joint margin (negative: clear)",
            f"{self.caps.into_margin_deg:+.4f} deg",
        )
        return table


def run_safety_benchmark(episodes: int = 40, seed: int = 0) -> SafetyBenchResult:
    """The whole probe (module docstring), with the safety layer's stop logging muted."""
    if episodes < 1:
        raise ConfigError(f"episodes must be at least 1, got {episodes}")
    previous = logging.root.manager.disable
    logging.disable(logging.WARNING)  # one line per safety stop otherwise
    try:
        result = SafetyBenchResult(
            episodes, seed, math.degrees(SafetyLimits().joint_margin),
            {f"{v:g}": joint_6_clearance(v) for v in JOINT_6_SPEEDS_DEG},
        )  # fmt: skip
        result.caps = probe_caps(episodes, seed)
    finally:
        logging.disable(previous)
    return result


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=40)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    from rich.console import Console

    Console().print(run_safety_benchmark(args.episodes, args.seed).table())


if __name__ == "__main__":
    main()
