"""Pouring: a cup of about 100 small spheres (a particle liquid) to empty into a container.

The cup stands on the arm's left (+y), the open container (a square of walls on the table)
on its right (-y). Each particle is counted as in the cup (inside its walls, in the cup's
frame), delivered (inside the container's walls, below their rim), spilled (outside both,
below the container's rim: on the table or the floor) or airborne (anywhere else: falling).
The task succeeds when nothing is spilled, nothing is airborne and at most
:data:`LEFT_FRACTION` of the particles are left in the cup; it fails once a particle is
spilled or the cup falls off the table. Particle size and count follow the granular
"liquids" of robot pouring benchmarks (spheres of about 1 cm).
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np

from wovenskin.tasks.base import Task
from wovenskin.tasks.scene import (
    base_spec,
    collide,
    free_body,
    regular_walls,
    set_free_pose,
    static_body,
)

N_PARTICLES = 100
PARTICLE_RADIUS = 0.005  # m
PARTICLE_DENSITY = 1000.0  # kg/m^3
PARTICLE_FRICTION = (0.3, 0.005, 0.0001)  # (unused while frictionless)
PARTICLE_CONDIM = 1  # frictionless, like a liquid: one constraint row per contact
# Stiff contacts (time constant two physics steps): with MuJoCo's default (0.02 s) a stack of
# six layers sank 3 mm per layer into itself and through the cup's bottom.
PARTICLE_SOLREF = (0.004, 1.0)
PARTICLE_SOLIMP = (0.95, 0.99, 0.001, 0.5, 2.0)
CUP_XY = (0.45, 0.22)  # m, the cup's start on the table
CUP_RADIUS = 0.03  # m, inside
CUP_WALL = 0.003  # m
CUP_HEIGHT = 0.08  # m, walls above the bottom
CUP_BOTTOM = 0.004  # m thick
CUP_SIDES = 16
CONTAINER_XY = (0.45, -0.22)  # m
CONTAINER_HALF = 0.08  # m, inside half width
CONTAINER_HEIGHT = 0.06  # m
CONTAINER_WALL = 0.008  # m
JITTER = 0.01  # m, the cup's start varies by up to this along x and y
LEFT_FRACTION = 0.05  # success leaves at most this share in the cup
OFF_TABLE_Z = -0.05  # m


@dataclass(frozen=True)
class PourState:
    """Where the particles are."""

    in_cup: int
    delivered: int
    spilled: int
    airborne: int
    total: int
    cup_position: np.ndarray  # (3,) m
    cup_tilt: float  # deg, the cup's axis from upright


def particle_layout(rng: np.random.Generator) -> np.ndarray:
    """Start positions of the particles in the cup's frame: a loose grid, layer upon layer,
    jittered by ``rng``."""
    pitch = 2.0 * PARTICLE_RADIUS + 0.0008
    reach = CUP_RADIUS - PARTICLE_RADIUS - 0.0005
    steps = np.arange(-reach, reach + 1e-9, pitch)
    layer = [(x, y) for x in steps for y in steps if x * x + y * y <= reach * reach]
    positions = []
    z = CUP_BOTTOM + PARTICLE_RADIUS + 0.0005
    while len(positions) < N_PARTICLES:
        for x, y in layer[: N_PARTICLES - len(positions)]:
            positions.append((x, y, z))
        z += pitch
    jitter = rng.uniform(-0.0003, 0.0003, (N_PARTICLES, 2))
    out = np.array(positions)
    out[:, :2] += jitter
    return out


class PourTask(Task):
    """Pour the particles from the cup into the container without spilling."""

    name = "pour"

    def build(self) -> mujoco.MjSpec:
        spec = base_spec()
        cup = free_body(spec, "cup", (CUP_XY[0], CUP_XY[1], 0.0))
        bottom = cup.add_geom(
            name="cup_bottom", type=mujoco.mjtGeom.mjGEOM_CYLINDER,
            size=[CUP_RADIUS + CUP_WALL, CUP_BOTTOM / 2.0, 0.0], pos=[0.0, 0.0, CUP_BOTTOM / 2.0],
            rgba=[0.9, 0.9, 0.95, 1.0], density=900.0,
        )  # fmt: skip
        collide(bottom)
        regular_walls(
            cup, "cup_wall", CUP_SIDES, CUP_RADIUS, CUP_WALL, CUP_HEIGHT, z0=CUP_BOTTOM,
            rgba=(0.9, 0.9, 0.95, 0.6),
        )  # fmt: skip
        container = static_body(spec, "container", (CONTAINER_XY[0], CONTAINER_XY[1], 0.0))
        regular_walls(
            container, "container_wall", 4, CONTAINER_HALF, CONTAINER_WALL, CONTAINER_HEIGHT
        )
        for i in range(N_PARTICLES):
            particle = free_body(spec, f"particle_{i}", (CUP_XY[0], CUP_XY[1], 0.1 + 0.011 * i))
            geom = particle.add_geom(
                name=f"particle_{i}", type=mujoco.mjtGeom.mjGEOM_SPHERE,
                size=[PARTICLE_RADIUS, 0.0, 0.0], density=PARTICLE_DENSITY,
                rgba=[0.2, 0.45, 0.95, 1.0],
            )  # fmt: skip
            collide(geom, condim=PARTICLE_CONDIM)
            geom.priority = 2  # its contacts are frictionless, whatever it touches
            geom.friction = list(PARTICLE_FRICTION)
            geom.solref = list(PARTICLE_SOLREF)
            geom.solimp = list(PARTICLE_SOLIMP)
        return spec

    def _particle_ids(self) -> np.ndarray:
        model = self.physics.model
        return np.array([model.body(f"particle_{i}").id for i in range(N_PARTICLES)])

    def place(self, rng: np.random.Generator) -> None:
        model, data = self.physics.model, self.physics.data
        cup = (
            CUP_XY[0] + rng.uniform(-JITTER, JITTER),
            CUP_XY[1] + rng.uniform(-JITTER, JITTER),
            0.0,
        )
        set_free_pose(model, data, "cup", cup, 0.0)
        for i, local in enumerate(particle_layout(rng)):
            set_free_pose(model, data, f"particle_{i}", np.add(cup, local), 0.0)

    def state(self) -> PourState:
        data = self.physics.data
        cup = self.physics.model.body("cup").id
        cup_pos = data.xpos[cup].copy()
        rotation = data.xmat[cup].reshape(3, 3)
        points = data.xpos[self._particle_ids()]
        local = (points - cup_pos) @ rotation  # into the cup's frame
        in_cup = (np.hypot(local[:, 0], local[:, 1]) <= CUP_RADIUS) & (
            (local[:, 2] >= 0.0) & (local[:, 2] <= CUP_BOTTOM + CUP_HEIGHT + 3 * PARTICLE_RADIUS)
        )
        offset = points[:, :2] - np.array(CONTAINER_XY)
        inside = np.all(np.abs(offset) <= CONTAINER_HALF, axis=1)
        delivered = ~in_cup & inside & (points[:, 2] <= CONTAINER_HEIGHT + PARTICLE_RADIUS)
        spilled = ~in_cup & ~delivered & (points[:, 2] < CONTAINER_HEIGHT)
        tilt = float(np.degrees(np.arccos(np.clip(rotation[2, 2], -1.0, 1.0))))
        return PourState(
            in_cup=int(in_cup.sum()),
            delivered=int(delivered.sum()),
            spilled=int(spilled.sum()),
            airborne=int(N_PARTICLES - in_cup.sum() - delivered.sum() - spilled.sum()),
            total=N_PARTICLES,
            cup_position=cup_pos,
            cup_tilt=tilt,
        )

    def succeeded(self) -> bool:
        state = self.state()
        return (
            state.spilled == 0
            and state.airborne == 0
            and state.in_cup <= LEFT_FRACTION * state.total
        )

    def failed(self) -> bool:
        state = self.state()
        return state.spilled > 0 or state.cup_position[2] < OFF_TABLE_Z
