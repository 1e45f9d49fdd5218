"""Pick-and-place: scene, seating rules, seeded resets, and a scripted grasp with the arm."""

import json
import math

import numpy as np
import pytest

from wovenskin.robots.base import Pose
from wovenskin.tasks.pick_place import XY_TOL, PickPlaceTask, yaw_error
from wovenskin.tasks.scene import set_free_pose


@pytest.fixture(scope="module")
def task():
    return PickPlaceTask()


def _settle(task, seconds=0.5):
    q = task.physics.data.qpos[task.physics.arm_qpos].copy()
    task.physics.advance(q, q, seconds)


def test_reset_places_objects_on_the_table_without_nan(task):
    task.reset(0)
    _settle(task)
    assert np.all(np.isfinite(task.physics.data.qpos))
    state = task.state()
    assert state.total == 3 and state.seated == 0
    for obj in state.objects:
        assert obj.position[1] > 0.15 and obj.tilt < 1.0
    assert not task.succeeded() and not task.failed()
    json.dumps(task.to_dict())


def test_reset_is_deterministic_per_seed(task):
    task.reset(5)
    first = task.physics.data.qpos.copy()
    task.reset(6)
    other = task.physics.data.qpos.copy()
    task.reset(5)
    np.testing.assert_array_equal(task.physics.data.qpos, first)
    assert not np.array_equal(first, other)


def test_reset_refuses_a_bad_seed(task):
    with pytest.raises(ValueError):
        task.reset(-1)


def test_dropped_in_its_mold_is_seated_beside_it_is_not(task):
    task.reset(1)
    model, data = task.physics.model, task.physics.data
    cube = task.mold_position("cube")
    set_free_pose(model, data, "cube", (cube[0], cube[1], 0.06), math.pi / 2 + 0.03)
    prism = task.mold_position("prism")
    set_free_pose(model, data, "prism", (prism[0], prism[1], 0.07), 2 * math.pi / 3)
    cylinder = task.mold_position("cylinder")
    set_free_pose(model, data, "cylinder", (cylinder[0] + 0.06, cylinder[1], 0.06), 0.0)
    _settle(task, 1.0)
    seated = {o.name: o.seated for o in task.state().objects}
    assert seated == {"cube": True, "prism": True, "cylinder": False}
    assert not task.succeeded()
    set_free_pose(model, data, "cylinder", (cylinder[0], cylinder[1], 0.06), 0.0)
    _settle(task, 1.0)
    assert task.succeeded()


def test_turned_prism_does_not_fit(task):
    task.reset(2)
    prism = task.mold_position("prism")
    set_free_pose(
        task.physics.model, task.physics.data, "prism", (prism[0], prism[1], 0.07), math.pi / 3
    )
    _settle(task, 1.0)
    state = {o.name: o for o in task.state().objects}["prism"]
    assert not state.seated and state.offset < 0.05


def test_yaw_error_respects_symmetry():
    assert yaw_error(math.pi / 2 + 0.1, 0.0, math.pi / 2) == pytest.approx(0.1)
    assert yaw_error(-0.1, 0.0, 2 * math.pi / 3) == pytest.approx(0.1)
    assert yaw_error(1.0, 0.0, None) == 0.0


def test_object_off_the_table_fails(task):
    task.reset(3)
    set_free_pose(task.physics.model, task.physics.data, "cube", (1.3, 0.0, -0.5), 0.0)
    _settle(task, 0.01)
    assert task.failed()


def test_gripper_closes_on_the_cube_and_lifts_it_into_its_mold():
    task = PickPlaceTask()
    task.reset(3)
    robot = task.robot()
    robot.connect()
    quat = robot.state().tcp.quat
    body = task.physics.model.body("cube").id

    def go(x, y, z, speed=0.2):
        robot.move_to_pose(Pose(np.array([x, y, z]), quat), speed)
        while robot.state().moving:
            robot.step(0.02)

    start = task.physics.data.xpos[body].copy()
    go(start[0], start[1], 0.12)
    go(start[0], start[1], 0.015, 0.1)
    robot.set_gripper(True)
    robot.step(0.5)
    assert robot.state().gripper.width == pytest.approx(0.04, abs=0.004)
    go(start[0], start[1], 0.2, 0.1)
    cube = task.physics.data.xpos[body]
    tcp = robot.state().tcp.position
    assert cube[2] > 0.18 and abs(cube[2] - tcp[2] - (start[2] - 0.015)) < 0.005
    mold = task.mold_position("cube")
    go(mold[0], mold[1], 0.2)
    go(mold[0], mold[1], 0.06, 0.1)
    robot.set_gripper(False)
    robot.step(0.5)
    go(mold[0], mold[1], 0.2)
    cube_state = task.state().objects[0]
    assert cube_state.seated and cube_state.offset < XY_TOL
