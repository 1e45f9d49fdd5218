"""ArmPhysics: a MuJoCo physics scene whose arm joints follow the kinematic SimRobot.

The simulated arm stays kinematic (its joint angles come from :class:`SimRobot`'s IK and
joint moves); in a physics scene every physics step first sets the arm's joint positions
and velocities to the commanded ones, then ``mj_step`` moves everything else (gripper
fingers, objects, particles) through contacts. With the velocities set consistently the
contact solver sees the true relative motion, so the fingers push and carry objects as a
stiff, position-controlled industrial arm does; the arm's large joint armature keeps the
contact reactions from moving it within a step (it is an idealised arm that no object can
push back; a position servo at high gain was the alternative, whose tracking lag and
stiffness trade-off would add errors that the real arm's controller does not have).
The model must hold the arm's joints (``joint1`` .. ``joint6``, first in ``qpos``) and its
``tcp`` site; a gripper is there when the model has the :data:`FINGER_JOINTS` actuators.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from wovenskin.robots.base import N_JOINTS, GripperState
from wovenskin.robots.sim.gripper import FINGER_JOINTS, FINGER_TRAVEL
from wovenskin.robots.sim.tm5_900 import JOINT_NAMES


class ArmPhysics:
    """Steps ``model`` with the arm's joints prescribed; see the module docstring."""

    def __init__(self, model: mujoco.MjModel) -> None:
        self.model = model
        self.data = mujoco.MjData(model)
        try:
            joints = [model.joint(name) for name in JOINT_NAMES]
            self._tcp = model.site("tcp").id
        except KeyError as exc:
            raise ValueError(f"the physics model lacks the arm's {exc}") from None
        self._qadr = np.array([int(j.qposadr[0]) for j in joints])
        self._dadr = np.array([int(j.dofadr[0]) for j in joints])
        names = {model.actuator(i).name for i in range(model.nu)}
        self.has_gripper = all(name in names for name in FINGER_JOINTS)
        self._fingers = (
            [int(model.joint(name).qposadr[0]) for name in FINGER_JOINTS]
            if self.has_gripper
            else []
        )
        self._actuators = (
            [model.actuator(name).id for name in FINGER_JOINTS] if self.has_gripper else []
        )
        self._closed = False
        self._pending = 0.0
        self.reset(np.zeros(N_JOINTS))

    @property
    def arm_qpos(self) -> np.ndarray:
        """Where the arm's six joint angles sit in ``data.qpos``."""
        return self._qadr.copy()

    @property
    def timestep(self) -> float:
        return float(self.model.opt.timestep)

    @property
    def time(self) -> float:
        """Simulated seconds since the last :meth:`reset`."""
        return float(self.data.time)

    def reset(self, q: np.ndarray) -> None:
        """Everything back to the model's initial state, the arm at ``q``, gripper open."""
        mujoco.mj_resetData(self.model, self.data)
        self._pending = 0.0
        self.data.qpos[self._qadr] = q
        self.set_gripper(False)
        for adr in self._fingers:
            self.data.qpos[adr] = FINGER_TRAVEL
        mujoco.mj_forward(self.model, self.data)

    def place_arm(self, q: np.ndarray) -> None:
        """Put the arm at ``q``, at rest, leaving everything else where it is."""
        self.data.qpos[self._qadr] = q
        self.data.qvel[self._dadr] = 0.0
        mujoco.mj_forward(self.model, self.data)

    def set_gripper(self, closed: bool) -> None:
        """Command the fingers shut (they stop on whatever is between them) or open."""
        if not self.has_gripper:
            return
        self._closed = bool(closed)
        self.data.ctrl[self._actuators] = 0.0 if self._closed else FINGER_TRAVEL

    def gripper_state(self) -> GripperState | None:
        """The last gripper command and the opening between the fingers (m)."""
        if not self.has_gripper:
            return None
        width = float(sum(self.data.qpos[adr] for adr in self._fingers))
        return GripperState(closed=self._closed, width=width)

    def advance(self, q_start: np.ndarray, q_end: np.ndarray, h: float) -> None:
        """Run the physics over ``h`` seconds while the arm goes from ``q_start`` to
        ``q_end`` at constant joint velocity (time left over below one physics step is
        carried to the next call)."""
        if h <= 0.0:
            return
        dq = (np.asarray(q_end) - np.asarray(q_start)) / h
        self._pending += h
        steps = math.floor(self._pending / self.timestep + 1e-9)
        self._pending -= steps * self.timestep
        for k in range(steps):
            # where the arm is at the start of this physics step (the last ends at q_end)
            fraction = 1.0 - (steps - k) * self.timestep / h
            self.data.qpos[self._qadr] = q_start + dq * max(fraction, 0.0) * h
            self.data.qvel[self._dadr] = dq
            mujoco.mj_step(self.model, self.data)
        self.data.qpos[self._qadr] = q_end
        self.data.qvel[self._dadr] = dq
        mujoco.mj_kinematics(self.model, self.data)

    def tcp_position(self) -> np.ndarray:
        return self.data.site_xpos[self._tcp].copy()
