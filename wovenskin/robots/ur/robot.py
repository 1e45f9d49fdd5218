"""URRobot: a Universal Robots arm through ``ur_rtde`` (the optional ``wovenskin[ur]`` extra).

Twists go to ``speedL(twist, acceleration, time)``, joint and pose targets to ``moveJ`` /
``moveL`` with ``asynchronous=True`` (so they return at once; ``getAsyncOperationProgress``
tells when they are over), and ``stop`` ends a speed command with ``speedStop`` and a move
with ``stopL``. ``connect`` arms the RTDE watchdog (``setWatchdog(min_frequency)``); every
``send_twist`` and ``state`` call kicks it, so the robot stops by itself when the control
loop stalls.

The RTDE objects are made by ``control_factory(host)`` / ``receive_factory(host)``; by
default these import ``rtde_control`` / ``rtde_receive`` lazily, so the package is needed
only when a UR arm is really used. Tests pass stand-ins.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from wovenskin.robots.base import (
    JointLimits,
    Kinematics,
    Pose,
    Robot,
    RobotCapabilities,
    RobotError,
    RobotState,
    SceneModel,
    check_pose_move,
    command_twist,
    joint_move_target,
)
from wovenskin.robots.dh import chain_jacobian
from wovenskin.robots.ur import models
from wovenskin.robots.ur.models import ur_model

# UR e-series: every joint turns +-360 deg; base and shoulder of the bigger arms are the
# slowest joints (UR10e: 120 deg/s), so that is the speed limit for all six when the arm's
# model is not given (a named model brings its data sheet's limits, see .models).
MAX_TOOL_LENGTH_M = 0.5  # a measured TCP further from the flange means the wrong model
SERVO_PERIOD_S = 0.002  # the e-series controller's 500 Hz cycle
TRACKING_ERROR = 0.01  # assumed speedL tracking allowance (see URRobot.capabilities)
MAX_POSE_SPEED = 0.25  # m/s, the fastest moveL that move_to_pose sends

UR_JOINT_LIMITS = JointLimits(
    lower=np.full(6, -2 * np.pi),
    upper=np.full(6, 2 * np.pi),
    max_speed=np.full(6, np.deg2rad(120.0)),
)


def _default_control(host: str) -> Any:
    try:
        import rtde_control
    except ImportError:
        raise RobotError("ur_rtde is not installed: install wovenskin[ur]") from None
    return rtde_control.RTDEControlInterface(host)


def _default_receive(host: str) -> Any:
    try:
        import rtde_receive
    except ImportError:
        raise RobotError("ur_rtde is not installed: install wovenskin[ur]") from None
    return rtde_receive.RTDEReceiveInterface(host)


def pose_from_ur(vector: Any) -> Pose:
    """``[x, y, z, rx, ry, rz]`` (metres, axis-angle) as a :class:`Pose`."""
    values = np.asarray(vector, dtype=float)
    if values.shape != (6,):
        raise RobotError(f"UR pose has shape {values.shape}, expected (6,)")
    quat_xyzw = Rotation.from_rotvec(values[3:]).as_quat()
    return Pose(values[:3], quat_xyzw[[3, 0, 1, 2]])


def pose_to_ur(pose: Pose) -> list[float]:
    """A :class:`Pose` as UR's ``[x, y, z, rx, ry, rz]`` (metres, axis-angle)."""
    rotvec = Rotation.from_quat(pose.quat[[1, 2, 3, 0]]).as_rotvec()
    return [*np.asarray(pose.position, dtype=float).tolist(), *rotvec.tolist()]


class URRobot(Robot):
    """A UR arm over RTDE: ``speedL`` for twists, asynchronous ``moveJ``/``moveL`` for moves."""

    name = "ur"

    def __init__(
        self,
        host: str,
        *,
        control_factory: Callable[[str], Any] = _default_control,
        receive_factory: Callable[[str], Any] = _default_receive,
        linear_accel: float = 0.5,
        stop_decel: float = 2.0,
        watchdog_hz: float = 10.0,
        command_time_s: float = 0.0,
        limits: JointLimits | None = None,
        model: str | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        """``model`` (``ur3e``, ``ur5e``, ``ur10e``, ``ur16e``) gives the arm's kinematics,
        declared in :meth:`capabilities`: for the 3D view, for the safety layer (forward
        kinematics and Jacobian of the arm's active TCP, measured on connect from its
        reported joints and TCP pose) and, unless ``limits`` is given, its data sheet's
        joint speeds.  Without it the limits are the conservative :data:`UR_JOINT_LIMITS`,
        the view draws a UR5e, and the safety layer refuses the arm unless the user opts
        into degraded safety."""
        self.host = host
        self.model = ur_model(model) if model is not None else None
        self._tool = np.eye(4)  # flange <- TCP, measured on connect (named model only)
        if limits is None:
            limits = self.model.limits if self.model is not None else UR_JOINT_LIMITS
        self.linear_accel = linear_accel
        self.stop_decel = stop_decel
        self.watchdog_hz = watchdog_hz
        self.command_time_s = command_time_s
        self._limits = limits
        self._clock = clock
        self._control_factory = control_factory
        self._receive_factory = receive_factory
        self._control: Any = None
        self._receive: Any = None
        self._speeding = False  # a speedL command is active
        self._moving_async = False  # an asynchronous moveJ/moveL was started

    # -- connection -------------------------------------------------------------------

    def connect(self) -> None:
        if self._control is not None:
            return
        receive = control = None
        try:
            receive = self._receive_factory(self.host)
            control = self._control_factory(self.host)
            watchdog_ok = control.setWatchdog(self.watchdog_hz)
        except RobotError:
            self._release(control, receive)
            raise
        except Exception as exc:  # ur_rtde raises RuntimeError on an unreachable host
            self._release(control, receive)
            reason = " ".join(str(exc).split())
            raise RobotError(f"cannot connect to the UR arm at {self.host}: {reason}") from None
        if not watchdog_ok:
            self._release(control, receive)
            raise RobotError(f"UR arm at {self.host} refused the RTDE watchdog")
        if self.model is not None:
            try:
                self._tool = self._measured_tool(receive)
            except RobotError:
                self._release(control, receive)
                raise
        self._control, self._receive = control, receive

    def _measured_tool(self, receive: Any) -> np.ndarray:
        """Flange <- TCP of the arm's active TCP, from its reported joints and TCP pose; a
        named model that cannot explain them (the wrong arm) is refused."""
        assert self.model is not None
        q = np.asarray(receive.getActualQ(), dtype=float)
        tcp = pose_from_ur(receive.getActualTCPPose())
        if q.shape != (6,) or not np.all(np.isfinite(q)):
            raise RobotError("UR state has no valid joint angles")
        measured = np.eye(4)
        measured[:3, :3], measured[:3, 3] = tcp.rotation(), tcp.position
        tool = np.linalg.inv(self.model.flange_pose(q)) @ measured
        length = float(np.linalg.norm(tool[:3, 3]))
        if length > MAX_TOOL_LENGTH_M:
            raise RobotError(
                f"the UR arm at {self.host} does not move like a {self.model.name}: its TCP "
                f"would be {length:.2f} m from the flange; check the model in the robot spec"
            )
        return tool

    def capabilities(self) -> RobotCapabilities:
        """The named model's kinematics and drawing (a UR5e drawing, with a caveat, when
        none is named), and how ``speedStop`` stops: at ``stop_decel`` (m/s^2, and the
        same number in rad/s^2 for rotation). The e-series controller updates joint
        velocities every :data:`SERVO_PERIOD_S`; :data:`TRACKING_ERROR` is an assumed
        allowance for ``speedL``'s tracking (not measured: no UR arm was at hand)."""
        kinematics = None
        if self.model is not None:
            kinematics = Kinematics(self._forward_kinematics, self._jacobian)
        drawn = self.model or models.ur_model(models.DEFAULT_DISPLAY_MODEL)
        caveat = ""
        if self.model is None:
            name = "UR" + drawn.name[2:]  # ur5e -> UR5e, as Universal Robots writes it
            caveat = f"UR model not given (ur:HOST?model=ur10e, say): the view draws a {name}"
        scene = SceneModel(
            drawn.mujoco_model, models.SKIN_SITE, models.SKIN_UP_AXIS, models.SKIN_RIGHT_AXIS,
            caveat,
        )  # fmt: skip
        return RobotCapabilities(
            kinematics=kinematics,
            scene=scene,
            stop_deceleration=(self.stop_decel, self.stop_decel),
            control_period_s=SERVO_PERIOD_S,
            tracking_error=TRACKING_ERROR,
            how_to_complete="name the arm's model in the robot spec (ur:HOST?model=ur5e)",
        )

    def _forward_kinematics(self, q: np.ndarray) -> np.ndarray:
        """Base <- TCP (4x4) of the named model at ``q``, with the arm's active TCP."""
        assert self.model is not None
        return self.model.flange_pose(q) @ self._tool

    def _jacobian(self, q: np.ndarray) -> np.ndarray:
        """The 6x6 base-frame Jacobian of the active TCP of the named model at ``q``."""
        assert self.model is not None
        return chain_jacobian(self.model.dh, q, self._tool)

    @staticmethod
    def _release(control: Any, receive: Any) -> None:
        for interface in (control, receive):
            if interface is not None:
                with contextlib.suppress(Exception):
                    interface.disconnect()

    def disconnect(self) -> None:
        if self._control is None:
            return
        with contextlib.suppress(RobotError):
            self.stop()
        control, receive = self._control, self._receive
        self._control = self._receive = None
        control.stopScript()
        control.disconnect()
        receive.disconnect()

    def _require(self) -> tuple[Any, Any]:
        if self._control is None:
            raise RobotError("UR arm is not connected")
        if not self._control.isConnected():
            raise RobotError(f"lost the RTDE control connection to {self.host}")
        return self._control, self._receive

    def _require_unfaulted(self) -> Any:
        """The RTDE control interface of a connected arm in no stop; else a RobotError."""
        control, _ = self._require()
        fault = self._fault()
        if fault is not None:
            raise RobotError(f"UR arm is in {fault}")
        return control

    def _fault(self) -> str | None:
        receive = self._receive
        if receive.isEmergencyStopped():
            return "emergency stop"
        if receive.isProtectiveStopped():
            return "protective stop"
        return None

    def _check(self, ok: object, what: str) -> None:
        if not ok:
            fault = self._fault()
            reason = f" ({fault})" if fault else ""
            raise RobotError(f"UR arm refused {what}{reason}")

    # -- the Robot interface ----------------------------------------------------------

    def joint_limits(self) -> JointLimits:
        return self._limits

    def state(self) -> RobotState:
        control, receive = self._require()
        control.kickWatchdog()
        q = np.asarray(receive.getActualQ(), dtype=float)
        dq = np.asarray(receive.getActualQd(), dtype=float)
        tcp = pose_from_ur(receive.getActualTCPPose())
        speed = np.asarray(receive.getActualTCPSpeed(), dtype=float)
        if q.shape != (6,) or dq.shape != (6,) or speed.shape != (6,):
            raise RobotError("UR state has the wrong shape")
        if self._moving_async and control.getAsyncOperationProgress() < 0:
            self._moving_async = False
        moving = self._speeding or self._moving_async or float(np.linalg.norm(speed[:3])) > 1e-3
        return RobotState(
            t=self._clock(),
            q=q,
            dq=dq,
            tcp=tcp,
            tcp_twist=speed,  # ur_rtde reports [v, omega] in the base frame
            moving=moving,
            fault=self._fault(),
        )

    def send_twist(self, twist: np.ndarray) -> None:
        command = command_twist(twist)
        control = self._require_unfaulted()
        if self._moving_async:
            control.stopL(self.stop_decel)
            self._moving_async = False
        control.kickWatchdog()
        ok = control.speedL(command.tolist(), self.linear_accel, self.command_time_s)
        self._speeding = bool(np.any(command != 0.0))
        self._check(ok, "speedL")

    def _before_move(self) -> Any:
        control = self._require_unfaulted()
        if self._speeding:
            control.speedStop(self.stop_decel)
            self._speeding = False
        return control

    def move_to_joints(self, q: np.ndarray, speed_fraction: float = 0.2) -> None:
        target = joint_move_target(q, speed_fraction, self._limits)
        control = self._before_move()
        speed = float(np.min(self._limits.max_speed)) * speed_fraction
        ok = control.moveJ(target.tolist(), speed, 1.4, True)
        self._check(ok, "moveJ")
        self._moving_async = True

    def move_to_pose(self, pose: Pose, speed: float = 0.05) -> None:
        check_pose_move(pose, speed, MAX_POSE_SPEED)
        control = self._before_move()
        ok = control.moveL(pose_to_ur(pose), float(speed), self.linear_accel, True)
        self._check(ok, "moveL")
        self._moving_async = True

    def stop(self) -> None:
        if self._control is None or not self._control.isConnected():
            return
        control = self._control
        if self._moving_async:
            control.stopL(self.stop_decel)
            self._moving_async = False
        control.speedStop(self.stop_decel)
        self._speeding = False
