"""TechmanRobot: a Techman arm driven through TMflow's Listen Node and read via Ethernet Slave.

Two TCP connections: scripts go to the Listen Node (port 5890) as ``TMSCT`` packets; state
comes from the Ethernet Slave (port 5891), which pushes its data table in binary mode
(Techman's default for its drivers) or JSON mode, both read here (:mod:`.ethernet_slave`).
The table must hold ``Joint_Angle``, ``Coord_Robot_Tool``, ``TCP_Speed``, ``Robot_Error``
and ``Error_Code``; ``TCP_Speed3D``, ``Joint_Speed``, ``ESTOP`` and ``Project_Run`` are
used when present. A frame that fails its checks (corrupt bytes, wrong types, NaN) is
dropped and counted; the state then goes stale and reports a one-line fault.

Velocity mode (:mod:`.velocity`): the first twist sends ``ContinueVLine(300,2000)`` (the
controller's zero-velocity and stop timeouts, ms) and waits for its answer; each twist
then sends ``SetContinueVLine(vx, vy, vz, wx, wy, wz)`` in mm/s and deg/s (base frame)
without waiting, so a tick costs no round trip; a refused or unanswered script surfaces as
one :class:`RobotError` on the next call. A watch thread sends a zero velocity when no
twist arrives for ``command_timeout_s``, and while the commanded velocity is zero it
re-sends it every ``keepalive_s`` so the mode outlives the idle time between gestures.
``stop`` sends ``StopContinueVmode()`` and ``StopAndClearBuffer()``. Point-to-point moves
are ``PTP("JPP", ...)`` and ``Line("CAP", ...)`` followed by ``QueueTag(n)``; the watch
thread polls the tag (``TMSTA 01``) to know when the move is over.

The controller's ``0,NAME`` message (the flow entered the Listen Node) is recorded, not
taken for an error. docs/techman.md describes the setup and every error message.
"""

from __future__ import annotations

import contextlib
import logging
import socket
import threading
import time
from collections.abc import Callable

import numpy as np

from wovenskin.robots.base import (
    JointLimits,
    Pose,
    Robot,
    RobotCapabilities,
    RobotError,
    RobotState,
    finite_vector,
)
from wovenskin.robots.techman.ethernet_slave import TechmanState, read_items, read_state
from wovenskin.robots.techman.protocol import (
    ETHERNET_SLAVE_PORT,
    LISTEN_NODE_PORT,
    CommError,
    NodeEntered,
    Packet,
    PacketError,
    PacketParser,
    ScriptReply,
    call,
    parse_comm_error,
    parse_tmsct,
    pose_from_wire,
    pose_to_wire,
    script_packet,
    split_status,
    status_packet,
)
from wovenskin.robots.techman.velocity import VelocityTimeouts, enter_refused, stream_refused

log = logging.getLogger(__name__)

_MOVING_SPEED_MM_S = 1.0  # measured TCP speed above which the arm counts as moving
_MOVING_SPEED_DEG_S = 0.5  # measured TCP angular speed above which it counts as moving
_TAG_POLL_S = 0.05
_WATCH_PERIOD_S = 0.01
_ZERO_TWIST = (0.0,) * 6


def _one_line(exc: BaseException) -> str:
    text = getattr(exc, "strerror", None) or str(exc) or type(exc).__name__
    return " ".join(str(text).split())


def _same_tag(text: str, tag: int | None) -> bool:
    """Whether a ``TMSTA 01`` reply's tag field (``8`` or ``08``) names ``tag``."""
    return tag is not None and text.strip().isdigit() and int(text) == tag


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
        velocity_timeouts: VelocityTimeouts | None = None,
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
        self.velocity_timeouts = velocity_timeouts or VelocityTimeouts()
        if not 0.0 < command_timeout_s < self.velocity_timeouts.zero_velocity_s:
            raise ValueError(
                f"command timeout {command_timeout_s} s must be positive and shorter than the "
                f"controller's zero-velocity timeout ({self.velocity_timeouts.zero_velocity_ms} ms)"
            )
        self._limits = limits
        self._clock = clock
        # counters a caller or test may read
        self.watchdog_stops = 0  # zero velocities sent because twists stopped arriving
        self.keepalives = 0  # zero velocities re-sent to keep an idle velocity mode alive
        self.velocity_mode_entries = 0  # ContinueVLine accepted
        self.velocity_refusals = 0  # ContinueVLine / SetContinueVLine refused
        self.bad_state_frames = 0
        self.last_bad_state: str | None = None
        self.listen_node_name: str | None = None  # from the controller's enter-node message
        self._cond = threading.Condition()
        self._send_lock = threading.Lock()
        self._velocity_lock = threading.RLock()  # one writer of velocity commands at a time
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
        self._last_comm_error = CommError.PACKET
        self._status: dict[str, tuple[int, list[str]]] = {}
        self._state_items: dict[str, object] = {}
        self._state: TechmanState | None = None
        self._state_t = 0.0
        self._logged_bad: set[str] = set()
        self._velocity_mode = False
        self._mode_doubtful = False  # the controller may still be in velocity mode
        self._entered_before = False
        self._last_velocity_sent_t = 0.0
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
                raise RobotError(
                    f"Techman at {self.host}: the TMflow project is not in a Listen Node "
                    "(start the project and let its flow reach the Listen Node)"
                )
            with self._cond:
                got_state = self._cond.wait_for(
                    lambda: self._state is not None or self._lost is not None, self.timeout_s
                )
            if not got_state or self._state is None:
                why = (
                    f": {self.last_bad_state}"
                    if self.last_bad_state
                    else " (enable the Ethernet Slave in TMflow, binary or JSON mode)"
                )
                raise RobotError(
                    f"no usable state from the Ethernet Slave at {self.host}:{self.state_port} "
                    f"within {self.timeout_s:g} s{why}"
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

    @property
    def in_velocity_mode(self) -> bool:
        """Whether the client believes the controller is in velocity mode."""
        return self._velocity_mode

    # -- reader threads ---------------------------------------------------------------

    def _receive_loop(
        self, sock: socket.socket, handle: Callable[[Packet], None], what: str
    ) -> None:
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
                    self._on_corrupt(what, item)
                else:
                    handle(item)

    def _on_corrupt(self, what: str, error: PacketError) -> None:
        if what == "state":
            self._bad_state(f"corrupt Ethernet Slave packet: {error}")
            return
        with self._cond:
            self._failures.append(f"corrupt packet from the Listen Node: {error}")
            self._cond.notify_all()

    def _mark_lost(self, reason: str) -> None:
        if self._closing.is_set():
            return
        with self._cond:
            if self._lost is None:
                self._lost = reason
            self._cond.notify_all()

    def _read_listen(self) -> None:
        assert self._listen is not None
        self._receive_loop(self._listen, self._on_listen_packet, "listen")

    def _read_state(self) -> None:
        assert self._state_sock is not None
        self._receive_loop(self._state_sock, self._on_state_packet, "state")

    def _on_listen_packet(self, packet: Packet) -> None:
        with self._cond:
            try:
                if packet.header == "TMSCT":
                    message = parse_tmsct(packet.data)
                    if isinstance(message, NodeEntered):
                        self._on_node_entered(message.node)
                    else:
                        self._on_reply(message)
                elif packet.header == "TMSTA":
                    self._on_status(*split_status(packet.data))
                elif packet.header == "CPERR":
                    self._on_comm_error(parse_comm_error(packet.data))
                else:
                    self._failures.append(f"unexpected {packet.header} packet from the Listen Node")
            except PacketError as exc:
                self._failures.append(f"unexpected answer from the robot: {exc}")
            self._cond.notify_all()

    def _on_node_entered(self, node: str) -> None:
        """The flow entered the Listen Node ``node``: not an error. Entered again while we
        believed velocity mode on, the flow has left and re-entered, so the mode is gone."""
        self.listen_node_name = node
        if self._velocity_mode:
            self._velocity_mode = False
            self._twist_nonzero = False
            log.warning(
                "Techman: the flow re-entered Listen Node %r; velocity mode ended, the next "
                "command re-enters it",
                node,
            )
        else:
            log.info("Techman: the flow entered Listen Node %r", node)

    def _on_reply(self, reply: ScriptReply) -> None:
        sent = self._in_flight.pop(reply.script_id, None)
        if sent is None:
            self._replies[reply.script_id] = reply
        elif not reply.ok:
            self._on_stream_refused(sent[1], reply)

    def _on_stream_refused(self, name: str, reply: ScriptReply) -> None:
        if name == "SetContinueVLine":
            self.velocity_refusals += 1
            if not self._velocity_mode:
                return  # a later answer to the same lost mode: already reported once
            self._velocity_mode = False  # stop keep-alives: no loop of refused scripts
            self._twist_nonzero = False
            message = stream_refused(name, reply.error_lines, self.velocity_timeouts.stop_ms)
            log.info("Techman: %s", message)
            self._failures.append(message)
        else:
            self._failures.append(self._rejection(name, reply))

    def _on_status(self, subcommand: str, args: list[str]) -> None:
        count = self._status.get(subcommand, (0, []))[0]
        self._status[subcommand] = (count + 1, args)
        tag_over = args[1:2] in (["true"], ["none"])
        if subcommand == "01" and args and _same_tag(args[0], self._pending_tag) and tag_over:
            self._pending_tag = None
            self._tag_done_t = self._clock()

    def _on_comm_error(self, code: CommError) -> None:
        if code is CommError.NO_ERROR:
            return
        self._last_comm_error = code
        if code is CommError.NOT_IN_LISTEN_NODE and self._velocity_mode:
            self._velocity_mode = False
            self._twist_nonzero = False
        if self._in_flight:  # answers come in order: the oldest streamed script caused it
            oldest = next(iter(self._in_flight))
            name = self._in_flight.pop(oldest)[1]
            self._failures.append(f"the robot refused the {name} packet: {code.explain()}")
        else:
            self._comm_errors += 1

    def _on_state_packet(self, packet: Packet) -> None:
        try:
            if packet.header == "CPERR":
                code = parse_comm_error(packet.data)
                raise PacketError(f"the Ethernet Slave answered: {code.explain()}")
            if packet.header != "TMSVR":
                raise PacketError(f"unexpected {packet.header} packet on the Ethernet Slave")
            items = read_items(packet.payload)
            if items is None:
                return  # a response frame: nothing to read
            with self._cond:
                merged = {**self._state_items, **items}
            state = read_state(merged)
        except PacketError as exc:
            self._bad_state(str(exc))
            return
        with self._cond:
            self._state_items = merged
            self._state = state
            self._state_t = self._clock()
            self._cond.notify_all()

    def _bad_state(self, reason: str) -> None:
        with self._cond:
            self.bad_state_frames += 1
            self.last_bad_state = reason
            first = reason not in self._logged_bad and len(self._logged_bad) < 32
            self._logged_bad.add(reason)
        if first:
            log.warning("Techman state frame dropped: %s", reason)

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
        self._next_id += 1  # never "0": that id is the controller's enter-node message
        return str(self._next_id)

    def _script(self, script: str, wait: bool = True, check: bool = True) -> ScriptReply | None:
        """Send a script; with ``wait`` block for its answer and return it, raising when the
        packet is refused, unanswered, or (with ``check``) answered ``ERROR``."""
        name = script.split("(", 1)[0]
        with self._cond:
            script_id = self._new_id()
            errors_before = self._comm_errors
            if not wait:
                self._in_flight[script_id] = (self._clock(), name)
        self._send(script_packet(script_id, script))
        if not wait:
            return None
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
                explained = self._last_comm_error.explain()
                raise RobotError(f"the robot refused the {name} packet: {explained}")
        if self._lost is not None:
            raise RobotError(f"Techman robot: {self._lost}")
        if not answered or reply is None:
            raise RobotError(f"the robot did not answer {name} within {self.timeout_s:g} s")
        if check and not reply.ok:
            raise RobotError(self._rejection(name, reply))
        return reply

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
        with self._cond:
            self._failures.clear()  # answers that arrived while stopping belong to this one
        raise RobotError(failure)

    def _check_fault(self) -> None:
        fault = self._fault()
        if fault is not None:
            with self._cond:
                self._failures.clear()  # refusals during a fault are explained by it
            raise RobotError(f"Techman robot: {fault}")

    # -- velocity mode ----------------------------------------------------------------

    def _enter_velocity_mode(self) -> None:
        """Send ``ContinueVLine`` and wait for it; a refusal raises one explained line."""
        if self._pending_tag is not None:
            self._script(call("StopAndClearBuffer"))
            self._pending_tag = None
        if self._mode_doubtful:  # leave a mode that may linger before entering afresh
            self._script(call("StopContinueVmode"), check=False)
            self._mode_doubtful = False
        reply = self._script(self.velocity_timeouts.enter_script(), check=False)
        assert reply is not None
        if not reply.ok:
            self.velocity_refusals += 1
            message = enter_refused(reply.error_lines, self._entered_before)
            log.info("Techman: %s", message)
            raise RobotError(message)
        self._velocity_mode = True
        self._entered_before = True
        self.velocity_mode_entries += 1
        self._last_velocity_sent_t = self._clock()
        if self.velocity_mode_entries > 1:
            log.info("Techman: velocity mode entered again (%d times)", self.velocity_mode_entries)

    def _send_velocity(self, values: tuple[float, ...] | list[float], now: float) -> None:
        self._last_velocity_sent_t = now
        self._script(call("SetContinueVLine", *values), wait=False)

    def _mode_went_stale(self, now: float) -> bool:
        """If no velocity went out for half the controller's stop timeout, stop trusting
        the mode (the controller may have left it): the next twist re-enters it."""
        idle = now - self._last_velocity_sent_t
        if not self._velocity_mode or idle < self.velocity_timeouts.reenter_after_s:
            return False
        self._velocity_mode = False
        self._twist_nonzero = False
        self._mode_doubtful = True
        log.warning(
            "Techman: no velocity command went out for %.2f s (the controller leaves velocity "
            "mode after %d ms); the next command re-enters velocity mode",
            idle,
            self.velocity_timeouts.stop_ms,
        )
        return True

    def _leave_velocity_mode(self) -> None:
        with self._velocity_lock:
            if self._velocity_mode:
                self._velocity_mode = False
                self._twist_nonzero = False
                self._script(call("StopContinueVmode"))
            elif self._mode_doubtful:
                self._mode_doubtful = False
                self._script(call("StopContinueVmode"), check=False)

    # -- watch thread: command timeout, keep-alive and move tags ----------------------

    def _watch(self) -> None:
        keepalive_s = self.velocity_timeouts.keepalive_s
        while not self._closing.wait(_WATCH_PERIOD_S):
            if self._lost is not None:
                continue
            try:
                with self._velocity_lock:
                    now = self._clock()
                    if self._mode_went_stale(now):
                        pass
                    elif self._velocity_mode and self._twist_nonzero:
                        if now - self._last_twist_t > self.command_timeout_s:
                            self._twist_nonzero = False
                            self.watchdog_stops += 1
                            self._send_velocity(_ZERO_TWIST, now)
                    elif self._velocity_mode and now - self._last_velocity_sent_t >= keepalive_s:
                        self.keepalives += 1
                        self._send_velocity(_ZERO_TWIST, now)
                now = self._clock()
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

    def capabilities(self) -> RobotCapabilities:
        """The TM5-900 model and drawing. No stop profile is declared (the safety layer
        then assumes its conservative stop time) and no default poses (a real arm goes
        only to poses the user stored); 1 % tracking allowance, assumed, not measured."""
        from wovenskin.robots.sim import tm5_900

        return RobotCapabilities(
            kinematics=tm5_900.kinematics(), scene=tm5_900.scene(), tracking_error=0.01
        )

    def _fault(self) -> str | None:
        with self._cond:
            state = self._state
            age = self._clock() - self._state_t
            bad = self.last_bad_state
        if self._lost is not None:
            return self._lost
        if state is None:
            return "no state received from the robot" + (f" ({bad})" if bad else "")
        if age > self.stale_state_s:
            why = f" (last frame dropped: {bad})" if bad else ""
            return f"no valid state from the robot for {age:.2f} s{why}"
        if state.estop:
            return "the emergency stop is pressed"
        if state.robot_error:
            return f"robot error code {state.error_code}"
        return None

    def state(self) -> RobotState:
        if not self._connected:
            raise RobotError("Techman robot is not connected")
        with self._cond:
            current = self._state
            t = self._state_t
        if current is None:
            raise RobotError(f"Techman robot: {self._fault()}")
        try:
            tcp = pose_from_wire(current.tool_wire)
        except PacketError as exc:
            raise RobotError(f"Techman state frame is unusable: {_one_line(exc)}") from None
        speed = current.tcp_speed
        twist = np.concatenate([speed[:3] / 1000.0, np.deg2rad(speed[3:])])
        joint_speed = current.joint_speed_deg_s
        dq = np.zeros(6) if joint_speed is None else np.deg2rad(joint_speed)
        commanding = self._velocity_mode and self._twist_nonzero
        moving = (
            commanding
            or self._pending_tag is not None
            or t <= self._tag_done_t
            or current.linear_speed_mm_s > _MOVING_SPEED_MM_S
            or float(np.linalg.norm(speed[3:])) > _MOVING_SPEED_DEG_S
        )
        return RobotState(
            t=t,
            q=np.deg2rad(current.joint_deg),
            dq=dq,
            tcp=tcp,
            tcp_twist=twist,
            moving=moving,
            fault=self._fault(),
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
        with self._velocity_lock:
            now = self._clock()
            self._mode_went_stale(now)
            if not self._velocity_mode:
                self._enter_velocity_mode()
            values = [*linear_mm_s, *np.rad2deg(command[3:])]
            self._last_twist_t = now
            self._twist_nonzero = bool(np.any(command != 0.0))
            self._send_velocity(values, self._clock())

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
