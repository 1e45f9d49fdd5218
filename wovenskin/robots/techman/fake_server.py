"""A fake Techman controller on TCP: a Listen Node (scripts) and an Ethernet Slave (state).

:class:`FakeListenNode` is a :class:`~.fake_controller.FakeController` behind two TCP
servers on ``127.0.0.1`` (ports chosen by the OS unless given). The Listen Node checks
the format, LENGTH and checksum of every packet (upper- or lower-case hex) and answers
as the controller does; it writes its own checksums in lower case, as Techman's driver
does, so a client must read both. Each new Listen Node client first gets the flow's
enter-node message ``0,Listen1``. A simulation thread advances the controller (motion,
velocity-mode timeouts) and pushes a ``TMSVR`` state frame to every Ethernet Slave
client every ``push_interval_s``, in binary mode by default (``state_mode``).

Run it alone to try a client against it::

    python -m wovenskin.robots.techman.fake_server --listen-port 5890 --state-port 5891

It prints the ``tm:`` spec to use and, on exit (Ctrl-C), what it saw: protocol
violations, script errors, velocity-mode entries and exits, the fastest commands.
It is a test double built from Techman's public material, not a robot model.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import signal
import socket
import threading
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from wovenskin.robots.sim import tm5_900
from wovenskin.robots.techman.ethernet_slave import SvrMode
from wovenskin.robots.techman.fake_controller import FakeController, ReceivedPacket
from wovenskin.robots.techman.protocol import Packet, PacketParser

__all__ = ["FakeListenNode", "ReceivedPacket", "main"]


class FakeListenNode(FakeController):
    """A threaded loopback stand-in for a Techman arm running a Listen Node."""

    def __init__(
        self,
        q0_deg: np.ndarray | None = None,
        tcp0: np.ndarray | None = None,
        fk: Callable[[np.ndarray], np.ndarray] | None = None,
        push_interval_s: float = 0.01,
        tick_s: float = 0.004,
        joint_speed_deg_s: float = 180.0,
        *,
        listen_port: int = 0,
        state_port: int = 0,
        lowercase_checksums: bool = True,
        send_enter_message: bool = True,
        **controller: Any,
    ) -> None:
        super().__init__(q0_deg, tcp0, fk, joint_speed_deg_s=joint_speed_deg_s, **controller)
        self.host = "127.0.0.1"
        self.push_interval_s = push_interval_s
        self.tick_s = tick_s
        self.lowercase_checksums = lowercase_checksums
        self.send_enter_message = send_enter_message
        self.answer_scripts = True  # False: accept packets but never answer (a hung robot)
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._clients: list[socket.socket] = []
        self._state_clients: list[socket.socket] = []
        self._client_lock = threading.Lock()
        self._listen_server = self._server(listen_port)
        try:
            self._state_server = self._server(state_port)
        except OSError:
            self._listen_server.close()
            raise

    @classmethod
    def tm5_900(cls, **options: Any) -> FakeListenNode:
        """A fake whose joints move with the TM5-900 model (joints and TCP agree), at the
        model's initial pose unless ``q0_deg`` is given."""
        options.setdefault("q0_deg", np.rad2deg(tm5_900.INITIAL_Q))
        return cls(
            forward_kinematics=tm5_900.forward_kinematics, jacobian=tm5_900.jacobian, **options
        )

    # -- lifecycle --------------------------------------------------------------------

    def _server(self, port: int) -> socket.socket:
        server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        server.bind((self.host, port))
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

    @property
    def spec(self) -> str:
        """The robot spec that reaches this fake: ``tm:127.0.0.1?listen_port=..&state_port=..``."""
        return f"tm:{self.host}?listen_port={self.listen_port}&state_port={self.state_port}"

    def start(self) -> FakeListenNode:
        """Start accepting clients and simulating; returns ``self``."""
        for target in (self._accept_listen, self._accept_state, self._simulate):
            thread = threading.Thread(target=target, daemon=True, name=f"fake-tm-{target.__name__}")
            thread.start()
            self._threads.append(thread)
        return self

    def stop(self) -> None:
        """Close every socket and stop the threads."""
        self._stop.set()
        self.drop_clients()
        for thread in list(self._threads):
            thread.join(timeout=2.0)
        self._listen_server.close()
        self._state_server.close()

    def __enter__(self) -> FakeListenNode:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def drop_clients(self) -> None:
        """Close every client connection (the robot went away)."""
        with self._client_lock:
            clients = self._clients + self._state_clients
            self._clients, self._state_clients = [], []
        for client in clients:
            with contextlib.suppress(OSError):
                client.shutdown(socket.SHUT_RDWR)
            client.close()

    def enter_listen_node(self) -> Packet:
        """The flow (re-)enters the Listen Node: every client gets the enter-node message,
        ordered with the script answers (both are sent holding the controller's lock)."""
        with self._lock:
            message = super().enter_listen_node()
            with self._client_lock:
                clients = list(self._clients)
            for client in clients:
                self._send(client, message)
        return message

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
            with self._client_lock:
                self._clients.append(client)
            thread = threading.Thread(target=self._serve_listen, args=(client,), daemon=True)
            thread.start()
            self._threads.append(thread)

        self._accept(self._listen_server, serve)

    def _accept_state(self) -> None:
        def register(client: socket.socket) -> None:
            client.settimeout(0.5)  # a client that stops reading is dropped, not waited for
            with self._client_lock:
                self._state_clients.append(client)

        self._accept(self._state_server, register)

    def _send(self, client: socket.socket, packet: Packet) -> None:
        with contextlib.suppress(OSError):
            client.sendall(packet.encode(lowercase=self.lowercase_checksums))

    def _serve_listen(self, client: socket.socket) -> None:
        parser = PacketParser()
        try:
            client.settimeout(0.05)
        except OSError:  # the client was closed (or the server stopped) before we began
            return
        if self.send_enter_message and self.in_listen_node:
            self._send(client, self.enter_message())
        while not self._stop.is_set():
            try:
                chunk = client.recv(65536)
            except TimeoutError:
                continue
            except OSError:
                return
            if not chunk:
                return
            for item in parser.feed(chunk):
                with self._lock:  # answers leave in the order the controller made them
                    replies = self.handle(item)
                    if self.answer_scripts:
                        for reply in replies:
                            self._send(client, reply)

    # -- simulation -------------------------------------------------------------------

    def _simulate(self) -> None:
        last_push = time.monotonic()
        while not self._stop.wait(self.tick_s):
            self.advance()
            now = time.monotonic()
            if now - last_push >= self.push_interval_s:
                last_push = now
                self._push_state()

    def _push_state(self) -> None:
        payload = self.state_frame().encode(lowercase=self.lowercase_checksums)
        with self._client_lock:
            clients = list(self._state_clients)
        for client in clients:
            try:
                client.sendall(payload)
            except OSError:
                with self._client_lock:
                    if client in self._state_clients:
                        self._state_clients.remove(client)

    # -- a summary for people and scripts ---------------------------------------------

    def summary(self) -> dict[str, object]:
        """What the fake saw, JSON-ready: violations, errors, velocity mode, fastest commands."""
        with self._lock:
            return {
                "protocol_violations": len(self.violations),
                "violations": list(self.violations[:20]),
                "script_errors": list(self.script_errors[:20]),
                "scripts": len(self.scripts),
                "velocity_commands": len(self.velocity_commands),
                "velocity_mode_entries": self.velocity_mode_entries,
                "velocity_mode_exits": [reason for _, reason in self.velocity_mode_exits],
                "zero_velocity_timeouts": self.zero_velocity_timeouts,
                "max_linear_command_mm_s": round(self.max_linear_command_mm_s, 3),
                "max_angular_command_deg_s": round(self.max_angular_command_deg_s, 3),
                "last_scripts": list(self.scripts[-3:]),
                "in_velocity_mode": self.velocity_mode,
            }


def main(argv: list[str] | None = None) -> int:
    """Run a fake controller until interrupted; print its spec, then its summary (JSON)."""
    parser = argparse.ArgumentParser(description="A fake Techman controller on loopback.")
    parser.add_argument("--listen-port", type=int, default=0, help="Listen Node port (0: any)")
    parser.add_argument("--state-port", type=int, default=0, help="Ethernet Slave port (0: any)")
    parser.add_argument("--json", action="store_true", help="push state in JSON mode")
    parser.add_argument("--no-licence", action="store_true", help="refuse velocity mode")
    parser.add_argument("--free-tcp", action="store_true", help="no TM5-900 joint model")
    parser.add_argument("--seconds", type=float, default=0.0, help="stop after this long")
    args = parser.parse_args(argv)
    options: dict[str, Any] = {
        "listen_port": args.listen_port,
        "state_port": args.state_port,
        "state_mode": SvrMode.JSON if args.json else SvrMode.BINARY,
        "velocity_licence": not args.no_licence,
    }
    node = FakeListenNode(**options) if args.free_tcp else FakeListenNode.tm5_900(**options)
    done = threading.Event()
    signal.signal(signal.SIGTERM, lambda *_: done.set())
    with node:
        print(node.spec, flush=True)
        with contextlib.suppress(KeyboardInterrupt):
            done.wait(args.seconds if args.seconds > 0 else None)
    print(json.dumps(node.summary()), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
