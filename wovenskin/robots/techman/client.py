"""TechmanRobot: a Techman arm driven through TMflow's Listen Node and read via Ethernet Slave.

Two TCP connections: scripts go to the Listen Node (port 5890) as ``TMSCT`` packets, state
comes from the Ethernet Slave (port 5891), which TMflow must be set to push in JSON mode
with the items ``Joint_Angle``, ``Coord_Robot_Tool``, ``TCP_Speed3D``, ``Robot_Error`` and
``Error_Code``.

Velocity mode: the first twist sends ``ContinueVLine(accel_ms, max_speed)``; each twist
then sends ``SetContinueVLine(vx, vy, vz, wx, wy, wz)`` in mm/s and deg/s (base frame)
without waiting for the answer, so a tick costs no round trip; a rejected or unanswered
script surfaces as a :class:`RobotError` on the next call. A watch thread sends a zero
velocity when no twist arrives for ``command_timeout_s``. ``stop`` sends
``StopContinueVmode()`` and ``StopAndClearBuffer()``. Point-to-point moves are
``PTP("JPP", ...)`` and ``Line("CAP", ...)`` followed by ``QueueTag(n)``; the watch thread
polls the tag (``TMSTA 01``) to know when the move is over.
"""

from __future__ import annotations

import contextlib
import socket
import threading
import time
from collections.abc import Callable

import numpy as np

from wovenskin.robots.base import (
    JointLimits,
    Pose,
    Robot,
    RobotError,
    RobotState,
    finite_vector,
)
from wovenskin.robots.techman.protocol import (
    ETHERNET_SLAVE_PORT,
    LISTEN_NODE_PORT,
    CommError,
    Packet,
    PacketError,
    PacketParser,
    ScriptReply,
    call,
    parse_comm_error,
    parse_script_reply,
    parse_state,
    pose_from_wire,
    pose_to_wire,
    script_packet,
    split_status,
    status_packet,
)

_MOVING_SPEED_MM_S = 1.0  # measured TCP speed above which the arm counts as moving
_TAG_POLL_S = 0.05
_WATCH_PERIOD_S = 0.01


def _one_line(exc: BaseException) -> str:
    text = getattr(exc, "strerror", None) or str(exc) or type(exc).__name__
    return " ".join(str(text).split())


class TechmanRobot(Robot):
    """A Techman arm (TM5-900 by default) over the Listen Node and Ethernet Slave."""

    name = "techman"

    def __init__(
        self,
        host: str,
        port: int = LISTEN_NODE_PORT,
        state_port: int = ETHERNET_SLAVE_PORT,
        *,
        timeout_s: float = 1.0,
        command_timeout_s: float = 0.2,
        accel_time_ms: int = 200,
        max_speed_mm_s: float = 250.0,
        stale_state_s: float = 0.5,
        limits: JointLimits | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.host = host
        self.port = port
        self.state_port = state_port
        self.timeout_s = timeout_s
        self.command_timeout_s = command_timeout_s
        self.accel_time_ms = int(accel_time_ms)
        self.max_speed_mm_s = float(max_speed_mm_s)
        self.stale_state_s = stale_state_s
        self._limits = limits
        self._clock = clock
        self.watchdog_stops = 0  # zero velocities sent because twists stopped arriving
        self.bad_state_frames = 0
        self._cond = threading.Condition()
        self._send_lock = threading.Lock()
        self._closing = threading.Event()
        self._threads: list[threading.Thread] = []
        self._listen: socket.socket | None = None
        self._state_sock: socket.socket | None = None
        self._reset_session()

    def _reset_session(self) -> None:
        self._connected = False
        self._lost: str | None = None
        self._next_id = 0
        self._replies: dict[str, ScriptReply] = {}
        self._in_flight: dict[str, tuple[float, str]] = {}  # id -> (sent at, script name)
        self._failures: list[str] = []
        self._comm_errors = 0
        self._status: dict[str, tuple[int, list[str]]] = {}
        self._state_items: dict[str, object] | None = None
        self._state_t = 0.0
        self._velocity_mode = False
        self._last_twist_t = 0.0
        self._twist_nonzero = False
        self._tag = 0
        self._pending_tag: int | None = None
        self._tag_polled_t = 0.0
        self._tag_done_t = float("-inf")  # moving until a state frame newer than this

    # -- connection -------------------------------------------------------------------

    def connect(self) -> None:
        if self._connected:
            return
        self._reset_session()
        self._closing.clear()
        self._listen = self._open(self.port, "Listen Node")
        try:
            self._state_sock = self._open(self.state_port, "Ethernet Slave")
        except RobotError:
            self._close_sockets()
            raise
        self._connected = True
        for target in (self._read_listen, self._read_state, self._watch):
            thread = threading.Thread(target=target, daemon=True, name=f"techman-{target.__name__}")
            thread.start()
            self._threads.append(thread)
        try:
            args = self._status_request("00")
            if not args or args[0] != "true":
                raise RobotError(f"Techman at {self.host}: the Listen Node is not running")
            with self._cond:
                got_state = self._cond.wait_for(
                    lambda: self._state_items is not None or self._lost is not None,
                    self.timeout_s,
                )
            if not got_state or self._state_items is None:
                raise RobotError(
                    f"no state from the Ethernet Slave at {self.host}:{self.state_port} "
                    f"within {self.timeout_s:g} s (enable JSON data push in TMflow)"
                )
        except RobotError:
            self._shutdown()
            raise

    def _open(self, port: int, what: str) -> socket.socket:
        try:
            sock = socket.create_connection((self.host, port), timeout=self.timeout_s)
        except OSError as exc:
            raise RobotError(
                f"cannot connect to the Techman {what} at {self.host}:{port}: {_one_line(exc)}"
            ) from None
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        sock.settimeout(0.1)
        return sock

    def disconnect(self) -> None:
        if not self._connected:
            return
        if self._lost is None:
            with contextlib.suppress(RobotError):
                self.stop()
        self._shutdown()

    def _shutdown(self) -> None:
        self._closing.set()
        self._close_sockets()
        for thread in self._threads:
            if thread is not threading.current_thread():
                thread.join(timeout=1.0)
        self._threads.clear()
        self._connected = False
        self._velocity_mode = False

    def _close_sockets(self) -> None:
        for sock in (self._listen, self._state_sock):
            if sock is not None:
                with contextlib.suppress(OSError):
                    sock.shutdown(socket.SHUT_RDWR)
                sock.close()
        self._listen = self._state_sock = None

    @property
    def connected(self) -> bool:
        """True between a successful ``connect`` and ``disconnect`` while the link holds."""
        return self._connected and self._lost is None

    # -- reader threads ---------------------------------------------------------------

    def _receive_loop(self, sock: socket.socket, handle: Callable[[Packet], None]) -> None:
        parser = PacketParser()
        while not self._closing.is_set():
            try:
                chunk = sock.recv(65536)
            except TimeoutError:
                continue
            except OSError as exc:
                self._mark_lost(f"connection to the robot failed: {_one_line(exc)}")
                return
            if not chunk:
                self._mark_lost("the robot closed the connection")
                return
            for item in parser.feed(chunk):
                if isinstance(item, PacketError):
                    with self._cond:
                        self._failures.append(f"corrupt packet from the robot: {item}")
                        self._cond.notify_all()
                else:
                    handle(item)

    def _mark_lost(self, reason: str) -> None:
        if self._closing.is_set():
            return
        with self._cond:
            if self._lost is None:
                self._lost = reason
            self._cond.notify_all()

    def _read_listen(self) -> None:
        assert self._listen is not None
        self._receive_loop(self._listen, self._on_listen_packet)

    def _read_state(self) -> None:
        assert self._state_sock is not None
        self._receive_loop(self._state_sock, self._on_state_packet)

    def _on_listen_packet(self, packet: Packet) -> None:
        with self._cond:
            try:
                if packet.header == "TMSCT":
                    reply = parse_script_reply(packet.data)
                    sent = self._in_flight.pop(reply.script_id, None)
                    if sent is not None and not reply.ok:
                        self._failures.append(self._rejection(sent[1], reply))
                    elif sent is None:
                        self._replies[reply.script_id] = reply
                elif packet.header == "TMSTA":
                    subcommand, args = split_status(packet.data)
                    count = self._status.get(subcommand, (0, []))[0]
                    self._status[subcommand] = (count + 1, args)
                    tag_over = args[1:2] in (["true"], ["none"])
                    if subcommand == "01" and args[:1] == [str(self._pending_tag)] and tag_over:
                        self._pending_tag = None
                        self._tag_done_t = self._clock()
                elif packet.header == "CPERR":
                    code = parse_comm_error(packet.data)
                    if code is not CommError.NO_ERROR:
                        self._comm_errors += 1
                        self._failures.append(f"the robot reported a {code.describe()} error")
            except PacketError as exc:
                self._failures.append(f"unexpected answer from the robot: {exc}")
            self._cond.notify_all()

    def _on_state_packet(self, packet: Packet) -> None:
        try:
            items = parse_state(packet.data) if packet.header == "TMSVR" else None
        except PacketError:
            items = None
        with self._cond:
            if items is None:
                self.bad_state_frames += 1
                return
            merged = dict(self._state_items or {})
            merged.update(items)
            self._state_items = merged
            self._state_t = self._clock()
            self._cond.notify_all()

    @staticmethod
    def _rejection(script_name: str, reply: ScriptReply) -> str:
        lines = ",".join(str(n) for n in reply.error_lines) or "?"
        return f"the robot rejected {script_name} (error on script line {lines})"

    # -- sending ----------------------------------------------------------------------

    def _send(self, packet: Packet) -> None:
        sock = self._listen
        if sock is None:
            raise RobotError("Techman robot is not connected")
        try:
            with self._send_lock:
                sock.sendall(packet.encode())
        except OSError as exc:
            self._mark_lost(f"sending to the robot failed: {_one_line(exc)}")
            raise RobotError(f"sending to the Techman robot failed: {_one_line(exc)}") from None

    def _new_id(self) -> str:
        self._next_id += 1
        return str(self._next_id)

    def _script(self, script: str, wait: bool = True) -> None:
        """Send a script; with ``wait`` block for its answer and raise when it is refused."""
        name = script.split("(", 1)[0]
        with self._cond:
            script_id = self._new_id()
            errors_before = self._comm_errors
            if not wait:
                self._in_flight[script_id] = (self._clock(), name)
        self._send(script_packet(script_id, script))
        if not wait:
            return
        with self._cond:
            answered = self._cond.wait_for(
                lambda: (
                    script_id in self._replies
                    or self._comm_errors > errors_before
                    or self._lost is not None
                ),
                self.timeout_s,
            )
            reply = self._replies.pop(script_id, None)
            if reply is None and self._comm_errors > errors_before:
                raise RobotError(f"the robot refused the {name} packet: {self._failures.pop()}")
        if self._lost is not None:
            raise RobotError(f"Techman robot: {self._lost}")
        if not answered or reply is None:
            raise RobotError(f"the robot did not answer {name} within {self.timeout_s:g} s")
        if not reply.ok:
            raise RobotError(self._rejection(name, reply))

    def _status_request(self, subcommand: str, *args: str) -> list[str]:
        with self._cond:
            before = self._status.get(subcommand, (0, []))[0]
        self._send(status_packet(subcommand, *args))
        with self._cond:
            if not self._cond.wait_for(
                lambda: self._status.get(subcommand, (0, []))[0] > before or self._lost is not None,
                self.timeout_s,
            ):
                raise RobotError(f"the robot did not answer status {subcommand} in time")
            if self._lost is not None:
                raise RobotError(f"Techman robot: {self._lost}")
            return self._status[subcommand][1]

    def _require_link(self) -> None:
        if not self._connected:
            raise RobotError("Techman robot is not connected")
        if self._lost is not None:
            raise RobotError(f"Techman robot: {self._lost}")

    def _raise_pending_failure(self) -> None:
        """Raise for a streamed script the robot refused or never answered."""
        with self._cond:
            now = self._clock()
            late = [name for sent, name in self._in_flight.values() if now - sent > self.timeout_s]
            if late:
                self._failures.append(
                    f"the robot did not answer {late[0]} within {self.timeout_s:g} s"
                )
                self._in_flight.clear()
            if not self._failures:
                return
            failure = self._failures[0]
            self._failures.clear()
        with contextlib.suppress(RobotError):
            self.stop()
        raise RobotError(failure)

    def _check_fault(self) -> None:
        fault = self._fault()
        if fault is not None:
            with self._cond:
                self._failures.clear()  # refusals during a fault are explained by it
            raise RobotError(f"Techman robot: {fault}")

    # -- watch thread: command timeout and move tags ----------------------------------

    def _watch(self) -> None:
        while not self._closing.wait(_WATCH_PERIOD_S):
            if self._lost is not None:
                continue
            now = self._clock()
            try:
                if (
                    self._velocity_mode
                    and self._twist_nonzero
                    and now - self._last_twist_t > self.command_timeout_s
                ):
                    self._twist_nonzero = False
                    self.watchdog_stops += 1
                    self._script(call("SetContinueVLine", *([0.0] * 6)), wait=False)
                if self._pending_tag is not None and now - self._tag_polled_t > _TAG_POLL_S:
                    self._tag_polled_t = now
                    self._send(status_packet("01", str(self._pending_tag)))
            except RobotError:
                continue

    # -- the Robot interface ----------------------------------------------------------

    def joint_limits(self) -> JointLimits:
        if self._limits is None:
            from wovenskin.robots.sim.tm5_900 import JOINT_LIMITS

            self._limits = JOINT_LIMITS
        return self._limits

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        """The TM5-900 model's 6x6 base-frame TCP Jacobian (used by the safety layer)."""
        from wovenskin.robots.sim.tm5_900 import jacobian

        return jacobian(q)

    def forward_kinematics(self, q: np.ndarray) -> np.ndarray:
        """The TM5-900 model's TCP pose (4x4, base frame) at ``q``, with the model's gripper."""
        from wovenskin.robots.sim.tm5_900 import forward_kinematics

        return forward_kinematics(q)

    def _fault(self) -> str | None:
        with self._cond:
            items = self._state_items
            age = self._clock() - self._state_t
        if self._lost is not None:
            return self._lost
        if items is None:
            return "no state received from the robot"
        if age > self.stale_state_s:
            return f"no state from the robot for {age:.2f} s"
        if items.get("Robot_Error"):
            return f"robot error code {items.get('Error_Code', '?')}"
        return None

    def state(self) -> RobotState:
        if not self._connected:
            raise RobotError("Techman robot is not connected")
        with self._cond:
            items = dict(self._state_items or {})
            t = self._state_t
        try:
            q = np.deg2rad(np.asarray(items["Joint_Angle"], dtype=float).reshape(6))
            tcp = pose_from_wire(items["Coord_Robot_Tool"])
            speed = np.asarray(items.get("TCP_Speed3D", [0.0] * 6), dtype=float).reshape(6)
        except (KeyError, ValueError, TypeError, PacketError) as exc:
            raise RobotError(f"Techman state frame is incomplete: {_one_line(exc)}") from None
        twist = np.concatenate([speed[:3] / 1000.0, np.deg2rad(speed[3:])])
        commanding = self._velocity_mode and self._twist_nonzero
        moving = (
            commanding
            or self._pending_tag is not None
            or t <= self._tag_done_t
            or float(np.linalg.norm(speed[:3])) > _MOVING_SPEED_MM_S
        )
        return RobotState(
            t=t, q=q, dq=np.zeros(6), tcp=tcp, tcp_twist=twist, moving=moving, fault=self._fault()
        )

    def send_twist(self, twist: np.ndarray) -> None:
        try:
            command = finite_vector(twist, 6, "twist")
        except ValueError as exc:
            raise RobotError(str(exc)) from None
        linear_mm_s = command[:3] * 1000.0
        if float(np.linalg.norm(linear_mm_s)) > self.max_speed_mm_s * (1 + 1e-6):
            raise RobotError(
                f"twist speed {np.linalg.norm(command[:3]):.3f} m/s exceeds "
                f"{self.max_speed_mm_s / 1000.0:.3f} m/s"
            )
        self._require_link()
        self._check_fault()
        self._raise_pending_failure()
        if not self._velocity_mode:
            if self._pending_tag is not None:
                self._script(call("StopAndClearBuffer"))
                self._pending_tag = None
            self._script(call("ContinueVLine", self.accel_time_ms, int(round(self.max_speed_mm_s))))
            self._velocity_mode = True
        values = [*linear_mm_s, *np.rad2deg(command[3:])]
        self._last_twist_t = self._clock()
        self._twist_nonzero = bool(np.any(command != 0.0))
        self._script(call("SetContinueVLine", *values), wait=False)

    def _leave_velocity_mode(self) -> None:
        if self._velocity_mode:
            self._velocity_mode = False
            self._twist_nonzero = False
            self._script(call("StopContinueVmode"))

    def _start_move(self, line: str) -> None:
        self._require_link()
        self._check_fault()
        self._raise_pending_failure()
        self._leave_velocity_mode()
        self._tag = self._tag % 15 + 1
        self._script(f"{line}\r\n{call('QueueTag', self._tag)}")
        self._pending_tag = self._tag
        self._tag_polled_t = self._clock()

    def move_to_joints(self, q: np.ndarray, speed_fraction: float = 0.2) -> None:
        target = np.asarray(q, dtype=float)
        if target.shape != (6,) or not np.all(np.isfinite(target)):
            raise RobotError("joint target must be six finite angles")
        if not (np.isfinite(speed_fraction) and 0.0 < speed_fraction <= 1.0):
            raise RobotError(f"speed fraction {speed_fraction} is not in (0, 1]")
        limits = self.joint_limits()
        if np.any(target < limits.lower) or np.any(target > limits.upper):
            raise RobotError("joint target is outside the joint limits")
        percent = max(1, int(round(speed_fraction * 100)))
        degrees = np.rad2deg(target)
        self._start_move(call("PTP", "JPP", *degrees, percent, self.accel_time_ms, 0, False))

    def move_to_pose(self, pose: Pose, speed: float = 0.05) -> None:
        if not isinstance(pose, Pose):
            raise RobotError("move_to_pose needs a Pose")
        speed_mm_s = speed * 1000.0
        if not (np.isfinite(speed_mm_s) and 0.0 < speed_mm_s <= self.max_speed_mm_s):
            raise RobotError(f"pose move speed {speed} m/s is not in (0, max speed]")
        wire = pose_to_wire(pose)
        speed_arg = max(1, int(round(speed_mm_s)))
        self._start_move(call("Line", "CAP", *wire, speed_arg, self.accel_time_ms, 0, False))

    def stop(self) -> None:
        if not self._connected or self._lost is not None:
            return
        errors: list[str] = []
        for action in (self._leave_velocity_mode, lambda: self._script(call("StopAndClearBuffer"))):
            try:
                action()
            except RobotError as exc:
                errors.append(str(exc))
        self._pending_tag = None
        if errors:
            raise RobotError(errors[0])
