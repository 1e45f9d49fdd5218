"""The behaviour of a Techman controller running a Listen Node, without sockets.

:class:`FakeController` answers packets as Techman's public material describes the
controller (docs/techman.md lists the sources and what is assumed): ``CPERR`` for a
packet that is malformed (``01``), has a wrong checksum (``02``), an unknown header
(``03``) or unreadable data (``04``), and ``F1`` for scripts while the flow is not in the
Listen Node; ``ID,OK`` / ``ID,ERROR;line`` for scripts; ``TMSTA`` answers (``00,true,NAME``
and ``01,TT,true|false|none``); the enter-node message ``0,NAME``.

Velocity mode follows ``ContinueVLine(timeout_zero_vel, timeout_stop)`` (ms): with no
``SetContinueVLine`` for ``timeout_zero_vel`` the target velocity drops to zero, after
``timeout_stop`` the mode ends and later ``SetContinueVLine`` lines are refused. Without
the velocity-mode licence both functions are refused. Motion is a TCP whose velocity
ramps towards the target at a bounded acceleration, integrated in the base frame (mm,
deg); given a kinematic model (``forward_kinematics``/``jacobian``, radians) the joints
move instead and the TCP follows from them, so joints and TCP agree.

Every packet the client should never send is recorded in :attr:`violations`, every
``ERROR`` answer in :attr:`script_errors`, every ``SetContinueVLine`` in
:attr:`velocity_commands`, and every way velocity mode ended in :attr:`velocity_mode_exits`.
Time comes from ``clock``; :meth:`advance` moves the simulation to the clock's time, so a
test can drive it step by step. :mod:`.fake_scripts` reads the script lines;
:mod:`.fake_server` puts the controller behind two TCP servers.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from wovenskin.robots.techman.ethernet_slave import SvrMode, state_packet
from wovenskin.robots.techman.fake_scripts import CALL, ScriptError, numbers, parse_args
from wovenskin.robots.techman.protocol import (
    CommError,
    NodeEntered,
    Packet,
    PacketError,
    ScriptReply,
)

_ROTATION_SPEED_DEG_S = 45.0  # how fast a Line move turns the tool when it barely travels
_MAX_RECORDED = 200_000  # velocity commands kept for inspection


@dataclass(frozen=True)
class ReceivedPacket:
    """One packet the Listen Node got: the packet, or the error that made it a violation."""

    packet: Packet | None
    error: str | None = None


@dataclass
class _Move:
    kind: str  # "joints" or "line"
    start: np.ndarray
    target: np.ndarray
    duration: float
    elapsed: float = 0.0


def _ramp(current: np.ndarray, target: np.ndarray, max_step: float) -> np.ndarray:
    delta = target - current
    size = float(np.linalg.norm(delta))
    return target.copy() if size <= max_step else current + delta * (max_step / size)


class FakeController:
    """A Techman controller with its flow in a Listen Node, driven by :meth:`handle`."""

    def __init__(
        self,
        q0_deg: np.ndarray | None = None,
        tcp0: np.ndarray | None = None,
        fk: Callable[[np.ndarray], np.ndarray] | None = None,
        *,
        forward_kinematics: Callable[[np.ndarray], np.ndarray] | None = None,
        jacobian: Callable[[np.ndarray], np.ndarray] | None = None,
        joint_speed_deg_s: float = 180.0,
        linear_accel_mm_s2: float = 2000.0,
        angular_accel_deg_s2: float = 720.0,
        node_name: str = "Listen1",
        velocity_licence: bool = True,
        state_mode: SvrMode = SvrMode.BINARY,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.q_deg = np.zeros(6) if q0_deg is None else np.asarray(q0_deg, dtype=float).copy()
        self.fk = fk  # joint degrees -> TCP wire pose (mm, deg), for joint moves only
        self.forward_kinematics = forward_kinematics  # q rad -> 4x4 (m)
        self.jacobian = jacobian  # q rad -> 6x6, [v (m/s); w (rad/s)] = J dq
        if (forward_kinematics is None) != (jacobian is None):
            raise ValueError("give both forward_kinematics and jacobian, or neither")
        start_tcp = [400.0, 0.0, 400.0, 180.0, 0.0, 90.0] if tcp0 is None else tcp0
        self.position_mm = np.asarray(start_tcp[:3], dtype=float).copy()
        self.rotation = Rotation.from_euler("xyz", start_tcp[3:], degrees=True)
        if forward_kinematics is not None:
            self._tcp_from_joints()
        self.joint_speed_deg_s = joint_speed_deg_s
        self.linear_accel_mm_s2 = linear_accel_mm_s2
        self.angular_accel_deg_s2 = angular_accel_deg_s2
        self.node_name = node_name
        self.velocity_licence = velocity_licence
        self.state_mode = state_mode
        self.clock = clock
        # what the controller is doing
        self.in_listen_node = True
        self.velocity_mode = False
        self.timeouts_ms: tuple[float, float] | None = None  # (zero velocity, stop)
        self.command_velocity = np.zeros(6)  # target: mm/s, deg/s, base frame
        self.velocity = np.zeros(6)  # actual TCP velocity, ramped towards the target
        self.joint_velocity_deg_s = np.zeros(6)
        self.error_code = 0
        self.estop = False
        # what was seen, for tests
        self.received: list[ReceivedPacket] = []
        self.violations: list[str] = []
        self.script_errors: list[str] = []
        self.scripts: list[str] = []  # every accepted script line, in order
        self.velocity_commands: list[tuple[float, np.ndarray]] = []
        self.max_linear_command_mm_s = 0.0
        self.max_angular_command_deg_s = 0.0
        self.velocity_mode_entries = 0
        self.velocity_mode_exits: list[tuple[float, str]] = []
        self.zero_velocity_timeouts = 0
        self.not_in_node_packets = 0
        self._last_command_t = 0.0
        self._zeroed_by_timeout = False
        self._moves: list[_Move] = []
        self._moves_done = 0
        self._moves_queued = 0
        self._tags: dict[int, int] = {}
        self._t = clock()
        self._frame_counter = 0
        self._lock = threading.RLock()

    # -- what tests read --------------------------------------------------------------

    @property
    def protocol_violations(self) -> int:
        """How many packets broke the protocol (each is in :attr:`violations`)."""
        return len(self.violations)

    @property
    def measured_velocity(self) -> np.ndarray:
        """The TCP velocity the state frames report (mm/s, deg/s)."""
        return self.velocity.copy()

    def tcp_wire(self) -> np.ndarray:
        """The TCP as ``[X, Y, Z, RX, RY, RZ]`` (mm, deg)."""
        with self._lock:
            angles = self.rotation.as_euler("xyz", degrees=True)
            return np.concatenate([self.position_mm, angles])

    def state_items(self) -> dict[str, object]:
        """The Ethernet Slave data table (the items Techman's drivers use, subset)."""
        with self._lock:
            return {
                "Robot_Link": True,
                "Robot_Error": self.error_code != 0,
                "Project_Run": True,
                "Project_Pause": False,
                "ESTOP": self.estop,
                "Error_Code": self.error_code,
                "Joint_Angle": self.q_deg.tolist(),
                "Coord_Robot_Tool": self.tcp_wire().tolist(),
                "TCP_Speed": self.velocity.tolist(),
                "TCP_Speed3D": float(np.linalg.norm(self.velocity[:3])),
                "Joint_Speed": self.joint_velocity_deg_s.tolist(),
            }

    def state_frame(self) -> Packet:
        """The next pushed ``TMSVR`` frame, in :attr:`state_mode`."""
        with self._lock:
            self._frame_counter += 1
            items = self.state_items()
            # a text item the client has no use for, which it must skip
            items["Error_Content"] = b"" if self.state_mode is SvrMode.BINARY else ""
            return state_packet(str(self._frame_counter % 100000), items, self.state_mode)

    def tag_status(self, tag: int) -> str:
        """``true`` when the moves queued before ``tag`` are done, ``false``, or ``none``."""
        with self._lock:
            if tag not in self._tags:
                return "none"
            return "true" if self._moves_done >= self._tags[tag] else "false"

    # -- the flow and faults ----------------------------------------------------------

    def enter_message(self) -> Packet:
        """The message the flow sends when it enters the Listen Node: ``0,NAME``."""
        return NodeEntered(self.node_name).to_packet()

    def enter_listen_node(self) -> Packet:
        """The flow (re-)enters the Listen Node; returns the message to send to clients."""
        with self._lock:
            self._end_velocity_mode("flow re-entered the Listen Node")
            self.in_listen_node = True
            return self.enter_message()

    def leave_listen_node(self) -> None:
        """The flow leaves the Listen Node: scripts are answered ``CPERR F1`` until it is back."""
        with self._lock:
            self._end_velocity_mode("flow left the Listen Node")
            self.in_listen_node = False

    def inject_fault(self, code: int) -> None:
        """Raise a robot error: motion stops at once, velocity mode ends, state reports it."""
        with self._lock:
            self.error_code = int(code)
            self._halt()
            self.velocity[:] = 0.0
            self.joint_velocity_deg_s[:] = 0.0
            self._end_velocity_mode(f"robot error {code}")

    def clear_fault(self) -> None:
        """Clear the robot error."""
        with self._lock:
            self.error_code = 0

    # -- packets ----------------------------------------------------------------------

    def handle(self, item: Packet | PacketError) -> list[Packet]:
        """Answer one packet (or framing error) from a Listen Node client."""
        with self._lock:
            self.advance()
            if isinstance(item, PacketError):
                self.received.append(ReceivedPacket(None, str(item)))
                self.violations.append(str(item))
                return [Packet("CPERR", item.code.value)]
            self.received.append(ReceivedPacket(item))
            try:
                data = item.data
            except PacketError as exc:
                return [self._violation(str(exc), CommError.PACKET_DATA)]
            if item.header == "TMSCT":
                return [self._handle_script(data)]
            if item.header == "TMSTA":
                return [self._handle_status(data)]
            return [
                self._violation(f"{item.header} packet sent to the Listen Node", CommError.HEADER)
            ]

    def _violation(self, message: str, code: CommError) -> Packet:
        self.violations.append(message)
        return Packet("CPERR", code.value)

    def _handle_status(self, data: str) -> Packet:
        subcommand, *args = data.split(",")
        if subcommand == "00" and not args:
            name = self.node_name if self.in_listen_node else ""
            return Packet("TMSTA", f"00,{'true' if self.in_listen_node else 'false'},{name}")
        if subcommand == "01" and len(args) == 1 and args[0].isdigit():
            tag = int(args[0])
            return Packet("TMSTA", f"01,{tag:02d},{self.tag_status(tag)}")
        return self._violation(f"bad TMSTA data {data!r}", CommError.PACKET_DATA)

    def _handle_script(self, data: str) -> Packet:
        script_id, sep, script = data.partition(",")
        if not sep or not script_id or not script.strip():
            return self._violation(
                f"TMSCT data {data[:40]!r} lacks ID,SCRIPT", CommError.PACKET_DATA
            )
        if not self.in_listen_node:
            self.not_in_node_packets += 1
            return Packet("CPERR", CommError.NOT_IN_LISTEN_NODE.value)
        lines = script.split("\r\n")
        actions: list[Callable[[], None]] = []
        bad: list[int] = []
        velocity_mode = self.velocity_mode  # scripts run in order: track mode changes
        for number, line in enumerate(lines, start=1):
            try:
                action, velocity_mode = self._compile(line.strip(), velocity_mode)
                actions.append(action)
            except ScriptError as exc:
                bad.append(number)
                self.script_errors.append(f"script {script_id} line {number}: {exc}")
        if bad:
            return ScriptReply(script_id, False, tuple(bad)).to_packet()
        for action in actions:
            action()
        self.scripts.extend(line.strip() for line in lines)
        return ScriptReply(script_id, True).to_packet()

    # -- script semantics -------------------------------------------------------------

    def _compile(self, line: str, velocity_mode: bool) -> tuple[Callable[[], None], bool]:
        match = CALL.match(line)
        if match is None:
            raise ScriptError(f"not a function call: {line[:40]!r}")
        name, args = match.group(1), parse_args(match.group(2))
        if name in ("ContinueVLine", "SetContinueVLine"):
            if not self.velocity_licence:
                raise ScriptError(f"{name} needs the velocity-mode licence")
            if self.error_code != 0:
                raise ScriptError(f"{name} refused during robot error {self.error_code}")
        if name == "ContinueVLine":
            zero_ms, stop_ms = numbers(args, 2, name)
            if not (zero_ms == int(zero_ms) > 0 and stop_ms == int(stop_ms) > 0):
                raise ScriptError("ContinueVLine timeouts must be positive whole milliseconds")
            return lambda: self._enter_velocity_mode(zero_ms, stop_ms), True
        if name == "SetContinueVLine":
            velocity = numbers(args, 6, name)
            if not velocity_mode:
                raise ScriptError("SetContinueVLine outside velocity mode")
            return lambda: self._set_velocity(velocity), True
        if name == "StopContinueVmode":
            numbers(args, 0, name)
            return lambda: self._end_velocity_mode("StopContinueVmode"), False
        if name == "StopAndClearBuffer" and len(args) <= 1:
            return self._halt, velocity_mode
        if name in ("PTP", "Line"):
            return self._compile_move(name, args, velocity_mode), velocity_mode
        if name == "QueueTag":
            if len(args) not in (1, 2):
                raise ScriptError("QueueTag takes a tag and an optional wait flag")
            (tag,) = numbers(args[:1], 1, name)
            if tag != int(tag) or not 1 <= tag <= 15:
                raise ScriptError("QueueTag's tag is 1-15")
            return lambda: self._tag(int(tag)), velocity_mode
        if name == "ScriptExit":
            numbers(args, 0, name)
            return self.leave_listen_node, False
        raise ScriptError(f"unknown function {name}")

    def _compile_move(
        self, name: str, args: list[object], velocity_mode: bool
    ) -> Callable[[], None]:
        expected_format = "JPP" if name == "PTP" else "CAP"
        if len(args) != 11 or args[0] != expected_format or not isinstance(args[10], bool):
            raise ScriptError(f"bad {name} arguments")
        values = numbers(args[1:10], 9, name)
        if velocity_mode:
            raise ScriptError(f"{name} refused in velocity mode")
        if self.error_code != 0 or not values[6] > 0:
            raise ScriptError(f"{name} refused")
        if name == "PTP" and values[6] > 100:
            raise ScriptError("PTP speed above 100%")
        return lambda: self._queue_move(name, values)

    def _enter_velocity_mode(self, zero_ms: float, stop_ms: float) -> None:
        self.velocity_mode_entries += 1
        self.velocity_mode = True
        self.timeouts_ms = (zero_ms, stop_ms)
        self.command_velocity = np.zeros(6)
        self._last_command_t = self._t
        self._zeroed_by_timeout = False

    def _set_velocity(self, velocity: np.ndarray) -> None:
        self.command_velocity = velocity.copy()
        self._last_command_t = self._t
        self._zeroed_by_timeout = False
        if len(self.velocity_commands) < _MAX_RECORDED:
            self.velocity_commands.append((self._t, velocity.copy()))
        self.max_linear_command_mm_s = max(
            self.max_linear_command_mm_s, float(np.linalg.norm(velocity[:3]))
        )
        self.max_angular_command_deg_s = max(
            self.max_angular_command_deg_s, float(np.linalg.norm(velocity[3:]))
        )

    def _end_velocity_mode(self, reason: str, at: float | None = None) -> None:
        if self.velocity_mode:
            self.velocity_mode = False
            self.velocity_mode_exits.append((self._t if at is None else at, reason))
        self.command_velocity = np.zeros(6)

    def _halt(self) -> None:
        self.command_velocity = np.zeros(6)
        self._moves.clear()
        self._moves_done = self._moves_queued

    def _tag(self, tag: int) -> None:
        self._tags[tag] = self._moves_queued

    def _queue_move(self, name: str, values: np.ndarray) -> None:
        speed = values[6]
        if name == "PTP":
            target = values[:6]
            rate = self.joint_speed_deg_s * speed / 100.0
            duration = float(np.max(np.abs(target - self.q_deg))) / rate
            self._moves.append(_Move("joints", np.empty(6), target, duration))
        else:
            distance = float(np.linalg.norm(values[:3] - self.position_mm))
            self._moves.append(_Move("line", np.empty(6), values[:6], distance / speed))
        self._moves_queued += 1

    # -- simulation -------------------------------------------------------------------

    def advance(self, now: float | None = None) -> None:
        """Run timeouts and motion up to ``now`` (default: the clock's time)."""
        with self._lock:
            now = self.clock() if now is None else now
            dt = now - self._t
            if dt <= 0.0:
                return
            self._check_timeouts(now)
            self._t = now
            self._step(min(dt, 0.1))

    def _check_timeouts(self, now: float) -> None:
        if not self.velocity_mode or self.timeouts_ms is None:
            return
        zero_ms, stop_ms = self.timeouts_ms
        idle_ms = (now - self._last_command_t) * 1000.0
        if idle_ms > zero_ms and not self._zeroed_by_timeout:
            self._zeroed_by_timeout = True
            if np.any(self.command_velocity != 0.0):
                self.zero_velocity_timeouts += 1
            self.command_velocity = np.zeros(6)
        if idle_ms > stop_ms:
            at = self._last_command_t + stop_ms / 1000.0
            self._end_velocity_mode(f"timeout_stop ({stop_ms:g} ms without a command)", at)

    def _step(self, dt: float) -> None:
        if self.error_code != 0:
            return
        target = self.command_velocity if self.velocity_mode else np.zeros(6)
        previous = self.velocity.copy()
        self.velocity[:3] = _ramp(previous[:3], target[:3], self.linear_accel_mm_s2 * dt)
        self.velocity[3:] = _ramp(previous[3:], target[3:], self.angular_accel_deg_s2 * dt)
        if np.any(previous != 0.0) or np.any(self.velocity != 0.0):
            self._move_tcp((previous + self.velocity) / 2.0, dt)
            return
        self.joint_velocity_deg_s[:] = 0.0
        if self._moves:
            self._step_move(dt)

    def _move_tcp(self, velocity: np.ndarray, dt: float) -> None:
        if self.jacobian is None:
            self.position_mm = self.position_mm + velocity[:3] * dt
            turn = Rotation.from_rotvec(np.deg2rad(velocity[3:]) * dt)
            self.rotation = turn * self.rotation
            return
        q = np.deg2rad(self.q_deg)
        jac = np.asarray(self.jacobian(q), dtype=float)
        twist = np.concatenate([velocity[:3] / 1000.0, np.deg2rad(velocity[3:])])
        damping = 1e-4 * np.eye(6)
        dq = jac.T @ np.linalg.solve(jac @ jac.T + damping, twist)
        limit = np.deg2rad(self.joint_speed_deg_s)
        peak = float(np.max(np.abs(dq)))
        if peak > limit:
            dq *= limit / peak
        self.joint_velocity_deg_s = np.rad2deg(dq)
        self.q_deg = self.q_deg + self.joint_velocity_deg_s * dt
        achieved = jac @ dq
        self.velocity = np.concatenate([achieved[:3] * 1000.0, np.rad2deg(achieved[3:])])
        self._tcp_from_joints()

    def _tcp_from_joints(self) -> None:
        assert self.forward_kinematics is not None
        pose = np.asarray(self.forward_kinematics(np.deg2rad(self.q_deg)), dtype=float)
        self.position_mm = pose[:3, 3] * 1000.0
        self.rotation = Rotation.from_matrix(pose[:3, :3])

    def _step_move(self, dt: float) -> None:
        move = self._moves[0]
        if move.elapsed == 0.0:
            move.start = self.q_deg.copy() if move.kind == "joints" else self.tcp_wire()
            if move.kind == "line":
                start_rot = Rotation.from_euler("xyz", move.start[3:], degrees=True)
                goal_rot = Rotation.from_euler("xyz", move.target[3:], degrees=True)
                angle = np.rad2deg((goal_rot * start_rot.inv()).magnitude())
                move.duration = max(move.duration, angle / _ROTATION_SPEED_DEG_S)
        move.elapsed += dt
        fraction = 1.0 if move.duration <= 0 else min(1.0, move.elapsed / move.duration)
        if move.kind == "joints":
            self.q_deg = move.start + fraction * (move.target - move.start)
            if self.forward_kinematics is not None:
                self._tcp_from_joints()
            elif self.fk is not None:
                wire = np.asarray(self.fk(self.q_deg), dtype=float)
                self.position_mm = wire[:3].copy()
                self.rotation = Rotation.from_euler("xyz", wire[3:], degrees=True)
        else:
            self._set_tcp_between(move.start, move.target, fraction)
        if fraction >= 1.0:
            self._moves.pop(0)
            self._moves_done += 1

    def _set_tcp_between(self, start: np.ndarray, target: np.ndarray, fraction: float) -> None:
        self.position_mm = start[:3] + fraction * (target[:3] - start[:3])
        start_rot = Rotation.from_euler("xyz", start[3:], degrees=True)
        goal_rot = Rotation.from_euler("xyz", target[3:], degrees=True)
        delta = (goal_rot * start_rot.inv()).as_rotvec()
        self.rotation = Rotation.from_rotvec(delta * fraction) * start_rot
