"""Task scene building: the gripper arm on a table, plus walls, objects and particles (MjSpec).

Every scene starts from :func:`~wovenskin.robots.sim.gripper.arm_with_gripper`: the arm
stands on a table whose top is the base frame's z = 0 (the arm bolted to it), 1.2 m deep
and 1.6 m wide, the floor 0.75 m below. Pockets, cups and containers are rings of wall
boxes around a regular polygon (:func:`regular_walls`): MuJoCo's collision primitives are
convex, so a hollow is built from several of them. Nothing is downloaded: all shapes are
primitives or small convex meshes written here.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import mujoco
import numpy as np

from wovenskin.robots.sim.gripper import CONTACT_BITS, arm_with_gripper

TABLE_HALF = (0.6, 0.8, 0.02)  # m: x from -0.2 to 1.0, y from -0.8 to 0.8, top at z = 0
TABLE_CENTRE = (0.4, 0.0, -0.02)
FLOOR_Z = -0.75
OBJECT_FRICTION = (1.0, 0.01, 0.0001)
WALL_RGBA = (0.55, 0.6, 0.68, 1.0)


def yaw_quat(yaw: float) -> list[float]:
    """The quaternion ``[w, x, y, z]`` of a turn by ``yaw`` about z."""
    return [math.cos(yaw / 2.0), 0.0, 0.0, math.sin(yaw / 2.0)]


def base_spec() -> mujoco.MjSpec:
    """The gripper arm on the table, ready for a task to add its objects."""
    spec = arm_with_gripper()
    spec.modelname = "task_scene"
    # Conjugate gradient: with a hundred particles (600 degrees of freedom, 400 contacts)
    # the Newton solver's factorisation took 10 ms a step, CG 1 ms (bench/tasks.py).
    spec.option.solver = mujoco.mjtSolver.mjSOL_CG
    # Objects at rest sleep (MuJoCo's island sleeping: a resting cup of particles cost
    # 1.2 ms a step awake, 0.07 ms asleep) and wake when touched.  The arm never sleeps:
    # its tree is actuated (the gripper), which MuJoCo's automatic policy keeps awake.
    spec.option.enableflags |= mujoco.mjtEnableBit.mjENBL_SLEEP
    for key in list(spec.keys):
        spec.delete(key)  # the arm's keyframes would not cover the objects' joints
    floor = spec.geom("floor")
    floor.pos = [0.0, 0.0, FLOOR_Z]
    collide(floor)
    table = spec.worldbody.add_body(name="table", pos=list(TABLE_CENTRE))
    top = table.add_geom(
        name="table", type=mujoco.mjtGeom.mjGEOM_BOX, size=list(TABLE_HALF),
        rgba=[0.72, 0.6, 0.45, 1.0],
    )  # fmt: skip
    collide(top)
    top.friction = list(OBJECT_FRICTION)
    return spec


def collide(geom: mujoco.MjsGeom, condim: int = 4) -> None:
    """Let ``geom`` touch everything else that collides in a task scene."""
    geom.contype = CONTACT_BITS
    geom.conaffinity = CONTACT_BITS
    geom.condim = condim


def regular_walls(
    body: mujoco.MjsBody,
    prefix: str,
    sides: int,
    inradius: float,
    thickness: float,
    height: float,
    z0: float = 0.0,
    phase: float = 0.0,
    rgba: Sequence[float] = WALL_RGBA,
) -> None:
    """Walls around a regular polygon of ``sides`` sides whose inner faces lie
    ``inradius`` from the body's origin (the first face's normal at ``phase`` rad), from
    ``z0`` up to ``z0 + height``; a many-sided one stands for a round wall."""
    half_edge = inradius * math.tan(math.pi / sides) + thickness * math.tan(math.pi / sides)
    for k in range(sides):
        angle = phase + 2.0 * math.pi * k / sides
        distance = inradius + thickness / 2.0
        wall = body.add_geom(
            name=f"{prefix}_{k}", type=mujoco.mjtGeom.mjGEOM_BOX,
            size=[thickness / 2.0, half_edge, height / 2.0],
            pos=[distance * math.cos(angle), distance * math.sin(angle), z0 + height / 2.0],
            quat=yaw_quat(angle), rgba=list(rgba),
        )  # fmt: skip
        collide(wall)
        wall.friction = list(OBJECT_FRICTION)


def free_body(spec: mujoco.MjSpec, name: str, pos: Sequence[float]) -> mujoco.MjsBody:
    """A body that moves freely (its own free joint, named like it)."""
    body = spec.worldbody.add_body(name=name, pos=list(pos))
    body.add_freejoint(name=name)
    return body


def static_body(spec: mujoco.MjSpec, name: str, pos: Sequence[float]) -> mujoco.MjsBody:
    return spec.worldbody.add_body(name=name, pos=list(pos))


def set_free_pose(
    model: mujoco.MjModel, data: mujoco.MjData, joint: str, pos: Sequence[float], yaw: float
) -> None:
    """Place a free body (by its joint's name) at ``pos`` turned by ``yaw``, at rest."""
    j = model.joint(joint)
    adr, dof = int(j.qposadr[0]), int(j.dofadr[0])
    data.qpos[adr : adr + 3] = pos
    data.qpos[adr + 3 : adr + 7] = yaw_quat(yaw)
    data.qvel[dof : dof + 6] = 0.0


def body_yaw_and_tilt(data: mujoco.MjData, body: int) -> tuple[float, float]:
    """A body's yaw (rad, of its x axis about world z) and tilt (rad, its z axis from up)."""
    rotation = data.xmat[body].reshape(3, 3)
    yaw = math.atan2(rotation[1, 0], rotation[0, 0])
    tilt = math.acos(float(np.clip(rotation[2, 2], -1.0, 1.0)))
    return yaw, tilt
