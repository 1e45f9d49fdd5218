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
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from wovenskin.robots.base import Robot
from wovenskin.skin.layout import SkinLayout

_GEOM_TYPES = {
    mujoco.mjtGeom.mjGEOM_SPHERE: "sphere",
    mujoco.mjtGeom.mjGEOM_CAPSULE: "capsule",
    mujoco.mjtGeom.mjGEOM_CYLINDER: "cylinder",
    mujoco.mjtGeom.mjGEOM_BOX: "box",
    mujoco.mjtGeom.mjGEOM_ELLIPSOID: "sphere",
}


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
