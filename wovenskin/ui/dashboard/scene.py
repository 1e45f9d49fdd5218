"""The 3D view's content: the arm's shapes once, then their world poses for joint angles.

:class:`ArmScene` loads the MuJoCo model of a robot with a kinematic model (the simulated
TM5-900, or a real Techman arm whose reported joints it mirrors), lists its visible geoms
(type, size, colour) and, for joint angles ``q``, computes every geom's position and
orientation with ``mj_kinematics``, plus the skin patch's corners, so the page draws the
same arm the simulation moves.  Which model to draw is the backend's declaration
(``RobotCapabilities.scene``): a Universal Robots arm is drawn from its own DH table
(:mod:`wovenskin.robots.ur.models`: the model named in its spec, else a UR5e, said so in
the page's messages).  An arm that declares no scene gets none: the page then shows the
TCP only.

:class:`TaskScene` does the same for a study task's physics scene (:mod:`wovenskin.tasks`):
its fixed geoms (table, molds, container) with their poses once, its moving geoms (the
objects, the cup, the gripper fingers) and its particles (small spheres named
``particle_*``, sent as bare positions for the page to draw as one instanced mesh), posed
from the physics state each frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from wovenskin.robots.base import Robot
from wovenskin.robots.sim.gripper import FINGER_JOINTS
from wovenskin.skin.layout import SkinLayout

_GEOM_TYPES = {
    mujoco.mjtGeom.mjGEOM_SPHERE: "sphere",
    mujoco.mjtGeom.mjGEOM_CAPSULE: "capsule",
    mujoco.mjtGeom.mjGEOM_CYLINDER: "cylinder",
    mujoco.mjtGeom.mjGEOM_BOX: "box",
    mujoco.mjtGeom.mjGEOM_ELLIPSOID: "sphere",
}
PARTICLE_PREFIX = "particle_"  # a task's particles: drawn instanced, positions only


@dataclass(frozen=True)
class GeomShape:
    """One visible geom: MuJoCo type name, MuJoCo sizes (half-lengths, radii), RGBA."""

    name: str
    type: str
    size: tuple[float, ...]
    rgba: tuple[float, ...]

    def to_dict(self) -> dict:
        return {"name": self.name, "type": self.type, "size": self.size, "rgba": self.rgba}


class ArmScene:
    """Shapes and poses of an arm model (see the module docstring)."""

    def __init__(
        self,
        model: mujoco.MjModel,
        skin_site: str,
        up: np.ndarray,
        right: np.ndarray,
        caveat: str = "",
    ) -> None:
        self.model = model
        self.caveat = caveat  # how the drawing may differ from the arm, for the page
        self.data = mujoco.MjData(model)
        self._geoms: list[int] = []
        self.shapes: list[GeomShape] = []
        for g in range(model.ngeom):
            kind = _GEOM_TYPES.get(int(model.geom_type[g]))
            if kind is None:  # the floor plane: the page draws its own grid
                continue
            name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or f"geom{g}"
            size = tuple(round(float(v), 5) for v in model.geom_size[g])
            rgba = tuple(round(float(v), 3) for v in model.geom_rgba[g])
            self._geoms.append(g)
            self.shapes.append(GeomShape(name, kind, size, rgba))
        self._site = model.site(skin_site).id
        self._site_half = np.asarray(model.site_size[self._site], dtype=float)
        self._up = np.asarray(up, dtype=float)
        self._right = np.asarray(right, dtype=float)
        self.nq = int(model.nq)

    @classmethod
    def for_robot(cls, robot: object) -> ArmScene | None:
        """The scene a backend declares (``RobotCapabilities.scene``), or ``None``."""
        if not isinstance(robot, Robot):
            return None
        scene = robot.capabilities().scene
        if scene is None:
            return None
        return cls(scene.load(), scene.skin_site, scene.up_axis, scene.right_axis, scene.caveat)

    def describe(self) -> dict:
        """The static part, sent once per page: shapes in the order of :meth:`poses`."""
        return {"geoms": [shape.to_dict() for shape in self.shapes]}

    def poses(self, q: np.ndarray) -> list[list[float]]:
        """``[x, y, z, qw, qx, qy, qz]`` (m, base frame) of every shape at joints ``q``."""
        q = np.asarray(q, dtype=float).reshape(-1)
        if q.shape[0] != self.nq or not np.all(np.isfinite(q)):
            raise ValueError(f"expected {self.nq} finite joint angles, got {q.shape[0]}")
        self.data.qpos[:] = q
        mujoco.mj_kinematics(self.model, self.data)
        out = []
        quat = np.zeros(4)
        for g in self._geoms:
            mujoco.mju_mat2Quat(quat, self.data.geom_xmat[g])
            out.append([round(float(v), 5) for v in (*self.data.geom_xpos[g], *quat)])
        return out

    def skin_corners(self, layout: SkinLayout) -> list[list[float]]:
        """World positions of the skin's top-left, top-right and bottom-left corners (the
        last :meth:`poses` call's joints), for a ``layout`` centred on the patch site."""
        centre = self.data.site_xpos[self._site]
        rotation = self.data.site_xmat[self._site].reshape(3, 3)
        up = rotation @ self._up
        right = rotation @ self._right
        half_h, half_w = layout.height_mm / 2000.0, layout.width_mm / 2000.0
        top_left = centre + up * half_h - right * half_w
        top_right = centre + up * half_h + right * half_w
        bottom_left = centre - up * half_h - right * half_w
        return [[round(float(v), 5) for v in p] for p in (top_left, top_right, bottom_left)]


def _pose(data: mujoco.MjData, g: int, quat: np.ndarray) -> list[float]:
    mujoco.mju_mat2Quat(quat, data.geom_xmat[g])
    return [round(float(v), 5) for v in (*data.geom_xpos[g], *quat)]


class TaskScene:
    """The task scene's shapes and their poses (see the module docstring).

    The arm and its gripper housing are :class:`ArmScene`'s; this draws every other geom
    of the task's physics model and the fingers (named in ``hide``: the page hides the arm
    model's own fingers, which do not slide)."""

    def __init__(self, task: object) -> None:
        physics = task.physics  # type: ignore[attr-defined]
        self.name = str(getattr(task, "name", "task"))
        self.model, self.data = physics.model, physics.data
        arm_bodies = {0} | {int(self.model.body(name).id) for name in _arm_body_names(self.model)}
        self.fixed: list[int] = []
        self.moving: list[int] = []
        self.particles: list[int] = []
        for g in range(self.model.ngeom):
            name = mujoco.mj_id2name(self.model, mujoco.mjtObj.mjOBJ_GEOM, g) or ""
            kind = int(self.model.geom_type[g])
            if kind == mujoco.mjtGeom.mjGEOM_PLANE:
                continue
            body = int(self.model.geom_bodyid[g])
            if name.startswith(PARTICLE_PREFIX) and kind == mujoco.mjtGeom.mjGEOM_SPHERE:
                self.particles.append(g)
            elif name in FINGER_JOINTS or body not in arm_bodies or body == 0:
                welded = int(self.model.body_weldid[body]) == 0
                (self.fixed if welded else self.moving).append(g)
        self.hide = [n for n in FINGER_JOINTS if any(self._name(g) == n for g in self.moving)]

    def _name(self, g: int) -> str:
        return mujoco.mj_id2name(self.model, mujoco.mjtObj.mjOBJ_GEOM, g) or f"geom{g}"

    def _shape(self, g: int) -> dict:
        kind = int(self.model.geom_type[g])
        shape = {
            "name": self._name(g),
            "type": "mesh" if kind == mujoco.mjtGeom.mjGEOM_MESH else _GEOM_TYPES.get(kind, "box"),
            "size": [round(float(v), 5) for v in self.model.geom_size[g]],
            "rgba": [round(float(v), 3) for v in self.model.geom_rgba[g]],
        }
        if shape["type"] == "mesh":
            mesh = int(self.model.geom_dataid[g])
            v0, nv = int(self.model.mesh_vertadr[mesh]), int(self.model.mesh_vertnum[mesh])
            f0, nf = int(self.model.mesh_faceadr[mesh]), int(self.model.mesh_facenum[mesh])
            vertices = self.model.mesh_vert[v0 : v0 + nv].reshape(-1)
            shape["vertices"] = [round(float(v), 5) for v in vertices]
            shape["faces"] = [int(i) for i in self.model.mesh_face[f0 : f0 + nf].reshape(-1)]
        return shape

    def describe(self) -> dict:
        """The static part, sent once per page: fixed shapes with their poses, moving
        shapes in the order of :meth:`poses`, the particles' count, radius and colour."""
        quat = np.zeros(4)
        size, rgba = self.model.geom_size, self.model.geom_rgba
        particle = self.particles[0] if self.particles else None
        return {
            "name": self.name,
            "fixed": [{**self._shape(g), "pose": _pose(self.data, g, quat)} for g in self.fixed],
            "moving": [self._shape(g) for g in self.moving],
            "particles": {
                "count": len(self.particles),
                "radius": 0.0 if particle is None else round(float(size[particle][0]), 5),
                "rgba": [] if particle is None else [round(float(v), 3) for v in rgba[particle]],
            },
            "hide": self.hide,
        }

    def poses(self) -> dict:
        """The moving shapes' ``[x, y, z, qw, qx, qy, qz]`` and the particles' positions
        as one flat ``[x0, y0, z0, x1, ...]`` list (m, 0.1 mm steps), from the physics."""
        quat = np.zeros(4)
        centres = self.data.geom_xpos[self.particles].reshape(-1) if self.particles else ()
        return {
            "geoms": [_pose(self.data, g, quat) for g in self.moving],
            "particles": [round(float(v), 4) for v in centres],
        }


def _arm_body_names(model: mujoco.MjModel) -> list[str]:
    """The bodies of the arm and its gripper: the subtree under the arm's base body."""
    base = int(model.body("base").id) if _has_body(model, "base") else 0
    names = []
    for b in range(1, model.nbody):
        walk = b
        while walk not in (0, base):
            walk = int(model.body_parentid[walk])
        if walk == base and base != 0:
            names.append(model.body(b).name)
    return names


def _has_body(model: mujoco.MjModel, name: str) -> bool:
    return mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name) >= 0
