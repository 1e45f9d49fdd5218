"""The two links to a Techman controller: scripts to the Listen Node, state from the Ethernet Slave.

:class:`TechmanConnection` opens both TCP connections, runs a reader thread on each, and
keeps what came back: script answers by id, ``TMSTA`` status replies, ``CPERR`` codes, the
latest state frame (a frame that fails its checks is dropped and counted) and whether the
link was lost. It sends scripts (waiting for their answer or streaming them) and status
requests. What to send, and when, is :class:`~wovenskin.robots.techman.client.TechmanRobot`'s
business; the connection only forgets velocity mode when the controller's messages say it
ended (the flow re-entered the Listen Node, a streamed velocity was refused).
"""

from __future__ import annotations

import contextlib
import logging
import socket
import threading
from collections.abc import Callable

from wovenskin.robots.base import RobotError
from wovenskin.robots.techman.ethernet_slave import TechmanState, read_items, read_state
from wovenskin.robots.techman.protocol import (
    CommError,
    NodeEntered,
    Packet,
    PacketError,
    PacketParser,
    ScriptReply,
    parse_comm_error,
    parse_tmsct,
    script_packet,
    split_status,
    status_packet,
)
from wovenskin.robots.techman.velocity import VelocityTimeouts, stream_refused

log = logging.getLogger(__name__)


def one_line(exc: BaseException) -> str:
    """An OS or socket error as one line of text."""
    text = getattr(exc, "strerror", None) or str(exc) or type(exc).__name__
    return " ".join(str(text).split())


def _same_tag(text: str, tag: int | None) -> bool:
    """Whether a ``TMSTA 01`` reply's tag field (``8`` or ``08``) names ``tag``."""
    return tag is not None and text.strip().isdigit() and int(text) == tag


class TechmanConnection:
    """The Listen Node and Ethernet Slave links of one controller, and what they reported."""

    def __init__(
        self,
        host: str,
        port: int,
        state_port: int,
        *,
        timeout_s: float,
        stale_state_s: float,
        velocity_timeouts: VelocityTimeouts,
        clock: Callable[[], float],
    ) -> None:
        self.host = host
        self.port = port
        self.state_port = state_port
        self.timeout_s = timeout_s
        self.stale_state_s = stale_state_s
        self.velocity_timeouts = velocity_timeouts
        self._clock = clock
        # counters a caller or test may read
        self.velocity_refusals = 0  # ContinueVLine / SetContinueVLine refused
        self.bad_state_frames = 0
        self.last_bad_state: str | None = None
        self.listen_node_name: str | None = None  # from the controller's enter-node message
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
        for target in (self._read_listen, self._read_state, *self._extra_threads()):
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
                f"cannot connect to the Techman {what} at {self.host}:{port}: {one_line(exc)}"
            ) from None
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        sock.settimeout(0.1)
        return sock

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
                self._mark_lost(f"connection to the robot failed: {one_line(exc)}")
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
            self._velocity_mode_ended()
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
            self._velocity_mode_ended()  # stop keep-alives: no loop of refused scripts
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
            self._velocity_mode_ended()
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
            self._mark_lost(f"sending to the robot failed: {one_line(exc)}")
            raise RobotError(f"sending to the Techman robot failed: {one_line(exc)}") from None

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

    def _extra_threads(self) -> tuple[Callable[[], None], ...]:
        """Further threads to run while connected (the robot's watch thread)."""
        return ()

    def _velocity_mode_ended(self) -> None:
        """The controller left velocity mode: the next twist must enter it again."""
        self._velocity_mode = False
        self._twist_nonzero = False
