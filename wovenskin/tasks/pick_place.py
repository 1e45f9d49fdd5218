"""Pick-and-place: a cube, a cylinder and a triangular prism to seat in their molds.

The shapes start in a row on the arm's left (+y), the molds stand in a row on its right
(-y). An object is seated when it rests upright in its own mold: its centre within
:data:`XY_TOL` of the pocket's centre (a few mm: the pocket's clearance), its base on the
table, and, for the cube and the prism, its yaw within :data:`YAW_TOL` of the pocket's
modulo the shape's symmetry (90 and 120 degrees). The task succeeds when all are seated and
fails when one falls off the table.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mujoco
import numpy as np

from wovenskin.errors import ConfigError
from wovenskin.tasks.base import Task
from wovenskin.tasks.scene import base_spec, body_yaw_and_tilt, set_free_pose
from wovenskin.tasks.shapes import CLEARANCE, SHAPES, Shape, add_mold

OBJECT_Y = 0.22  # m, the row of shapes
MOLD_Y = -0.22  # m, the row of molds
ROW_X = (0.38, 0.50, 0.62)  # m, along the rows, in the order of SHAPES
JITTER = 0.01  # m, the start positions vary by up to this along x and y
YAW_JITTER = 0.35  # rad, the start yaws vary by up to this
XY_TOL = CLEARANCE + 0.002  # m
Z_TOL = 0.004  # m, base above the table
YAW_TOL = math.radians(8.0)
TILT_TOL = math.radians(8.0)
OFF_TABLE_Z = -0.05  # m: an object below this has fallen off the table


@dataclass(frozen=True)
class ObjectState:
    """One shape against its mold."""

    name: str
    position: np.ndarray  # (3,) m, base frame
    offset: float  # m, horizontal distance from its pocket's centre
    yaw_error: float  # deg, modulo the shape's symmetry (0 for the cylinder)
    tilt: float  # deg, its axis from upright
    seated: bool


@dataclass(frozen=True)
class PickPlaceState:
    """Every shape against its mold, and how many are seated."""

    objects: tuple[ObjectState, ...]
    seated: int
    total: int


def yaw_error(yaw: float, target: float, symmetry: float | None) -> float:
    """Smallest yaw difference (rad) modulo ``symmetry`` (None: any yaw matches)."""
    if symmetry is None:
        return 0.0
    error = (yaw - target) % symmetry
    return min(error, symmetry - error)


class PickPlaceTask(Task):
    """Seat a cube, a cylinder and a triangular prism in their molds."""

    name = "pick_place"

    def __init__(self, objects: tuple[str, ...] | None = None) -> None:
        """``objects``: the names of the shapes to seat (default all three; the paper's
        trial moves one object), each keeping its place in the rows."""
        names = [shape.name for shape in SHAPES]
        chosen = names if objects is None else list(objects)
        unknown = [name for name in chosen if name not in names]
        if unknown or not chosen:
            known = ", ".join(names)
            raise ConfigError(f"pick_place objects must be some of {known}, got {chosen}")
        picked = [i for i, name in enumerate(names) if name in chosen]
        self.shapes: tuple[Shape, ...] = tuple(SHAPES[i] for i in picked)
        self.row_x: tuple[float, ...] = tuple(ROW_X[i] for i in picked)
        super().__init__()

    def build(self) -> mujoco.MjSpec:
        spec = base_spec()
        for shape, x in zip(self.shapes, self.row_x, strict=True):
            shape.add_to(spec, (x, OBJECT_Y, shape.height / 2.0))
            add_mold(spec, shape, (x, MOLD_Y))
        return spec

    def mold_position(self, name: str) -> np.ndarray:
        """Centre of ``name``'s pocket on the table (z = 0)."""
        return self.physics.model.body(f"mold_{name}").pos.copy()

    def place(self, rng: np.random.Generator) -> None:
        for shape, x in zip(self.shapes, self.row_x, strict=True):
            dx, dy = rng.uniform(-JITTER, JITTER, 2)
            yaw = float(rng.uniform(-YAW_JITTER, YAW_JITTER))
            pos = (x + dx, OBJECT_Y + dy, shape.height / 2.0 + 0.001)
            set_free_pose(self.physics.model, self.physics.data, shape.name, pos, yaw)

    def object_state(self, shape: Shape) -> ObjectState:
        data = self.physics.data
        body = self.physics.model.body(shape.name).id
        position = data.xpos[body].copy()
        yaw, tilt = body_yaw_and_tilt(data, body)
        offset = float(np.linalg.norm(position[:2] - self.mold_position(shape.name)[:2]))
        error = yaw_error(yaw, 0.0, shape.symmetry)
        seated = (
            offset <= XY_TOL
            and abs(position[2] - shape.height / 2.0) <= Z_TOL
            and error <= YAW_TOL
            and tilt <= TILT_TOL
        )
        return ObjectState(
            shape.name, position, offset, math.degrees(error), math.degrees(tilt), bool(seated)
        )

    def state(self) -> PickPlaceState:
        objects = tuple(self.object_state(shape) for shape in self.shapes)
        return PickPlaceState(objects, sum(o.seated for o in objects), len(objects))

    def succeeded(self) -> bool:
        state = self.state()
        return state.seated == state.total

    def failed(self) -> bool:
        return any(o.position[2] < OFF_TABLE_Z for o in self.state().objects)
