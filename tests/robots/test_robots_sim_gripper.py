"""The gripper arm's physics model, ArmPhysics, and the gripper on SimRobot and SafetyLayer."""

import numpy as np
import pytest

from wovenskin.control.safety import SafetyLayer
from wovenskin.robots.base import RobotError
from wovenskin.robots.sim import SimRobot, tm5_900
from wovenskin.robots.sim.gripper import FINGER_JOINTS, FINGER_TRAVEL, arm_with_gripper
from wovenskin.robots.sim.physics import ArmPhysics


@pytest.fixture
def physics():
    return ArmPhysics(arm_with_gripper().compile())


def test_model_has_fingers_with_actuators(physics):
    model = physics.model
    assert physics.has_gripper
    for name in FINGER_JOINTS:
        assert model.actuator(name).forcelimited
        assert model.geom(name).contype == 1 and model.geom(name).condim == 4
    assert model.opt.gravity[2] < 0.0


def test_gripper_opens_and_closes_without_nan(physics):
    q = tm5_900.INITIAL_Q.copy()
    physics.place_arm(q)
    assert physics.gripper_state().width == pytest.approx(2 * FINGER_TRAVEL)
    physics.set_gripper(True)
    physics.advance(q, q, 0.3)
    state = physics.gripper_state()
    assert state.closed and state.width < 0.002
    physics.set_gripper(False)
    physics.advance(q, q, 0.3)
    assert physics.gripper_state().width > 2 * FINGER_TRAVEL - 0.002
    assert np.all(np.isfinite(physics.data.qpos))


def test_arm_follows_the_prescribed_joints(physics):
    q0 = tm5_900.INITIAL_Q.copy()
    q1 = q0 + 0.01
    physics.place_arm(q0)
    physics.advance(q0, q1, 0.02)
    np.testing.assert_allclose(physics.data.qpos[physics.arm_qpos], q1)
    np.testing.assert_allclose(
        physics.tcp_position(), tm5_900.forward_kinematics(q1)[:3, 3], atol=1e-9
    )


def test_physics_needs_the_arm():
    import mujoco

    with pytest.raises(ValueError, match="lacks the arm"):
        ArmPhysics(mujoco.MjModel.from_xml_string("<mujoco><worldbody/></mujoco>"))


def test_sim_robot_with_physics_drives_gripper(physics):
    robot = SimRobot(physics=physics)
    robot.connect()
    assert robot.capabilities().gripper
    robot.set_gripper(True)
    robot.step(0.3)
    state = robot.state()
    assert state.gripper is not None and state.gripper.closed
    assert state.gripper.width < 0.002
    with pytest.raises(RobotError):
        robot.set_gripper("yes")


def test_default_sim_robot_has_no_gripper():
    robot = SimRobot()
    robot.connect()
    assert robot.state().gripper is None
    assert not robot.capabilities().gripper
    with pytest.raises(RobotError, match="no gripper"):
        robot.set_gripper(True)


def test_safety_layer_passes_gripper_and_refuses_it_while_stopped(physics):
    safe = SafetyLayer(SimRobot(physics=physics))
    safe.connect()
    safe.set_gripper(True)
    assert physics.gripper_state().closed
    safe.emergency_stop("test")
    with pytest.raises(RobotError, match="stopped"):
        safe.set_gripper(False)
    assert physics.gripper_state().closed
    safe.clear_stop()
    safe.set_gripper(False)
    assert not physics.gripper_state().closed
    with pytest.raises(ValueError):
        safe.set_gripper(1)


def test_safety_layer_on_an_arm_without_gripper():
    safe = SafetyLayer(SimRobot())
    safe.connect()
    with pytest.raises(RobotError, match="no gripper"):
        safe.set_gripper(True)
