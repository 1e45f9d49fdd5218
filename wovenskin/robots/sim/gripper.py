"""The simulated TM5-900 with a parallel gripper, as a MuJoCo spec for physics task scenes.

:func:`arm_with_gripper` loads the kinematic arm (``tm5_900.xml``) into a ``mujoco.MjSpec``
and turns it into a physics model: gravity on, the two fingers on slide joints driven by
force-limited position actuators, the fingers and the gripper housing in contact (the
fingertips with torsional friction, ``condim`` 4), the arm links gravity-compensated and
heavy in their joints (armature) so that contacts barely move them within a physics step;
:class:`~wovenskin.robots.sim.physics.ArmPhysics` then prescribes their joint positions and
velocities every step. The gripper follows the layout of common two-finger electric
grippers (e.g. a Robotiq 2F-85: 85 mm stroke, 20-235 N): 80 mm stroke, 15 N per finger.
Task scenes (``wovenskin.tasks``) add tables and objects to the returned spec.
"""

from __future__ import annotations

from importlib import resources

import mujoco

from wovenskin.robots.sim.tm5_900 import JOINT_NAMES, MODEL_FILE

FINGER_JOINTS = ("finger_left", "finger_right")  # slide joints; the actuators share the names
FINGER_TRAVEL = 0.04  # m per finger: the opening between the inner faces is 0 .. 80 mm
FINGER_FORCE = 15.0  # N, each finger's force limit (the grip force on a held object)
FINGER_GAIN = 1500.0  # N/m, the position actuators' stiffness
FINGER_DAMPING = 6.0  # N s/m, on each finger joint
ARM_ARMATURE = 50.0  # kg m^2 on each arm joint: contacts hardly move the prescribed arm
TIMESTEP = 0.002  # s
CONTACT_BITS = 1  # contype/conaffinity of everything that touches in a task scene
FINGER_FRICTION = (1.2, 0.01, 0.0001)  # sliding, torsional, rolling
# Fingertip contacts are stiffer than MuJoCo's default (0.02 s, which lets a 15 N grip sink
# 4 mm into a 40 g cube): time constant 2 physics steps, impedance up to 0.99.
FINGER_SOLREF = (2 * TIMESTEP, 1.0)
FINGER_SOLIMP = (0.95, 0.99, 0.001, 0.5, 2.0)
_HALF_THICKNESS = 0.006  # a finger is 12 mm thick along the closing axis


def arm_with_gripper() -> mujoco.MjSpec:
    """The TM5-900 with a contact gripper, gravity on, as a spec to add a scene to."""
    path = resources.files("wovenskin.robots.sim").joinpath(MODEL_FILE)
    with resources.as_file(path) as file:
        spec = mujoco.MjSpec.from_file(str(file))
    spec.modelname = "tm5_900_gripper"
    spec.option.gravity = [0.0, 0.0, -9.81]
    spec.option.timestep = TIMESTEP
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.option.cone = mujoco.mjtCone.mjCONE_ELLIPTIC
    spec.option.impratio = 5.0
    for name in JOINT_NAMES:
        spec.joint(name).armature = ARM_ARMATURE
    for body in ("base", "link1", "link2", "link3", "link4", "link5", "link6", "flange"):
        spec.body(body).gravcomp = 1.0
    for geom in ("gripper_housing", "end_link"):
        _collide(spec.geom(geom))
    for name, side in zip(FINGER_JOINTS, (1.0, -1.0), strict=True):
        body = spec.body(name)
        body.pos = [0.0, side * _HALF_THICKNESS, 0.105]  # inner face on the axis when shut
        body.add_joint(
            name=name,
            type=mujoco.mjtJoint.mjJNT_SLIDE,
            axis=[0.0, side, 0.0],
            range=[0.0, FINGER_TRAVEL],
            damping=FINGER_DAMPING,
        )
        finger = spec.geom(name)
        _collide(finger)
        finger.condim = 4
        finger.friction = list(FINGER_FRICTION)
        finger.priority = 1  # its contact parameters win over the touched object's
        finger.solref = list(FINGER_SOLREF)
        finger.solimp = list(FINGER_SOLIMP)
        actuator = spec.add_actuator(name=name, target=name, trntype=mujoco.mjtTrn.mjTRN_JOINT)
        actuator.set_to_position(kp=FINGER_GAIN)
        actuator.forcelimited = True
        actuator.forcerange = [-FINGER_FORCE, FINGER_FORCE]
        actuator.ctrlrange = [0.0, FINGER_TRAVEL]
    return spec


def _collide(geom: mujoco.MjsGeom) -> None:
    geom.contype = CONTACT_BITS
    geom.conaffinity = CONTACT_BITS
