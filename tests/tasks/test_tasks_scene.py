"""Scene building: the table, walls around a polygon, free bodies and their poses."""

import math

import mujoco
import numpy as np
import pytest

from wovenskin.tasks.scene import (
    base_spec,
    body_yaw_and_tilt,
    free_body,
    regular_walls,
    set_free_pose,
    yaw_quat,
)


def test_yaw_quat_is_unit_about_z():
    q = yaw_quat(math.pi / 2)
    assert np.linalg.norm(q) == pytest.approx(1.0) and q[1] == q[2] == 0.0


def test_walls_enclose_and_a_free_body_rests_inside():
    spec = base_spec()
    ring = spec.worldbody.add_body(name="ring", pos=[0.5, 0.0, 0.0])
    regular_walls(ring, "ring", 6, 0.03, 0.005, 0.02)
    ball = free_body(spec, "ball", (0.5, 0.0, 0.05))
    ball.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.01, 0, 0], contype=1, conaffinity=1)
    model = spec.compile()
    data = mujoco.MjData(model)
    set_free_pose(model, data, "ball", (0.51, 0.0, 0.0101), 0.3)
    data.qvel[model.joint("ball").dofadr[0]] = 0.5  # rolled at the wall along x
    for _ in range(500):
        mujoco.mj_step(model, data)
    position = data.xpos[model.body("ball").id]
    assert np.all(np.isfinite(data.qpos))
    assert abs(position[0] - 0.5) < 0.03 and position[2] == pytest.approx(0.01, abs=0.002)
    yaw, tilt = body_yaw_and_tilt(data, model.body("ring").id)
    assert yaw == pytest.approx(0.0) and tilt == pytest.approx(0.0)
