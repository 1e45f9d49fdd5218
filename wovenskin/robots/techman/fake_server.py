"""A fake Techman robot on loopback: a Listen Node (scripts) and an Ethernet Slave (state).

:class:`FakeListenNode` opens two TCP servers on ``127.0.0.1`` (ports chosen by the OS).
The Listen Node checks the format, LENGTH and checksum of **every** packet it receives;
a bad packet is answered with ``CPERR`` and recorded in :attr:`FakeListenNode.violations`.
Scripts are answered like the robot does (``ID,OK`` or ``ID,ERROR;line``): unknown
functions, wrong argument counts, ``SetContinueVLine`` outside velocity mode and
point-to-point moves inside it are errors. A simulation thread integrates the commanded
velocity (mm/s, deg/s, base frame) into the TCP pose, runs queued ``PTP``/``Line`` moves
and pushes JSON ``TMSVR`` state frames to every Ethernet Slave client.

Joint angles change only through ``PTP("JPP", ...)``; velocity mode moves the TCP alone,
unless ``fk`` (joint degrees -> TCP wire pose) is given, in which case joint moves update
the TCP too. It is a test double, not a robot model.
"""

from __future__ import annotations

import contextlib
import re
import socket
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from wovenskin.robots.techman.protocol import (
    CommError,
    Packet,
    PacketError,
    PacketParser,
    ScriptReply,
    state_packet,
)

_CALL = re.compile(r"^([A-Za-z_]\w*)\((.*)\)$")
_NUMBER = re.compile(r"^[-+]?(\d+(\.\d*)?|\.\d+)$")
_ROTATION_SPEED_DEG_S = 45.0  # how fast a Line move turns the tool when it barely travels


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


class _ScriptError(Exception):
    """A script line the fake robot refuses."""


def _parse_args(text: str) -> list[object]:
    if not text.strip():
        return []
    args: list[object] = []
    for raw in text.split(","):
        item = raw.strip()
        if len(item) >= 2 and item[0] == item[-1] == '"':
            args.append(item[1:-1])
        elif item in ("true", "false"):
            args.append(item == "true")
        elif _NUMBER.match(item):
            args.append(float(item))
        else:
            raise _ScriptError(f"bad argument {item!r}")
    return args


def _numbers(args: list[object], count: int) -> np.ndarray:
    if len(args) != count or not all(isinstance(a, float) for a in args):
        raise _ScriptError(f"expected {count} numbers")
    return np.array(args, dtype=float)


class FakeListenNode:
    """A threaded loopback stand-in for a Techman arm running a Listen Node."""

    def __init__(
        self,
        q0_deg: np.ndarray | None = None,
        tcp0: np.ndarray | None = None,
        fk: Callable[[np.ndarray], np.ndarray] | None = None,
        push_interval_s: float = 0.01,
        tick_s: float = 0.002,
        joint_speed_deg_s: float = 180.0,
    ) -> None:
        self.host = "127.0.0.1"
        self.q_deg = np.zeros(6) if q0_deg is None else np.asarray(q0_deg, dtype=float).copy()
        start_tcp = [400.0, 0.0, 400.0, 180.0, 0.0, 90.0] if tcp0 is None else tcp0
        self.position_mm = np.asarray(start_tcp[:3], dtype=float).copy()
        self.rotation = Rotation.from_euler("xyz", start_tcp[3:], degrees=True)
        self.fk = fk
        self.push_interval_s = push_interval_s
        self.tick_s = tick_s
        self.joint_speed_deg_s = joint_speed_deg_s
        self.answer_scripts = True  # False: accept packets but never answer (a hung robot)
        self.received: list[ReceivedPacket] = []
        self.violations: list[str] = []
        self.scripts: list[str] = []  # every script line that was accepted, in order
        self.velocity_mode = False
        self.max_speed_mm_s = 0.0
        self.command_velocity = np.zeros(6)  # mm/s, deg/s, base frame
        self.measured_velocity = np.zeros(6)
        self.error_code = 0
        self._moves: list[_Move] = []
        self._moves_done = 0
        self._moves_queued = 0
        self._tags: dict[int, int] = {}
        self._lock = threading.RLock()
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._clients: list[socket.socket] = []
        self._state_clients: list[socket.socket] = []
        self._listen_server = self._server()
        self._state_server = self._server()
        self._frame_counter = 0

    # -- lifecycle --------------------------------------------------------------------

    def _server(self) -> socket.socket:
        server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        server.bind((self.host, 0))
        server.listen(4)
        server.settimeout(0.05)
        return server

    @property
    def listen_port(self) -> int:
        """The Listen Node's port (scripts)."""
        return self._listen_server.getsockname()[1]

    @property
    def state_port(self) -> int:
        """The Ethernet Slave's port (state frames)."""
        return self._state_server.getsockname()[1]

    def start(self) -> FakeListenNode:
        """Start accepting clients and simulating; returns ``self``."""
        for target in (self._accept_listen, self._accept_state, self._simulate):
            thread = threading.Thread(target=target, daemon=True)
            thread.start()
            self._threads.append(thread)
        return self

    def stop(self) -> None:
        """Close every socket and stop the threads."""
        self._stop.set()
        self.drop_clients()
        for thread in self._threads:
            thread.join(timeout=2.0)
        self._listen_server.close()
        self._state_server.close()

    def __enter__(self) -> FakeListenNode:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def drop_clients(self) -> None:
        """Close every client connection (the robot went away)."""
        with self._lock:
            clients = self._clients + self._state_clients
            self._clients, self._state_clients = [], []
        for client in clients:
            with contextlib.suppress(OSError):
                client.shutdown(socket.SHUT_RDWR)
            client.close()

    # -- faults -----------------------------------------------------------------------

    def inject_fault(self, code: int) -> None:
        """Raise a robot error: motion stops, velocity mode ends, state reports ``code``."""
        with self._lock:
            self.error_code = int(code)
            self._halt()
            self.velocity_mode = False

    def clear_fault(self) -> None:
        """Clear the robot error."""
        with self._lock:
            self.error_code = 0

    # -- state ------------------------------------------------------------------------

    def tcp_wire(self) -> np.ndarray:
        """The TCP as ``[X, Y, Z, RX, RY, RZ]`` (mm, deg)."""
        with self._lock:
            angles = self.rotation.as_euler("xyz", degrees=True)
            return np.concatenate([self.position_mm, angles])

    def state_items(self) -> dict[str, object]:
        """The Ethernet Slave items the fake robot reports."""
        with self._lock:
            return {
                "Joint_Angle": self.q_deg.tolist(),
                "Coord_Robot_Tool": self.tcp_wire().tolist(),
                "TCP_Speed3D": self.measured_velocity.tolist(),
                "Robot_Error": self.error_code != 0,
                "Error_Code": self.error_code,
            }

    def tag_status(self, tag: int) -> str:
        """``true`` when the moves queued before ``tag`` are done, ``false``, or ``none``."""
        with self._lock:
            if tag not in self._tags:
                return "none"
            return "true" if self._moves_done >= self._tags[tag] else "false"

    # -- sockets ----------------------------------------------------------------------

    def _accept(self, server: socket.socket, on_client: Callable[[socket.socket], None]) -> None:
        while not self._stop.is_set():
            try:
                client, _ = server.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            client.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            on_client(client)

    def _accept_listen(self) -> None:
        def serve(client: socket.socket) -> None:
            with self._lock:
                self._clients.append(client)
            thread = threading.Thread(target=self._serve_listen, args=(client,), daemon=True)
            thread.start()
            self._threads.append(thread)

        self._accept(self._listen_server, serve)

    def _accept_state(self) -> None:
        def register(client: socket.socket) -> None:
            client.settimeout(0.5)  # a client that stops reading is dropped, not waited for
            with self._lock:
                self._state_clients.append(client)

        self._accept(self._state_server, register)

    def _send(self, client: socket.socket, packet: Packet) -> None:
        with contextlib.suppress(OSError):
            client.sendall(packet.encode())

    def _serve_listen(self, client: socket.socket) -> None:
        parser = PacketParser()
        try:
            client.settimeout(0.05)
        except OSError:  # the client was closed (or the server stopped) before we began
            return
        while not self._stop.is_set():
            try:
                chunk = client.recv(4096)
            except TimeoutError:
                continue
            except OSError:
                return
            if not chunk:
                return
            for item in parser.feed(chunk):
                reply = self._handle(item)
                if reply is not None and self.answer_scripts:
                    self._send(client, reply)

    def _handle(self, item: Packet | PacketError) -> Packet | None:
        with self._lock:
            if isinstance(item, PacketError):
                self.received.append(ReceivedPacket(None, str(item)))
                self.violations.append(str(item))
                return Packet("CPERR", item.code.value)
            self.received.append(ReceivedPacket(item))
            if item.header == "TMSCT":
                return self._handle_script(item.data)
            if item.header == "TMSTA":
                return self._handle_status(item.data)
            message = f"{item.header} packet sent to the Listen Node"
            self.violations.append(message)
            return Packet("CPERR", CommError.HEADER.value)

    def _handle_status(self, data: str) -> Packet:
        subcommand, *args = data.split(",")
        if subcommand == "00" and not args:
            return Packet("TMSTA", "00,true,wovenskin")
        if subcommand == "01" and len(args) == 1 and args[0].isdigit():
            return Packet("TMSTA", f"01,{args[0]},{self.tag_status(int(args[0]))}")
        self.violations.append(f"bad TMSTA data {data!r}")
        return Packet("CPERR", CommError.PACKET_DATA.value)

    def _handle_script(self, data: str) -> Packet:
        script_id, sep, script = data.partition(",")
        if not sep or not script_id or not script.strip():
            self.violations.append(f"TMSCT data {data!r} lacks ID,SCRIPT")
            return Packet("CPERR", CommError.PACKET_DATA.value)
        lines = script.split("\r\n")
        actions: list[Callable[[], None]] = []
        bad: list[int] = []
        velocity_mode = self.velocity_mode  # scripts run in order: track mode changes
        for number, line in enumerate(lines, start=1):
            try:
                action, velocity_mode = self._compile(line.strip(), velocity_mode)
                actions.append(action)
            except _ScriptError:
                bad.append(number)
        if bad:
            return ScriptReply(script_id, False, tuple(bad)).to_packet()
        for action in actions:
            action()
        self.scripts.extend(line.strip() for line in lines)
        return ScriptReply(script_id, True).to_packet()

    # -- script semantics -------------------------------------------------------------

    def _compile(self, line: str, velocity_mode: bool) -> tuple[Callable[[], None], bool]:
        match = _CALL.match(line)
        if match is None:
            raise _ScriptError(f"not a function call: {line!r}")
        name, args = match.group(1), _parse_args(match.group(2))
        moving_allowed = self.error_code == 0
        if name == "ContinueVLine":
            accel_ms, max_speed = _numbers(args, 2)
            if accel_ms <= 0 or max_speed <= 0 or not moving_allowed:
                raise _ScriptError("bad ContinueVLine")
            return lambda: self._enter_velocity_mode(max_speed), True
        if name == "SetContinueVLine":
            velocity = _numbers(args, 6)
            if not velocity_mode or not moving_allowed:
                raise _ScriptError("SetContinueVLine outside velocity mode")
            return lambda: self._set_velocity(velocity), True
        if name == "StopContinueVmode" and not args:
            return self._leave_velocity_mode, False
        if name == "StopAndClearBuffer" and len(args) <= 1:
            return self._halt, velocity_mode
        if name in ("PTP", "Line"):
            expected_format = "JPP" if name == "PTP" else "CAP"
            if len(args) != 11 or args[0] != expected_format or not isinstance(args[10], bool):
                raise _ScriptError(f"bad {name} arguments")
            values = _numbers(args[1:10], 9)
            if velocity_mode or not moving_allowed or not values[6] > 0:
                raise _ScriptError(f"{name} refused")
            if name == "PTP" and values[6] > 100:
                raise _ScriptError("PTP speed above 100%")
            return lambda: self._queue_move(name, values), velocity_mode
        if name == "QueueTag":
            (tag,) = _numbers(args, 1)
            if tag != int(tag) or not 1 <= tag <= 15:
                raise _ScriptError("bad tag")
            return lambda: self._tag(int(tag)), velocity_mode
        raise _ScriptError(f"unknown function {name}")

    def _enter_velocity_mode(self, max_speed_mm_s: float) -> None:
        self.velocity_mode = True
        self.max_speed_mm_s = max_speed_mm_s

    def _set_velocity(self, velocity: np.ndarray) -> None:
        self.command_velocity = velocity.copy()

    def _leave_velocity_mode(self) -> None:
        self.velocity_mode = False
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

    def _simulate(self) -> None:
        last = time.monotonic()
        last_push = last
        while not self._stop.wait(self.tick_s):
            now = time.monotonic()
            with self._lock:
                self._advance(now - last)
            last = now
            if now - last_push >= self.push_interval_s:
                last_push = now
                self._push_state()

    def _advance(self, dt: float) -> None:
        if self.velocity_mode and self.error_code == 0:
            velocity = self.command_velocity.copy()
            speed = float(np.linalg.norm(velocity[:3]))
            if speed > self.max_speed_mm_s > 0:
                velocity[:3] *= self.max_speed_mm_s / speed
            self.position_mm = self.position_mm + velocity[:3] * dt
            turn = Rotation.from_rotvec(np.deg2rad(velocity[3:]) * dt)
            self.rotation = turn * self.rotation
            self.measured_velocity = velocity
            return
        self.measured_velocity = np.zeros(6)
        if not self._moves or self.error_code != 0:
            return
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
            if self.fk is not None:
                self._set_tcp(np.asarray(self.fk(self.q_deg), dtype=float))
        else:
            self._set_tcp_between(move.start, move.target, fraction)
        if fraction >= 1.0:
            self._moves.pop(0)
            self._moves_done += 1

    def _set_tcp(self, wire: np.ndarray) -> None:
        self.position_mm = wire[:3].copy()
        self.rotation = Rotation.from_euler("xyz", wire[3:], degrees=True)

    def _set_tcp_between(self, start: np.ndarray, target: np.ndarray, fraction: float) -> None:
        self.position_mm = start[:3] + fraction * (target[:3] - start[:3])
        start_rot = Rotation.from_euler("xyz", start[3:], degrees=True)
        goal_rot = Rotation.from_euler("xyz", target[3:], degrees=True)
        delta = (goal_rot * start_rot.inv()).as_rotvec()
        self.rotation = Rotation.from_rotvec(delta * fraction) * start_rot

    def _push_state(self) -> None:
        self._frame_counter += 1
        payload = state_packet(str(self._frame_counter % 100000), self.state_items()).encode()
        with self._lock:
            clients = list(self._state_clients)
        for client in clients:
            try:
                client.sendall(payload)
            except OSError:
                with self._lock:
                    if client in self._state_clients:
                        self._state_clients.remove(client)
