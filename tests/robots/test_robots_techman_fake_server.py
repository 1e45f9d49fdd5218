"""Tests for the fake controller on TCP: packet checks, answers in lower-case checksums, the
enter-node message, motion and the state push in binary and JSON modes."""

from __future__ import annotations

import socket
import time
from collections.abc import Iterator

import numpy as np
import pytest
from stand_ins import wait_until

from wovenskin.robots.techman.ethernet_slave import SvrMode, read_items, split_frame
from wovenskin.robots.techman.fake_server import FakeListenNode, main
from wovenskin.robots.techman.protocol import (
    NodeEntered,
    Packet,
    PacketParser,
    encode_packet,
    parse_tmsct,
    script_packet,
)


class Link:
    """A raw socket to the fake robot that sends packets and waits for answers; it keeps
    the raw bytes received so tests can look at the checksums."""

    def __init__(self, port: int, skip_enter_message: bool = True) -> None:
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=5.0)
        self.parser = PacketParser()
        self.pending: list = []
        self.raw = b""
        if skip_enter_message:
            assert isinstance(parse_tmsct(self.receive().data), NodeEntered)

    def send_raw(self, raw: bytes) -> None:
        self.sock.sendall(raw)

    def receive(self) -> Packet:
        while not self.pending:
            chunk = self.sock.recv(65536)
            assert chunk, "the fake closed the connection"
            self.raw += chunk
            self.pending += self.parser.feed(chunk)
        item = self.pending.pop(0)
        assert isinstance(item, Packet), item
        return item

    def script(self, script_id: str, script: str) -> str:
        self.send_raw(script_packet(script_id, script).encode())
        return self.receive().data


@pytest.fixture
def link(fake: FakeListenNode) -> Iterator[Link]:
    connection = Link(fake.listen_port)
    yield connection
    connection.sock.close()


def test_a_new_client_first_hears_the_enter_node_message(fake: FakeListenNode) -> None:
    link = Link(fake.listen_port, skip_enter_message=False)
    assert link.receive() == Packet("TMSCT", "0,Listen1")
    fake.enter_listen_node()  # the flow passes through the node again
    assert link.receive() == Packet("TMSCT", "0,Listen1")
    link.sock.close()


def test_good_scripts_are_answered_ok_per_id(fake: FakeListenNode, link: Link) -> None:
    assert link.script("a1", "StopAndClearBuffer()") == "a1,OK"
    assert link.script("a2", "ContinueVLine(300,2000)") == "a2,OK"
    assert fake.velocity_mode
    assert fake.violations == []
    assert fake.scripts == ["StopAndClearBuffer()", "ContinueVLine(300,2000)"]
    assert link.raw.endswith(b"$TMSCT,5,a2,OK,*3f\r\n")  # lower-case checksum digits


def test_lower_case_checksums_from_the_client_are_accepted(
    fake: FakeListenNode, link: Link
) -> None:
    raw = encode_packet("TMSCT", "8,StopAndClearBuffer()", lowercase=True)
    assert raw.endswith(b",*6e\r\n")  # upper case would be *6E
    link.send_raw(raw)
    assert link.receive() == Packet("TMSCT", "8,OK")
    assert fake.violations == []


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
    assert link.script("3", "ContinueVLine(300,2000)\r\nSetContinueVLine(1,0,0)") == "3,ERROR;2"
    assert not fake.velocity_mode  # a refused script runs none of its lines
    reply = link.script("4", "ContinueVLine(300,2000)\r\nSetContinueVLine(10,0,0,0,0,0)")
    assert reply == "4,OK"
    assert link.script("5", 'PTP("JPP",0,0,0,0,0,0,10,200,0,false)') == "5,ERROR;1"
    assert fake.violations == []  # script errors are answers, not protocol violations
    assert len(fake.script_errors) == 4


def test_velocity_is_integrated_into_the_tcp(fake: FakeListenNode, link: Link) -> None:
    start = fake.tcp_wire()
    link.script("1", "ContinueVLine(300,2000)\r\nSetContinueVLine(100,0,-50,0,0,0)")
    time.sleep(0.2)
    link.script("2", "StopContinueVmode()")
    assert wait_until(lambda: not np.any(fake.measured_velocity))
    moved = fake.tcp_wire() - start
    assert 5.0 < moved[0] < 60.0
    assert moved[2] == pytest.approx(-moved[0] / 2, rel=1e-6)
    np.testing.assert_allclose(moved[3:], 0.0, atol=1e-9)
    assert fake.velocity_mode_exits[-1][1] == "StopContinueVmode"


def test_joint_move_and_queue_tag(fake: FakeListenNode, link: Link) -> None:
    reply = link.script("1", 'PTP("JPP",9,0,0,0,0,-9,50,200,0,false)\r\nQueueTag(3)')
    assert reply == "1,OK"
    link.send_raw(encode_packet("TMSTA", "01,3"))
    assert link.receive() == Packet("TMSTA", "01,03,false")
    assert wait_until(lambda: fake.tag_status(3) == "true")  # 9 deg at 90 deg/s
    link.send_raw(encode_packet("TMSTA", "01,3"))
    assert link.receive() == Packet("TMSTA", "01,03,true")
    np.testing.assert_allclose(fake.q_deg, [9, 0, 0, 0, 0, -9])
    link.send_raw(encode_packet("TMSTA", "01,7"))
    assert link.receive() == Packet("TMSTA", "01,07,none")


def test_line_move_reaches_the_pose(fake: FakeListenNode, link: Link) -> None:
    assert (
        link.script("1", 'Line("CAP",420,10,400,180,0,90,200,100,0,false)\r\nQueueTag(1)') == "1,OK"
    )
    assert wait_until(lambda: fake.tag_status(1) == "true")
    np.testing.assert_allclose(fake.tcp_wire()[:3], [420, 10, 400], atol=1e-6)


def test_fault_stops_motion_and_refuses_scripts(fake: FakeListenNode, link: Link) -> None:
    link.script("1", "ContinueVLine(300,2000)\r\nSetContinueVLine(50,0,0,0,0,0)")
    fake.inject_fault(3)
    assert link.script("2", "SetContinueVLine(50,0,0,0,0,0)") == "2,ERROR;1"
    before = fake.tcp_wire()
    time.sleep(0.05)
    np.testing.assert_allclose(fake.tcp_wire(), before)
    assert fake.state_items()["Error_Code"] == 3


@pytest.mark.parametrize("mode", [SvrMode.BINARY, SvrMode.JSON])
def test_status_and_state_push(mode: SvrMode) -> None:
    with FakeListenNode(state_mode=mode) as fake:
        link = Link(fake.listen_port)
        link.send_raw(encode_packet("TMSTA", "00"))
        assert link.receive() == Packet("TMSTA", "00,true,Listen1")
        state = Link(fake.state_port, skip_enter_message=False)
        packet = state.receive()
        assert packet.header == "TMSVR" and split_frame(packet.payload).mode is mode
        assert state.raw[-4:-2] == state.raw[-4:-2].lower()
        items = read_items(packet.payload)
        assert items is not None
        assert items["Coord_Robot_Tool"] == pytest.approx([400, 0, 400, 180, 0, 90])
        assert items["Robot_Error"] is False and items["TCP_Speed3D"] == 0.0
        assert items["TCP_Speed"] == [0.0] * 6
        state.sock.close()
        link.sock.close()


def test_the_fake_binds_the_ports_it_is_given() -> None:
    with FakeListenNode() as first:
        ports = (first.listen_port, first.state_port)
    with FakeListenNode(listen_port=ports[0], state_port=ports[1]) as fake:
        assert (fake.listen_port, fake.state_port) == ports
        assert fake.spec == f"tm:127.0.0.1?listen_port={ports[0]}&state_port={ports[1]}"


def test_the_command_line_fake_prints_its_spec_and_summary(capsys) -> None:
    assert main(["--seconds", "0.2", "--json"]) == 0
    spec, summary = capsys.readouterr().out.strip().splitlines()
    assert spec.startswith("tm:127.0.0.1?listen_port=")
    assert '"protocol_violations": 0' in summary and '"velocity_mode_entries": 0' in summary


def test_joint_moves_update_the_tcp_through_fk() -> None:
    def fk(q_deg: np.ndarray) -> np.ndarray:
        return np.array([300.0 + q_deg[0], 0.0, 500.0, 180.0, 0.0, 0.0])

    with FakeListenNode(fk=fk) as node:
        link = Link(node.listen_port)
        link.script("1", 'PTP("JPP",20,0,0,0,0,0,100,200,0,false)\r\nQueueTag(2)')
        assert wait_until(lambda: node.tag_status(2) == "true")
        np.testing.assert_allclose(node.tcp_wire()[:3], [320.0, 0.0, 500.0])
        link.sock.close()
