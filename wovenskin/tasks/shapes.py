"""The pick-and-place shapes (cube, cylinder, triangular prism) and their molds' pockets.

Each shape stands on its base, its footprint a regular polygon (a circle: ``sides`` 0)
centred on the body's origin; ``symmetry`` is the yaw period under which it looks the same
(None: any yaw). A mold is walls around the shape's footprint widened by the clearance on
every side (:func:`add_mold`), so a shape fits only in its own mold and, for the cube and
the prism, only turned to match.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import mujoco

from wovenskin.tasks.scene import OBJECT_FRICTION, collide, free_body, regular_walls

DENSITY = 600.0  # kg/m^3, wood
CLEARANCE = 0.003  # m, between a shape and its pocket's walls on every side
MOLD_WALL = 0.008  # m thick
MOLD_HEIGHT = 0.025  # m
ROUND_SIDES = 16  # a round pocket's walls


@dataclass(frozen=True)
class Shape:
    """A shape's footprint (a regular polygon of ``sides``, 0: a circle of ``inradius``),
    its height and its yaw symmetry."""

    name: str
    sides: int
    inradius: float  # m: polygon centre to the middle of an edge (a circle's radius)
    height: float  # m
    rgba: tuple[float, float, float, float]

    PHASES: ClassVar[dict[int, float]] = {4: 0.0, 3: math.pi / 3.0}  # first edge normal

    @property
    def symmetry(self) -> float | None:
        """Yaw period (rad) under which the shape looks the same; None: any yaw."""
        return 2.0 * math.pi / self.sides if self.sides else None

    @property
    def phase(self) -> float:
        return self.PHASES.get(self.sides, 0.0)

    def add_to(self, spec: mujoco.MjSpec, pos: tuple[float, float, float]) -> mujoco.MjsBody:
        """The shape as a free body named after it."""
        body = free_body(spec, self.name, pos)
        common = {"name": self.name, "rgba": list(self.rgba), "density": DENSITY}
        if self.sides == 0:
            geom = body.add_geom(
                type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=[self.inradius, self.height / 2.0, 0],
                **common,
            )  # fmt: skip
        elif self.sides == 4:
            half = [self.inradius, self.inradius, self.height / 2.0]
            geom = body.add_geom(type=mujoco.mjtGeom.mjGEOM_BOX, size=half, **common)
        else:
            spec.add_mesh(name=self.name, uservert=self._prism_vertices())
            geom = body.add_geom(type=mujoco.mjtGeom.mjGEOM_MESH, meshname=self.name, **common)
        collide(geom)
        geom.friction = list(OBJECT_FRICTION)
        return body

    def _prism_vertices(self) -> list[float]:
        """Corners of the extruded polygon (between two edge normals), flat."""
        circumradius = self.inradius / math.cos(math.pi / self.sides)
        vertices: list[float] = []
        for k in range(self.sides):
            angle = self.phase + (2 * k + 1) * math.pi / self.sides
            x, y = circumradius * math.cos(angle), circumradius * math.sin(angle)
            for z in (-self.height / 2.0, self.height / 2.0):
                vertices += [x, y, z]
        return vertices


CUBE = Shape("cube", 4, 0.02, 0.04, (0.85, 0.3, 0.25, 1.0))
CYLINDER = Shape("cylinder", 0, 0.02, 0.05, (0.25, 0.55, 0.85, 1.0))
PRISM = Shape("prism", 3, 0.046 / (2.0 * math.sqrt(3.0)), 0.05, (0.3, 0.7, 0.35, 1.0))
SHAPES = (CUBE, CYLINDER, PRISM)


def add_mold(spec: mujoco.MjSpec, shape: Shape, pos: tuple[float, float]) -> mujoco.MjsBody:
    """A pocket for ``shape`` on the table at ``pos`` (walls :data:`MOLD_HEIGHT` high)."""
    body = spec.worldbody.add_body(name=f"mold_{shape.name}", pos=[pos[0], pos[1], 0.0])
    sides = shape.sides or ROUND_SIDES
    inradius = shape.inradius + CLEARANCE  # every face CLEARANCE away from the shape's
    regular_walls(
        body, f"mold_{shape.name}", sides, inradius, MOLD_WALL, MOLD_HEIGHT, phase=shape.phase
    )
    return body
