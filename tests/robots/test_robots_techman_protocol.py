"""Tests for the Techman packet format: checksums, round trips and the streaming parser."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wovenskin.robots.base import Pose
from wovenskin.robots.techman.protocol import (
    CommError,
    NodeEntered,
    Packet,
    PacketError,
    PacketParser,
    ScriptReply,
    call,
    checksum,
    decode_packet,
    encode_packet,
    format_number,
    parse_comm_error,
    parse_script_reply,
    parse_tmsct,
    pose_from_wire,
    pose_to_wire,
    script_packet,
)

# Packets as printed in Techman's Listen Node documentation.
VECTORS = [
    (b"$TMSTA,2,00,*41\r\n", Packet("TMSTA", "00")),
    (b"$TMSCT,4,1,OK,*5C\r\n", Packet("TMSCT", "1,OK")),
]


@pytest.mark.parametrize(("raw", "packet"), VECTORS)
def test_known_packets_encode_and_decode(raw: bytes, packet: Packet) -> None:
    assert packet.encode() == raw
    assert decode_packet(raw) == packet


def test_lower_case_checksums_are_read_and_can_be_written() -> None:
    # Techman's ROS driver formats the checksum with std::hex: lower-case digits.
    assert decode_packet(b"$TMSCT,4,1,OK,*5c\r\n") == Packet("TMSCT", "1,OK")
    assert Packet("TMSCT", "1,OK").encode(lowercase=True) == b"$TMSCT,4,1,OK,*5c\r\n"
    assert encode_packet("TMSTA", "00", lowercase=True) == b"$TMSTA,2,00,*41\r\n"
    wrong = b"$TMSCT,4,1,OK,*5d\r\n"
    with pytest.raises(PacketError, match="checksum 5D, computed 5C"):
        decode_packet(wrong)


def test_binary_data_is_framed_by_length_and_kept_as_bytes() -> None:
    payload = b"7,1,\x0b\x00Joint_Angle\x18\x00" + bytes(range(200, 224))
    raw = encode_packet("TMSVR", payload)
    assert raw.startswith(b"$TMSVR,%d," % len(payload))
    packet = decode_packet(raw)
    assert packet.payload == payload
    with pytest.raises(PacketError, match="not text"):
        _ = packet.data


def test_checksum_is_xor_of_bytes() -> None:
    assert checksum(b"") == 0
    assert checksum(b"\x0f\xf0") == 0xFF
    assert checksum(b"AA") == 0


def test_length_counts_utf8_bytes() -> None:
    raw = encode_packet("TMSCT", '1,Display("µ")')
    assert raw.startswith(b"$TMSCT,15,")
    assert decode_packet(raw).data == '1,Display("µ")'


text = st.text(st.characters(codec="utf-8", exclude_categories=["Cs"]), max_size=60)


@settings(max_examples=80, deadline=None)
@given(st.sampled_from(["TMSCT", "TMSTA", "CPERR", "TMSVR"]), text)
def test_round_trip_and_checksum_property(header: str, data: str) -> None:
    raw = encode_packet(header, data)
    body = raw[1 : raw.index(b"*", len(raw) - 6)]
    assert checksum(body) == int(raw[-4:-2], 16)
    assert raw[-4:-2] == raw[-4:-2].upper()
    assert decode_packet(raw) == Packet(header, data)


@settings(max_examples=60, deadline=None)
@given(st.lists(text, min_size=1, max_size=5), st.integers(1, 7))
def test_parser_splits_stream_fed_in_pieces(datas: list[str], piece: int) -> None:
    stream = b"".join(encode_packet("TMSCT", d) for d in datas)
    parser = PacketParser()
    out = []
    for i in range(0, len(stream), piece):
        out += parser.feed(stream[i : i + piece])
    assert out == [Packet("TMSCT", d) for d in datas]
    assert parser.pending == 0


def test_data_with_trailer_like_bytes_is_framed_by_length() -> None:
    data = '1,a=2*3\r\nDisplay("$x,*41")'
    assert decode_packet(encode_packet("TMSCT", data)).data == data


def corrupt_cases() -> list[tuple[bytes, CommError, str]]:
    good = encode_packet("TMSCT", "7,StopAndClearBuffer()")
    flipped = good[:-4] + (b"00" if good[-4:-2] != b"00" else b"01") + b"\r\n"
    return [
        (flipped, CommError.CHECKSUM, "checksum"),
        (b"$TMSCT,4,1,OK,*5g\r\n", CommError.PACKET, "trailer"),
        (good.replace(b",22,", b",21,"), CommError.PACKET, "LENGTH 21"),
        (good.replace(b",22,", b",23,"), CommError.PACKET, "LENGTH 23"),
        (good.replace(b",22,", b",2x,"), CommError.PACKET, "not a number"),
        (b"$TMSXX,2,00,*" + b"%02X\r\n" % checksum(b"TMSXX,2,00,"), CommError.HEADER, "header"),
        (b"junk" + good, CommError.PACKET, "stray"),
    ]


@pytest.mark.parametrize(("raw", "code", "words"), corrupt_cases())
def test_corrupt_packets_give_one_line_errors(raw: bytes, code: CommError, words: str) -> None:
    items = PacketParser().feed(raw)
    errors = [item for item in items if isinstance(item, PacketError)]
    assert errors, items
    assert errors[0].code is code
    assert words in str(errors[0])
    assert "\n" not in str(errors[0])


@pytest.mark.parametrize(("raw", "_code", "_words"), corrupt_cases())
def test_parser_recovers_after_corrupt_packet(raw: bytes, _code: CommError, _words: str) -> None:
    follow = encode_packet("TMSTA", "00")
    items = PacketParser().feed(raw + follow)
    assert items[-1] == Packet("TMSTA", "00")
    assert any(isinstance(item, PacketError) for item in items)


def test_decode_rejects_incomplete_and_extra() -> None:
    good = encode_packet("TMSTA", "00")
    with pytest.raises(PacketError, match="incomplete"):
        decode_packet(good[:-3])
    with pytest.raises(PacketError, match="expected one packet"):
        decode_packet(good + good)


def test_encode_rejects_unknown_header() -> None:
    with pytest.raises(PacketError, match="unknown packet header"):
        encode_packet("HELLO", "x")


def test_script_replies() -> None:
    assert parse_script_reply("3,OK") == ScriptReply("3", True)
    assert parse_script_reply("3,OK;2") == ScriptReply("3", True, (2,))  # OK with a warning
    assert parse_script_reply("9,ERROR;1;3") == ScriptReply("9", False, (1, 3))
    assert ScriptReply("9", False, (1, 3)).to_packet().data == "9,ERROR;1;3"
    with pytest.raises(PacketError):
        parse_script_reply("9,MAYBE")
    with pytest.raises(PacketError):
        parse_script_reply("OK")


def test_the_enter_node_message_is_not_a_script_reply() -> None:
    # The flow entering the Listen Node sends TMSCT data "0,<node name>".
    assert parse_tmsct("0,Listen1") == NodeEntered("Listen1")
    assert NodeEntered("Listen1").to_packet() == Packet("TMSCT", "0,Listen1")
    assert parse_tmsct("0,OK") == ScriptReply("0", True)  # an answer to a script with id 0
    assert parse_tmsct("12,ERROR;1") == ScriptReply("12", False, (1,))
    with pytest.raises(PacketError, match="no node name"):
        parse_tmsct("0,")
    with pytest.raises(PacketError, match="neither OK nor ERROR"):
        parse_tmsct("5,Listen1")


def test_comm_errors_explain_themselves_in_one_line() -> None:
    for code in CommError:
        assert "\n" not in code.explain() and code.explain()
    assert "Listen Node" in CommError.NOT_IN_LISTEN_NODE.explain()
    assert "F1" in CommError.NOT_IN_LISTEN_NODE.explain()


def test_script_packet_and_comm_errors() -> None:
    assert script_packet("4", "QueueTag(1)").data == "4,QueueTag(1)"
    with pytest.raises(PacketError):
        script_packet("a,b", "x()")
    assert parse_comm_error("02") is CommError.CHECKSUM
    assert parse_comm_error("f1") is CommError.NOT_IN_LISTEN_NODE
    with pytest.raises(PacketError):
        parse_comm_error("77")


def test_call_formats_script_arguments() -> None:
    line = call("PTP", "JPP", 1.5, -0.0, 35, 200, 0, False)
    assert line == 'PTP("JPP",1.5,0,35,200,0,false)'
    assert format_number(1e-9) == "0"
    assert format_number(-12.3456) == "-12.346"
    assert "e" not in format_number(1e-5, decimals=6)


def test_wire_pose_uses_fixed_axis_xyz_degrees() -> None:
    # 90 deg about base Z: x axis -> y axis.
    pose = pose_from_wire([100.0, -50.0, 300.0, 0.0, 0.0, 90.0])
    np.testing.assert_allclose(pose.position, [0.1, -0.05, 0.3])
    np.testing.assert_allclose(pose.rotation() @ [1, 0, 0], [0, 1, 0], atol=1e-12)
    # Rx then Ry about fixed axes: R = Ry(90) Rx(90) maps y -> x.
    pose = pose_from_wire([0, 0, 0, 90.0, 90.0, 0.0])
    np.testing.assert_allclose(pose.rotation() @ [0, 1, 0], [1, 0, 0], atol=1e-12)


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.floats(-1, 1), min_size=4, max_size=4),
    st.lists(st.floats(-2, 2), min_size=3, max_size=3),
)
def test_wire_pose_round_trip(quat: list[float], position: list[float]) -> None:
    if np.linalg.norm(quat) < 1e-3:
        return
    pose = Pose(np.array(position), np.array(quat))
    back = pose_from_wire(pose_to_wire(pose))
    np.testing.assert_allclose(back.position, pose.position, atol=1e-12)
    # Euler angles lose precision near gimbal lock (pitch +-90 deg): about sqrt(eps) there
    np.testing.assert_allclose(back.rotation(), pose.rotation(), atol=1e-7)


def test_wire_pose_rejects_bad_vectors() -> None:
    with pytest.raises(PacketError):
        pose_from_wire([1, 2, 3])
    with pytest.raises(PacketError):
        pose_from_wire([1, 2, 3, 4, 5, float("nan")])
