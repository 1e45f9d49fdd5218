"""The task interface: a physics scene on the gripper arm that resets from a seed and measures.

A :class:`Task` owns an :class:`~wovenskin.robots.sim.physics.ArmPhysics` (its scene);
:meth:`Task.robot` builds the :class:`~wovenskin.robots.sim.robot.SimRobot` that moves the
arm in it. ``reset(seed)`` puts every object back with small seeded variations (the arm
stays where it is, the gripper opens), ``state()`` returns the task's measures as a
dataclass, ``succeeded()`` / ``failed()`` judge them (failed: success can no longer be
reached), ``to_dict()`` is one JSON-ready line for a trial log.
"""

from __future__ import annotations

import abc
from dataclasses import asdict
from typing import Any, ClassVar

import mujoco
import numpy as np

from wovenskin.io import to_jsonable
from wovenskin.robots.sim.physics import ArmPhysics
from wovenskin.robots.sim.robot import SimRobot

# The TCP lies between the fingertips, so a task's safety box lets it come down to 5 mm
# above the table (the default box keeps it 50 mm up, too high to grasp a 40 mm cube).
WORKSPACE_LOWER = np.array([-0.2, -0.8, 0.005])
WORKSPACE_UPPER = np.array([1.0, 0.8, 1.2])
SETTLE_S = 0.3  # after a reset, the objects settle this long (the arm held still)


class Task(abc.ABC):
    """One study task; subclasses build the scene and measure it."""

    name: ClassVar[str] = "task"

    def __init__(self) -> None:
        self.physics = ArmPhysics(self.build().compile())
        self.seed: int | None = None

    @abc.abstractmethod
    def build(self) -> mujoco.MjSpec:
        """The scene: :func:`~wovenskin.tasks.scene.base_spec` plus the task's bodies."""

    @abc.abstractmethod
    def place(self, rng: np.random.Generator) -> None:
        """Put the objects at their (varied) start poses in ``self.physics.data``."""

    @abc.abstractmethod
    def state(self) -> Any:
        """The task's measures now (a dataclass)."""

    @abc.abstractmethod
    def succeeded(self) -> bool:
        """Whether the task is done."""

    @abc.abstractmethod
    def failed(self) -> bool:
        """Whether success can no longer be reached (an object off the table, a spill)."""

    def robot(self, q0: np.ndarray | None = None, ik_rate_hz: float = 200.0) -> SimRobot:
        """The simulated arm moving in this scene (its gripper is the scene's), with one IK
        step per control tick of the 200 Hz skin (the arm alone takes 250 Hz: two IK
        steps a tick were half the cost of a step of the pouring scene)."""
        return SimRobot(q0, ik_rate_hz, physics=self.physics)

    def reset(self, seed: int) -> None:
        """Objects back to their start poses varied by ``seed`` (the same seed, the same
        scene), gripper open, then :data:`SETTLE_S` of physics with the arm still."""
        if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
            raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
        physics = self.physics
        q = physics.data.qpos[physics.arm_qpos].copy()
        physics.reset(q)
        self.place(np.random.default_rng(int(seed)))
        mujoco.mj_forward(physics.model, physics.data)
        physics.advance(q, q, SETTLE_S)
        physics.data.time = 0.0
        self.seed = int(seed)

    def to_dict(self) -> dict[str, Any]:
        """The task's measures and verdicts, JSON-ready."""
        return to_jsonable(
            {
                "task": self.name,
                "seed": self.seed,
                "t": self.physics.time,
                "succeeded": self.succeeded(),
                "failed": self.failed(),
                **asdict(self.state()),
            }
        )
