"""Tests for the fake Listen Node: packet checks, robot-like answers, motion and state push."""

from __future__ import annotations

import socket
import time
from collections.abc import Iterator

import numpy as np
import pytest

from wovenskin.robots.techman.fake_server import FakeListenNode
from wovenskin.robots.techman.protocol import (
    Packet,
    PacketParser,
    encode_packet,
    parse_state,
    script_packet,
)


class Link:
    """A raw socket to the fake robot that sends packets and waits for answers."""

    def __init__(self, port: int) -> None:
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=2.0)
        self.parser = PacketParser()
        self.pending: list = []

    def send_raw(self, raw: bytes) -> None:
        self.sock.sendall(raw)

    def receive(self) -> Packet:
        while not self.pending:
            self.pending += self.parser.feed(self.sock.recv(65536))
        item = self.pending.pop(0)
        assert isinstance(item, Packet), item
        return item

    def script(self, script_id: str, script: str) -> str:
        self.send_raw(script_packet(script_id, script).encode())
        return self.receive().data


@pytest.fixture
def fake() -> Iterator[FakeListenNode]:
    with FakeListenNode() as node:
        yield node


@pytest.fixture
def link(fake: FakeListenNode) -> Iterator[Link]:
    connection = Link(fake.listen_port)
    yield connection
    connection.sock.close()


def test_good_scripts_are_answered_ok_per_id(fake: FakeListenNode, link: Link) -> None:
    assert link.script("a1", "StopAndClearBuffer()") == "a1,OK"
    assert link.script("a2", "ContinueVLine(200,250)") == "a2,OK"
    assert fake.velocity_mode
    assert fake.violations == []
    assert fake.scripts == ["StopAndClearBuffer()", "ContinueVLine(200,250)"]


def test_bad_checksum_is_answered_with_cperr_and_recorded(fake: FakeListenNode, link: Link) -> None:
    raw = bytearray(encode_packet("TMSCT", "1,StopAndClearBuffer()"))
    raw[-3] = ord("0") if raw[-3] != ord("0") else ord("1")
    link.send_raw(bytes(raw))
    assert link.receive() == Packet("CPERR", "02")
    assert len(fake.violations) == 1 and "checksum" in fake.violations[0]
    assert fake.scripts == []
    assert link.script("2", "StopAndClearBuffer()") == "2,OK"  # still listening


def test_wrong_length_and_header_get_cperr(fake: FakeListenNode, link: Link) -> None:
    link.send_raw(encode_packet("TMSCT", "1,StopAndClearBuffer()").replace(b",22,", b",20,"))
    assert link.receive().header == "CPERR"
    link.send_raw(encode_packet("TMSVR", "1,3,[]"))
    assert link.receive() == Packet("CPERR", "03")
    link.send_raw(encode_packet("TMSCT", "noscript"))
    assert link.receive() == Packet("CPERR", "04")
    assert len(fake.violations) == 3


def test_script_errors_name_the_line(fake: FakeListenNode, link: Link) -> None:
    assert link.script("1", "SetContinueVLine(1,0,0,0,0,0)") == "1,ERROR;1"
    assert link.script("2", "Teleport(1)") == "2,ERROR;1"
    assert link.script("3", "ContinueVLine(200,250)\r\nSetContinueVLine(1,0,0)") == "3,ERROR;2"
    assert not fake.velocity_mode  # a refused script runs none of its lines
    reply = link.script("4", "ContinueVLine(200,250)\r\nSetContinueVLine(10,0,0,0,0,0)")
    assert reply == "4,OK"
    assert link.script("5", 'PTP("JPP",0,0,0,0,0,0,10,200,0,false)') == "5,ERROR;1"
    assert fake.violations == []  # script errors are answers, not protocol violations


def test_velocity_is_integrated_into_the_tcp(fake: FakeListenNode, link: Link) -> None:
    start = fake.tcp_wire()
    link.script("1", "ContinueVLine(100,250)\r\nSetContinueVLine(100,0,-50,0,0,0)")
    time.sleep(0.2)
    link.script("2", "StopContinueVmode()")
    moved = fake.tcp_wire() - start
    assert 10.0 < moved[0] < 40.0
    assert moved[2] == pytest.approx(-moved[0] / 2, rel=1e-6)
    np.testing.assert_allclose(moved[3:], 0.0, atol=1e-9)


def test_speed_is_capped_by_continuevline(fake: FakeListenNode, link: Link) -> None:
    link.script("1", "ContinueVLine(100,20)\r\nSetContinueVLine(300,400,0,0,0,0)")
    time.sleep(0.1)
    speed = float(np.linalg.norm(fake.state_items()["TCP_Speed3D"][:3]))
    assert speed == pytest.approx(20.0)


def test_joint_move_and_queue_tag(fake: FakeListenNode, link: Link) -> None:
    reply = link.script("1", 'PTP("JPP",9,0,0,0,0,-9,50,200,0,false)\r\nQueueTag(3)')
    assert reply == "1,OK"
    link.send_raw(encode_packet("TMSTA", "01,3"))
    assert link.receive() == Packet("TMSTA", "01,3,false")
    time.sleep(0.25)  # 9 deg at 90 deg/s
    link.send_raw(encode_packet("TMSTA", "01,3"))
    assert link.receive() == Packet("TMSTA", "01,3,true")
    np.testing.assert_allclose(fake.q_deg, [9, 0, 0, 0, 0, -9])
    link.send_raw(encode_packet("TMSTA", "01,7"))
    assert link.receive() == Packet("TMSTA", "01,7,none")


def test_line_move_reaches_the_pose(fake: FakeListenNode, link: Link) -> None:
    assert link.script("1", 'Line("CAP",420,10,400,180,0,90,200,100,0,false)') == "1,OK"
    time.sleep(0.3)
    np.testing.assert_allclose(fake.tcp_wire()[:3], [420, 10, 400], atol=1e-6)


def test_fault_stops_motion_and_refuses_scripts(fake: FakeListenNode, link: Link) -> None:
    link.script("1", "ContinueVLine(100,250)\r\nSetContinueVLine(50,0,0,0,0,0)")
    fake.inject_fault(3)
    assert link.script("2", "SetContinueVLine(50,0,0,0,0,0)") == "2,ERROR;1"
    before = fake.tcp_wire()
    time.sleep(0.05)
    np.testing.assert_allclose(fake.tcp_wire(), before)
    assert fake.state_items()["Error_Code"] == 3


def test_status_and_state_push(fake: FakeListenNode, link: Link) -> None:
    link.send_raw(encode_packet("TMSTA", "00"))
    assert link.receive().data.startswith("00,true")
    state = Link(fake.state_port)
    packet = state.receive()
    items = parse_state(packet.data)
    assert packet.header == "TMSVR"
    assert items["Coord_Robot_Tool"] == pytest.approx([400, 0, 400, 180, 0, 90])
    assert items["Robot_Error"] is False
    state.sock.close()


def test_joint_moves_update_the_tcp_through_fk() -> None:
    def fk(q_deg: np.ndarray) -> np.ndarray:
        return np.array([300.0 + q_deg[0], 0.0, 500.0, 180.0, 0.0, 0.0])

    with FakeListenNode(fk=fk) as node:
        link = Link(node.listen_port)
        link.script("1", 'PTP("JPP",20,0,0,0,0,0,100,200,0,false)')
        time.sleep(0.25)
        np.testing.assert_allclose(node.tcp_wire()[:3], [320.0, 0.0, 500.0])
        link.sock.close()
