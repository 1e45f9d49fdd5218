"""Tests for the Ethernet Slave data table: the TMSVR envelope, binary and JSON modes, and
the checks on the items the backend reads."""

from __future__ import annotations

import math
import struct

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wovenskin.robots.techman.ethernet_slave import (
    REQUIRED_ITEMS,
    SvrMode,
    decode_binary,
    encode_binary,
    read_items,
    read_state,
    split_frame,
    state_packet,
)
from wovenskin.robots.techman.protocol import PacketError, decode_packet


def item(name: str, value: bytes) -> bytes:
    """One binary item as Techman's driver lays it out: u16 name length, name, u16 value
    length, value (little-endian), built here by hand, independently of encode_binary."""
    raw = name.encode("latin-1")
    return struct.pack("<H", len(raw)) + raw + struct.pack("<H", len(value)) + value


def floats(*values: float) -> bytes:
    return struct.pack(f"<{len(values)}f", *values)


GOOD_TABLE = (
    item("Robot_Link", b"\x01")
    + item("Robot_Error", b"\x00")
    + item("Project_Run", b"\x01")
    + item("Error_Code", struct.pack("<i", 0))
    + item("Joint_Angle", floats(0, -10, 90, 0, 90, 0))
    + item("Coord_Robot_Tool", floats(518, -122, 321, 180, 0, 90))
    + item("TCP_Speed", floats(0, 50, 0, 0, 0, 10))
    + item("TCP_Speed3D", floats(50))
    + item("Stick_PlayPause", b"\x00")  # an item this client does not know: skipped
    + item("Error_Content", b"")
)


def test_a_hand_built_binary_table_is_read() -> None:
    items = decode_binary(GOOD_TABLE)
    assert "Stick_PlayPause" not in items and "Error_Content" not in items
    assert items["Robot_Error"] is False and items["Error_Code"] == 0
    assert items["TCP_Speed3D"] == pytest.approx(50.0)  # one number, mm/s
    state = read_state(items)
    np.testing.assert_allclose(state.joint_deg, [0, -10, 90, 0, 90, 0])
    np.testing.assert_allclose(state.tool_wire, [518, -122, 321, 180, 0, 90])
    np.testing.assert_allclose(state.tcp_speed, [0, 50, 0, 0, 0, 10])  # six values, TCP_Speed
    assert state.tcp_speed3d == pytest.approx(50.0) and state.linear_speed_mm_s == 50.0
    assert state.project_run is True and state.estop is None


def test_a_pushed_binary_frame_round_trips_through_the_packet() -> None:
    raw = b"$TMSVR," + str(len(b"42,1," + GOOD_TABLE)).encode() + b",42,1," + GOOD_TABLE + b","
    body = raw[1:]
    cs = 0
    for byte in body:
        cs ^= byte
    raw += b"*%02x\r\n" % cs  # lower case, as Techman's driver writes it
    frame = split_frame(decode_packet(raw).payload)
    assert (frame.transaction_id, frame.mode) == ("42", SvrMode.BINARY)
    assert read_items(decode_packet(raw).payload) == decode_binary(GOOD_TABLE)


@pytest.mark.parametrize("mode", [SvrMode.BINARY, SvrMode.JSON])
def test_state_packets_round_trip_in_both_modes(mode: SvrMode) -> None:
    items = {
        "Joint_Angle": [1.5, 2, 3, 4, 5, 6],
        "Robot_Error": True,
        "Error_Code": 7,
        "TCP_Speed3D": 12.5,
    }
    packet = decode_packet(state_packet("12", items, mode).encode())
    assert split_frame(packet.payload).mode is mode
    assert read_items(packet.payload) == items


def test_json_content_is_an_item_list() -> None:
    content = b'[{"Item":"Joint_Angle","Value":[1,2,3,4,5,6]},{"Item":"Robot_Error","Value":false}]'
    assert read_items(b"9,3," + content) == {
        "Joint_Angle": [1, 2, 3, 4, 5, 6],
        "Robot_Error": False,
    }
    with pytest.raises(PacketError, match="item list"):
        read_items(b"9,3,{not json")
    with pytest.raises(PacketError, match="item list"):
        read_items(b'9,3,[{"Name":"x"}]')


def test_modes_other_than_binary_and_json() -> None:
    assert split_frame(b"r1,13,[]").mode is SvrMode.READ_JSON  # two-digit modes
    assert read_items(b"w1,0,00,OK") is None  # a write response: nothing to read
    with pytest.raises(PacketError, match="string mode"):
        read_items(b"9,2,Joint_Angle=1")
    for bad in (b"9,7,x", b"9,x,1", b"nomode", b",1,abc"):
        with pytest.raises(PacketError):
            split_frame(bad)


@pytest.mark.parametrize(
    ("content", "words"),
    [
        (GOOD_TABLE[:-3], "ends inside"),
        (b"\x05", "ends inside the length"),
        (item("Joint_Angle", floats(1, 2, 3, 4, 5)), "has 20 bytes, expected 24"),
        (item("Error_Code", b"\x00\x00"), "has 2 bytes, expected 4"),
        (item("J\xffnt", b""), "non-ASCII"),
        (item("", b""), "bad item name"),
    ],
)
def test_corrupt_binary_tables_are_one_line_errors(content: bytes, words: str) -> None:
    with pytest.raises(PacketError, match=words) as info:
        decode_binary(content)
    assert "\n" not in str(info.value)


def good_items() -> dict[str, object]:
    return decode_binary(GOOD_TABLE)


@pytest.mark.parametrize(
    ("name", "value", "words"),
    [
        ("Joint_Angle", [0, 0, math.nan, 0, 0, 0], "non-finite"),
        ("Coord_Robot_Tool", [0, 0, math.inf, 0, 0, 0], "non-finite"),
        ("TCP_Speed", 42.0, "is not 6 numbers"),  # TCP_Speed3D's shape in TCP_Speed's place
        ("TCP_Speed", [1, 2, 3], "is not 6 numbers"),
        ("Joint_Angle", ["a", 0, 0, 0, 0, 0], "is not 6 numbers"),
        ("Joint_Angle", [True, 0, 0, 0, 0, 0], "is not 6 numbers"),
        ("Robot_Error", "no", "true/false"),
        ("Robot_Error", 2, "true/false"),
        ("Error_Code", 1.5, "integer"),
        ("Error_Code", None, "integer"),
        ("TCP_Speed3D", [1, 2, 3, 4, 5, 6], "one finite number"),
        ("TCP_Speed3D", math.nan, "one finite number"),
    ],
)
def test_bad_items_are_named_in_one_line(name: str, value: object, words: str) -> None:
    items = good_items()
    items[name] = value
    with pytest.raises(PacketError, match=words) as info:
        read_state(items)
    assert name in str(info.value) and "\n" not in str(info.value)


def test_missing_items_are_listed() -> None:
    items = good_items()
    for name in ("TCP_Speed", "Error_Code"):
        del items[name]
    with pytest.raises(PacketError, match="lacks TCP_Speed, Error_Code"):
        read_state(items)
    assert set(REQUIRED_ITEMS) <= set(good_items())


def test_json_flags_may_be_zero_or_one() -> None:
    items = good_items()
    items["Robot_Error"] = 1
    assert read_state(items).robot_error is True


def test_encode_binary_refuses_unknown_items_and_wrong_sizes() -> None:
    with pytest.raises(PacketError, match="no binary type"):
        encode_binary({"Teleport": 1})
    with pytest.raises(PacketError, match="needs 6 values"):
        encode_binary({"Joint_Angle": [1, 2]})
    assert encode_binary({"Error_Content": b"abc"}) == item("Error_Content", b"abc")


@settings(max_examples=200, deadline=None)
@given(st.binary(max_size=120))
def test_random_bytes_never_crash_the_reader(content: bytes) -> None:
    for mode in (b"1", b"3"):
        try:
            items = read_items(b"1," + mode + b"," + content)
            read_state(items or {})
        except PacketError as exc:
            assert "\n" not in str(exc)
