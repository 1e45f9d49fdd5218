"""Tests for the binary wire protocol: encoding, decoding, CRC, COBS and the stream decoder."""

from __future__ import annotations

import struct
import zlib

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from wovenskin.skin.layout import ChannelOrder
from wovenskin.skin.messages import (
    AckMessage,
    AckStatus,
    CommandId,
    CommandMessage,
    DecodeError,
    FrameMessage,
    InfoMessage,
    LogMessage,
    MessageType,
    ProtocolError,
    SampleDtype,
    dequantize,
    flags_to_order,
    order_to_flags,
    quantize,
)
from wovenskin.skin.protocol import (
    StreamDecoder,
    cobs_frame,
    decode_packet,
    encode_message,
    pack_message,
    unpack_message,
)

ORDERS = [
    ChannelOrder(m, fr, fc) for m in ("row", "col") for fr in (False, True) for fc in (False, True)
]


def _decode_wire(wire: bytes, scale: float = 1.0):
    assert wire.endswith(b"\x00") and wire.count(0) == 1
    return decode_packet(wire[:-1], scale)


def _with_crc(payload: bytes) -> bytes:
    return payload + struct.pack("<I", zlib.crc32(payload))


def _header(mtype: int, seq: int = 3, t_us: int = 99, version: int = 1) -> bytes:
    return struct.pack("<BBIQ", version, mtype, seq, t_us)


def _frame(seq: int = 1, rows: int = 10, cols: int = 10, seed: int = 0) -> FrameMessage:
    rng = np.random.default_rng(seed)
    samples = (20 + rng.standard_normal(rows * cols)).astype(np.float32)
    return FrameMessage(seq, 5000 * seq, rows, cols, samples)


def _reason(packet: bytes, scale: float = 1.0) -> str:
    with pytest.raises(ProtocolError) as info:
        decode_packet(packet, scale)
    return info.value.reason


# ---------------------------------------------------------------- the documented bytes


def test_frame_encoding_matches_the_worked_example_in_the_docs():
    msg = FrameMessage(7, 35000, 2, 2, np.array([20.0, 20.5, 21.25, 19.75], np.float32))
    assert pack_message(msg).hex(" ").upper() == (
        "01 01 07 00 00 00 B8 88 00 00 00 00 00 00 02 02 03 00 00 A0 41 00 00 A4 41 "
        "00 00 AA 41 00 00 9E 41 A8 6A 87 7A"
    )
    assert encode_message(msg).hex(" ").upper() == (
        "04 01 01 07 01 01 03 B8 88 01 01 01 01 01 04 02 02 03 01 03 A0 41 01 03 A4 41 "
        "01 03 AA 41 01 07 9E 41 A8 6A 87 7A 00"
    )


def test_info_encoding_matches_the_worked_example_in_the_docs():
    info = InfoMessage(
        firmware="skin-fw 1.2.0",
        device_id="S3-0001",
        dtype=SampleDtype.U16,
        scale=0.001,
        channel_order=ChannelOrder.parse("col-major,flip-rows"),
    )
    assert pack_message(info).hex().upper() == (
        "0102000000000000000000000000010D736B696E2D667720312E322E300753332D303030310A0A"
        "0000484301036F12833A02704600006041000020415FDF1C02"
    )


def test_crc_is_ieee_crc32():
    assert zlib.crc32(b"123456789") == 0xCBF43926


# ---------------------------------------------------------------- round trips


float32s = st.floats(width=32, allow_nan=False, allow_infinity=False)


@st.composite
def frame_messages(draw, dtype=None):
    rows = draw(st.integers(1, 16))
    cols = draw(st.integers(1, 16))
    seq = draw(st.integers(0, 2**32 - 1))
    t_us = draw(st.integers(0, 2**64 - 1))
    dtype = dtype or draw(st.sampled_from(list(SampleDtype)))
    if dtype is SampleDtype.F32:
        samples = draw(hnp.arrays(np.float32, rows * cols, elements=float32s))
        scale = 1.0
    else:
        scale = draw(st.sampled_from([1.0, 0.5, 1e-3, 2.0**-10]))
        # float32 holds every integer up to 2**24: beyond that counts are rounded (tested below).
        top = 2**16 - 1 if dtype is SampleDtype.U16 else 2**24
        counts = draw(hnp.arrays(np.int64, rows * cols, elements=st.integers(0, top)))
        samples = dequantize(counts.astype(dtype.numpy), scale)
    return FrameMessage(seq, t_us, rows, cols, samples, dtype, scale)


@given(frame_messages())
def test_frame_round_trip_is_bit_exact(msg):
    out = _decode_wire(encode_message(msg), msg.scale)
    assert isinstance(out, FrameMessage)
    assert (out.seq, out.device_t_us, out.rows, out.cols, out.dtype) == (
        msg.seq,
        msg.device_t_us,
        msg.rows,
        msg.cols,
        msg.dtype,
    )
    assert out.samples.dtype == np.float32
    np.testing.assert_array_equal(out.samples.view(np.uint32), msg.samples.view(np.uint32))


def test_large_u32_counts_decode_to_the_nearest_float32():
    counts = np.array([2**32 - 1, 2**24 + 1], "<u4")
    payload = _with_crc(_header(MessageType.FRAME) + b"\x01\x02\x02" + counts.tobytes())
    out = unpack_message(payload, scale=0.5)
    np.testing.assert_array_equal(out.samples, np.float32([(2**32 - 1) * 0.5, (2**24 + 1) * 0.5]))


@given(
    st.builds(
        InfoMessage,
        seq=st.integers(0, 2**32 - 1),
        device_t_us=st.integers(0, 2**64 - 1),
        firmware=st.text(max_size=60),
        device_id=st.text(max_size=60),
        rows=st.integers(1, 255),
        cols=st.integers(1, 255),
        sample_rate_hz=st.floats(1.0, 1e5, width=32),
        dtype=st.sampled_from(list(SampleDtype)),
        channel_order=st.sampled_from(ORDERS),
        scale=st.floats(2.0**-30, 1024.0, width=32),
        units=st.sampled_from(["pF", "fF", "counts", "µF"]),
        row_pitch_mm=st.floats(0.125, 100.0, width=32),
        col_pitch_mm=st.floats(0.125, 100.0, width=32),
    )
)
def test_info_round_trip(info):
    assert _decode_wire(encode_message(info)) == info


@given(
    st.one_of(
        st.builds(
            AckMessage,
            st.integers(0, 2**32 - 1),
            st.integers(0, 2**64 - 1),
            st.integers(0, 255),
            st.integers(0, 255),
        ),
        st.builds(LogMessage, st.integers(0, 2**32 - 1), st.integers(0, 2**64 - 1), st.text()),
        st.builds(
            CommandMessage,
            st.integers(0, 2**32 - 1),
            st.integers(0, 2**64 - 1),
            st.integers(0, 255),
        ),
    )
)
def test_ack_log_and_command_round_trip(msg):
    assert _decode_wire(encode_message(msg)) == msg


def test_info_builds_skin_info_and_layout():
    info = InfoMessage(
        firmware="fw 2",
        device_id="abc",
        rows=6,
        cols=8,
        sample_rate_hz=250.0,
        channel_order=ChannelOrder("col", True, False),
        row_pitch_mm=12.0,
        col_pitch_mm=9.0,
    )
    skin = info.to_skin_info(source="serial:/dev/x")
    assert (skin.rows, skin.cols, skin.sample_rate_hz) == (6, 8, 250.0)
    assert skin.channel_order == "col-major,flip-rows"
    assert ChannelOrder.parse(skin.channel_order) == info.channel_order
    assert (skin.firmware, skin.device_id, skin.source) == ("fw 2", "abc", "serial:/dev/x")
    assert info.layout.shape == (6, 8) and info.layout.row_pitch_mm == 12.0


@pytest.mark.parametrize("order", ORDERS)
def test_channel_order_flags_round_trip(order):
    assert flags_to_order(order_to_flags(order)) == order


def test_integer_frames_are_scaled_to_physical_units():
    counts = np.array([0, 1, 20000, 65535], np.uint16)
    msg = FrameMessage(0, 0, 2, 2, dequantize(counts, 0.001), SampleDtype.U16, 0.001)
    wire = encode_message(msg)
    out = _decode_wire(wire, scale=0.001)
    np.testing.assert_allclose(out.samples, [0.0, 0.001, 20.0, 65.535], rtol=1e-6)
    raw = _decode_wire(wire, scale=1.0)
    np.testing.assert_array_equal(raw.samples, counts.astype(np.float32))


def test_quantize_rejects_values_outside_the_count_range():
    with pytest.raises(ValueError, match="U16"):
        quantize(np.array([70.0]), SampleDtype.U16, 0.001)
    with pytest.raises(ValueError, match="U16"):
        quantize(np.array([-1.0]), SampleDtype.U16, 1.0)


def test_encoder_rejects_inconsistent_messages():
    with pytest.raises(ValueError, match="samples"):
        encode_message(FrameMessage(0, 0, 2, 2, np.zeros(3, np.float32)))
    with pytest.raises(ValueError, match="seq"):
        encode_message(FrameMessage(2**32, 0, 1, 1, np.zeros(1, np.float32)))
    with pytest.raises(ValueError, match="rows"):
        encode_message(FrameMessage(0, 0, 0, 1, np.zeros(0, np.float32)))
    with pytest.raises(TypeError):
        encode_message("hello")  # type: ignore[arg-type]


# ---------------------------------------------------------------- rejection reasons


@given(st.data())
def test_any_single_bit_flip_is_caught_by_the_crc(data):
    msg = data.draw(st.one_of(frame_messages(SampleDtype.F32), st.just(InfoMessage())))
    payload = bytearray(pack_message(msg))
    bit = data.draw(st.integers(0, len(payload) * 8 - 1))
    payload[bit // 8] ^= 1 << (bit % 8)
    assert _reason(cobs_frame(payload)[:-1]) == "crc"


def test_truncated_packets_are_rejected():
    payload = pack_message(_frame())
    for cut in (1, 5, 17, len(payload) - 1):
        assert _reason(cobs_frame(payload[:cut])[:-1]) in {"truncated", "crc"}
    assert _reason(cobs_frame(payload[:10])[:-1]) == "truncated"


def test_invalid_cobs_and_empty_packets_are_rejected():
    assert _reason(b"\x05\x01") == "cobs"
    assert _reason(b"") == "empty"


def test_body_errors_have_precise_reasons_and_keep_the_sequence_number():
    frame_body = struct.pack("<BBB", 1, 2, 3) + np.array([1, 2], "<f4").tobytes()
    cases = {
        "version": _with_crc(_header(MessageType.FRAME, version=2) + frame_body),
        "type": _with_crc(_header(9) + frame_body),
        "dtype": _with_crc(_header(MessageType.FRAME) + b"\x01\x02\x07" + bytes(8)),
        "shape": _with_crc(_header(MessageType.FRAME) + b"\x00\x02\x03"),
        "truncated": _with_crc(_header(MessageType.FRAME) + frame_body[:-1]),
        "length": _with_crc(_header(MessageType.FRAME) + frame_body + b"\x01"),
        "nonfinite": _with_crc(
            _header(MessageType.FRAME) + b"\x01\x02\x03" + np.array([1, np.inf], "<f4").tobytes()
        ),
    }
    for reason, payload in cases.items():
        with pytest.raises(ProtocolError) as info:
            unpack_message(payload)
        assert info.value.reason == reason, (reason, info.value)
        if reason not in ("version",):
            assert info.value.seq == 3 and info.value.device_t_us == 99


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_nonfinite_frames_are_rejected(bad):
    msg = _frame(seq=11)
    msg.samples[17] = bad
    with pytest.raises(ProtocolError) as info:
        _decode_wire(encode_message(msg))
    assert info.value.reason == "nonfinite"
    assert info.value.seq == 11 and info.value.msg_type == MessageType.FRAME


def test_invalid_info_fields_are_rejected():
    good = pack_message(InfoMessage())[:-4]
    body = bytearray(good[14:])
    # Layout: version(1) fw(1+0) id(1+0) rows cols rate(4) dtype order scale(4) units(1+2) pitches
    offsets = {"rows": 3, "rate": 5, "dtype": 9, "order": 10, "scale": 11}
    cases = [
        ("shape", "rows", b"\x00"),
        ("value", "rate", struct.pack("<f", -1.0)),
        ("value", "rate", struct.pack("<f", float("nan"))),
        ("dtype", "dtype", b"\x09"),
        ("order", "order", b"\x08"),
        ("value", "scale", struct.pack("<f", 0.0)),
    ]
    for reason, name, value in cases:
        patched = bytearray(body)
        at = offsets[name]
        patched[at : at + len(value)] = value
        with pytest.raises(ProtocolError) as info:
            unpack_message(_with_crc(bytes(good[:14]) + bytes(patched)))
        assert info.value.reason == reason, (name, info.value)
    with pytest.raises(ProtocolError, match="trailing"):
        unpack_message(_with_crc(bytes(good) + b"\x00"))
    bad_utf8 = bytes(good[:14]) + b"\x01\x02\xff\xfe" + bytes(body[2:])
    with pytest.raises(ProtocolError) as info:
        unpack_message(_with_crc(bad_utf8))
    assert info.value.reason == "utf8"


def test_ack_and_command_bodies_must_have_their_exact_length():
    for mtype, body in ((MessageType.ACK, b"\x01"), (MessageType.COMMAND, b"\x01\x02")):
        with pytest.raises(ProtocolError) as info:
            unpack_message(_with_crc(_header(mtype) + body))
        assert info.value.reason == "length"
    ack = AckMessage(4, 1, CommandId.STOP, AckStatus.BUSY)
    assert not _decode_wire(encode_message(ack)).ok


# ---------------------------------------------------------------- stream decoder


def _chunks(data: bytes, cuts: list[int]) -> list[bytes]:
    points = sorted({c % (len(data) + 1) for c in cuts})
    bounds = [0, *points, len(data)]
    return [data[a:b] for a, b in zip(bounds, bounds[1:], strict=False)]


def _feed_all(decoder: StreamDecoder, chunks: list[bytes]) -> list:
    out = []
    for chunk in chunks:
        out.extend(decoder.feed(chunk))
    return out


@settings(max_examples=300)
@given(st.binary(max_size=3000), st.lists(st.integers(0, 3000), max_size=20))
def test_random_bytes_never_raise_from_the_stream_decoder(data, cuts):
    decoder = StreamDecoder(max_packet_bytes=1024)
    items = _feed_all(decoder, _chunks(data, cuts))
    for item in items:
        assert isinstance(
            item,
            DecodeError | FrameMessage | InfoMessage | AckMessage | LogMessage | CommandMessage,
        )
        if isinstance(item, DecodeError):
            assert item.reason != "internal", item


@settings(max_examples=200)
@given(
    frame_messages(SampleDtype.F32),
    st.binary(max_size=600),
    st.binary(max_size=600),
    st.lists(st.integers(0, 5000), max_size=12),
)
def test_a_frame_between_garbage_is_recovered_intact(msg, before, after, cuts):
    stream = before + b"\x00" + encode_message(msg) + after
    items = _feed_all(StreamDecoder(), _chunks(stream, cuts))
    frames = [i for i in items if isinstance(i, FrameMessage)]
    assert any(
        f.seq == msg.seq
        and f.device_t_us == msg.device_t_us
        and (f.rows, f.cols) == (msg.rows, msg.cols)
        and np.array_equal(f.samples.view(np.uint32), msg.samples.view(np.uint32))
        for f in frames
    )


@given(st.lists(st.integers(0, 20000), max_size=30))
def test_many_frames_survive_any_chunking(cuts):
    msgs = [_frame(seq=i, seed=i) for i in range(40)]
    stream = b"\x00\x00".join(encode_message(m) for m in msgs)
    frames = _feed_all(StreamDecoder(), _chunks(stream, cuts))
    assert [f.seq for f in frames] == list(range(40))
    for f, m in zip(frames, msgs, strict=True):
        np.testing.assert_array_equal(f.samples, m.samples)


def test_oversize_garbage_is_reported_once_and_dropped():
    decoder = StreamDecoder(max_packet_bytes=1000)
    items = decoder.feed(b"\x07" * 600)
    items += decoder.feed(b"\x07" * 600)  # now over the limit
    items += decoder.feed(b"\x07" * 5000)  # still inside the same run
    items += decoder.feed(b"\x07" * 10 + b"\x00" + encode_message(_frame(seq=5)))
    errors = [i for i in items if isinstance(i, DecodeError)]
    frames = [i for i in items if isinstance(i, FrameMessage)]
    assert [e.reason for e in errors] == ["oversize"]
    assert [f.seq for f in frames] == [5]
    too_long = StreamDecoder(max_packet_bytes=1000).feed(b"\x07" * 1500 + b"\x00")
    assert [e.reason for e in too_long] == ["oversize"]


def test_stream_decoder_takes_its_scale_from_info():
    decoder = StreamDecoder()
    counts = np.array([20000, 21000], np.uint16)
    frame = FrameMessage(0, 0, 1, 2, dequantize(counts, 0.001), SampleDtype.U16, 0.001)
    info = InfoMessage(rows=1, cols=2, dtype=SampleDtype.U16, scale=0.001)
    before, _, after = decoder.feed(
        encode_message(frame) + encode_message(info) + encode_message(frame)
    )
    np.testing.assert_array_equal(before.samples, counts.astype(np.float32))
    np.testing.assert_allclose(after.samples, [20.0, 21.0], rtol=1e-6)
    assert decoder.scale == pytest.approx(0.001)


def test_stream_decoder_reports_bad_packets_and_goes_on():
    bad_crc = bytearray(pack_message(_frame(seq=1)))
    bad_crc[20] ^= 0xFF
    nan_frame = _frame(seq=2)
    nan_frame.samples[0] = np.nan
    stream = (
        b"\x00ESP-ROM:esp32s3-20210327\r\n\x00"
        + encode_message(_frame(seq=0))
        + cobs_frame(bad_crc)
        + encode_message(nan_frame)
        + b"\x00\x00\x00"
        + encode_message(_frame(seq=3))
    )
    items = StreamDecoder().feed(bytearray(stream))
    kinds = [i.reason if isinstance(i, DecodeError) else i.seq for i in items]
    assert kinds[1:] == [0, "crc", "nonfinite", 3]
    assert kinds[0] in {"cobs", "crc", "truncated"}
    assert StreamDecoder().feed(b"") == []
