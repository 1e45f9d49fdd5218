"""The bytes of the skin wire protocol (``docs/protocol.md``): layout, COBS framing, CRC.

Encodes and decodes the messages of :mod:`wovenskin.skin.messages`; :class:`StreamDecoder`
turns an arbitrary byte stream (partial reads, line noise, boot banners, resets) into
decoded messages and :class:`DecodeError` items without ever raising.

Wire format in one paragraph: every message is ``header + body + crc32`` (all integers
and floats little-endian), COBS-encoded and followed by one ``0x00`` delimiter.  The
header is ``u8 version, u8 type, u32 seq, u64 t_us``; the CRC is IEEE CRC-32
(``zlib.crc32``) over header and body.  FRAME samples are in the device's channel order
(declared by INFO); this module never reorders them -- :class:`~wovenskin.skin.layout.ChannelOrder`
does, downstream.
"""

from __future__ import annotations

import math
import struct
import zlib

import numpy as np
from cobs import cobs

from wovenskin.skin.messages import (
    NUMPY_DTYPES,
    PROTOCOL_VERSION,
    AckMessage,
    BytesLike,
    CommandMessage,
    DecodeError,
    FrameMessage,
    InfoMessage,
    LogMessage,
    Message,
    MessageType,
    ProtocolError,
    SampleDtype,
    flags_to_order,
    order_to_flags,
    quantize,
)

DELIMITER = b"\x00"
MAX_PACKET_BYTES = 65536
"""Longest encoded message (without its delimiter) a decoder accepts: a 127x127 f32 frame."""

U32_MAX = 0xFFFFFFFF
U64_MAX = 0xFFFFFFFFFFFFFFFF

_HEADER = struct.Struct("<BBIQ")  # version, type, seq, t_us
_CRC = struct.Struct("<I")
_FRAME_HEAD = struct.Struct("<BBB")  # rows, cols, sample dtype
_ACK = struct.Struct("<BB")  # command id, status
_GRID = struct.Struct("<BB")  # rows, cols
_U8 = struct.Struct("<B")
_F32 = struct.Struct("<f")
HEADER_BYTES = _HEADER.size
CRC_BYTES = _CRC.size
MIN_MESSAGE_BYTES = HEADER_BYTES + CRC_BYTES


# --------------------------------------------------------------------------- encoding


def _pack_string(text: str) -> bytes:
    data = text.encode("utf-8")
    if len(data) > 255:
        raise ValueError(f"string longer than 255 UTF-8 bytes: {text[:20]!r}...")
    return _U8.pack(len(data)) + data


def _check_u8(name: str, value: int, low: int = 0) -> None:
    if not low <= value <= 255:
        raise ValueError(f"{name} must be in {low}..255, got {value}")


def _frame_body(msg: FrameMessage) -> bytes:
    _check_u8("rows", msg.rows, 1)
    _check_u8("cols", msg.cols, 1)
    samples = np.asarray(msg.samples).reshape(-1)
    if samples.size != msg.rows * msg.cols:
        raise ValueError(f"{msg.rows}x{msg.cols} frame needs {msg.rows * msg.cols} samples")
    dtype = SampleDtype(msg.dtype)
    raw = quantize(samples, dtype, msg.scale)
    return _FRAME_HEAD.pack(msg.rows, msg.cols, dtype) + raw.tobytes()


def _info_body(msg: InfoMessage) -> bytes:
    _check_u8("rows", msg.rows, 1)
    _check_u8("cols", msg.cols, 1)
    _check_u8("protocol_version", msg.protocol_version)
    return b"".join(
        (
            _U8.pack(msg.protocol_version),
            _pack_string(msg.firmware),
            _pack_string(msg.device_id),
            _GRID.pack(msg.rows, msg.cols),
            _F32.pack(msg.sample_rate_hz),
            _U8.pack(SampleDtype(msg.dtype)),
            _U8.pack(order_to_flags(msg.channel_order)),
            _F32.pack(msg.scale),
            _pack_string(msg.units),
            _F32.pack(msg.row_pitch_mm),
            _F32.pack(msg.col_pitch_mm),
        )
    )


def pack_message(msg: Message) -> bytes:
    """The decoded form of ``msg``: header + body + CRC-32 (before COBS framing)."""
    if isinstance(msg, FrameMessage):
        mtype, t_us, body = MessageType.FRAME, msg.device_t_us, _frame_body(msg)
    elif isinstance(msg, InfoMessage):
        mtype, t_us, body = MessageType.INFO, msg.device_t_us, _info_body(msg)
    elif isinstance(msg, AckMessage):
        _check_u8("command", msg.command)
        _check_u8("status", msg.status)
        mtype, t_us, body = MessageType.ACK, msg.device_t_us, _ACK.pack(msg.command, msg.status)
    elif isinstance(msg, LogMessage):
        text = msg.text.encode("utf-8")
        if len(text) > MAX_PACKET_BYTES // 2:
            raise ValueError(f"log text too long ({len(text)} bytes)")
        mtype, t_us, body = MessageType.LOG, msg.device_t_us, text
    elif isinstance(msg, CommandMessage):
        _check_u8("command", msg.command)
        mtype, t_us, body = MessageType.COMMAND, msg.host_t_us, _U8.pack(msg.command)
    else:
        raise TypeError(f"not a protocol message: {type(msg).__name__}")
    if not 0 <= msg.seq <= U32_MAX:
        raise ValueError(f"seq must fit in u32, got {msg.seq}")
    if not 0 <= t_us <= U64_MAX:
        raise ValueError(f"timestamp must fit in u64, got {t_us}")
    payload = _HEADER.pack(PROTOCOL_VERSION, mtype, msg.seq, t_us) + body
    return payload + _CRC.pack(zlib.crc32(payload))


def cobs_frame(payload: bytes) -> bytes:
    """COBS-encode a decoded message and append the ``0x00`` delimiter (the wire bytes)."""
    return cobs.encode(bytes(payload)) + DELIMITER


def encode_message(msg: Message) -> bytes:
    """The wire bytes of ``msg``: COBS(header + body + CRC) followed by ``0x00``."""
    return cobs_frame(pack_message(msg))


# --------------------------------------------------------------------------- decoding


class _BodyReader:
    """Sequential reads from a message body; running off the end is a ``truncated`` error."""

    __slots__ = ("body", "pos")

    def __init__(self, body: memoryview) -> None:
        self.body = body
        self.pos = 0

    def unpack(self, st: struct.Struct) -> tuple:
        end = self.pos + st.size
        if end > len(self.body):
            raise ProtocolError("truncated", "body ends inside a field")
        values = st.unpack_from(self.body, self.pos)
        self.pos = end
        return values

    def u8(self) -> int:
        return self.unpack(_U8)[0]

    def f32(self) -> float:
        return self.unpack(_F32)[0]

    def string(self) -> str:
        n = self.u8()
        end = self.pos + n
        if end > len(self.body):
            raise ProtocolError("truncated", "body ends inside a string")
        raw = bytes(self.body[self.pos : end])
        self.pos = end
        try:
            return raw.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise ProtocolError("utf8", f"string is not UTF-8 ({exc.reason})") from None

    def finish(self) -> None:
        extra = len(self.body) - self.pos
        if extra:
            raise ProtocolError("length", f"{extra} unexpected trailing bytes")


def _positive_finite(name: str, value: float) -> float:
    if not (math.isfinite(value) and value > 0):
        raise ProtocolError("value", f"{name} must be positive and finite, got {value}")
    return value


def _decode_frame(body: memoryview, seq: int, t_us: int, scale: float) -> FrameMessage:
    if len(body) < _FRAME_HEAD.size:
        raise ProtocolError("truncated", "frame body shorter than its shape")
    rows, cols, dtype_code = _FRAME_HEAD.unpack_from(body)
    np_dtype = NUMPY_DTYPES.get(dtype_code)
    if np_dtype is None:
        raise ProtocolError("dtype", f"unknown sample dtype {dtype_code}")
    if rows == 0 or cols == 0:
        raise ProtocolError("shape", f"empty {rows}x{cols} frame")
    count = rows * cols
    expected = _FRAME_HEAD.size + count * np_dtype.itemsize
    if len(body) != expected:
        reason = "truncated" if len(body) < expected else "length"
        raise ProtocolError(
            reason, f"{rows}x{cols} frame needs {expected} body bytes, got {len(body)}"
        )
    raw = np.frombuffer(body, dtype=np_dtype, count=count, offset=_FRAME_HEAD.size)
    dtype = SampleDtype(dtype_code)
    if dtype is SampleDtype.F32:
        samples = raw.astype(np.float32)  # a native-endian, writable copy
    else:
        samples = (raw.astype(np.float64) * scale).astype(np.float32)
    # A float64 sum of finite float32 values cannot overflow, so it is finite exactly
    # when every sample is: one vectorised reduction instead of isfinite + all.
    if not math.isfinite(samples.sum(dtype=np.float64)):
        raise ProtocolError("nonfinite", f"frame {seq} holds NaN or inf")
    return FrameMessage(seq, t_us, rows, cols, samples, dtype, scale)


def _decode_info(body: memoryview, seq: int, t_us: int, scale: float) -> InfoMessage:
    r = _BodyReader(body)
    version = r.u8()
    firmware = r.string()
    device_id = r.string()
    rows, cols = r.u8(), r.u8()
    rate = r.f32()
    dtype_code = r.u8()
    order_flags = r.u8()
    info_scale = r.f32()
    units = r.string()
    row_pitch, col_pitch = r.f32(), r.f32()
    r.finish()
    if version != PROTOCOL_VERSION:
        raise ProtocolError("version", f"INFO declares protocol {version}")
    if rows == 0 or cols == 0:
        raise ProtocolError("shape", f"INFO declares an empty {rows}x{cols} grid")
    if dtype_code not in NUMPY_DTYPES:
        raise ProtocolError("dtype", f"INFO declares unknown sample dtype {dtype_code}")
    return InfoMessage(
        seq=seq,
        device_t_us=t_us,
        protocol_version=version,
        firmware=firmware,
        device_id=device_id,
        rows=rows,
        cols=cols,
        sample_rate_hz=_positive_finite("sample rate", rate),
        dtype=SampleDtype(dtype_code),
        channel_order=flags_to_order(order_flags),
        scale=_positive_finite("scale", info_scale),
        units=units,
        row_pitch_mm=_positive_finite("row pitch", row_pitch),
        col_pitch_mm=_positive_finite("column pitch", col_pitch),
    )


def _decode_ack(body: memoryview, seq: int, t_us: int, scale: float) -> AckMessage:
    if len(body) != _ACK.size:
        raise ProtocolError("length", f"ACK body must be {_ACK.size} bytes, got {len(body)}")
    command, status = _ACK.unpack_from(body)
    return AckMessage(seq, t_us, command, status)


def _decode_log(body: memoryview, seq: int, t_us: int, scale: float) -> LogMessage:
    return LogMessage(seq, t_us, bytes(body).decode("utf-8", errors="replace"))


def _decode_command(body: memoryview, seq: int, t_us: int, scale: float) -> CommandMessage:
    if len(body) != 1:
        raise ProtocolError("length", f"COMMAND body must be 1 byte, got {len(body)}")
    return CommandMessage(seq, t_us, body[0])


_BODY_DECODERS = {
    MessageType.FRAME: _decode_frame,
    MessageType.INFO: _decode_info,
    MessageType.ACK: _decode_ack,
    MessageType.LOG: _decode_log,
    MessageType.COMMAND: _decode_command,
}


def unpack_message(payload: BytesLike, scale: float = 1.0) -> Message:
    """Decode header + body + CRC (already COBS-decoded); raise :class:`ProtocolError`.

    Checks, in order: length (``truncated``), CRC (``crc``), version (``version``), type
    (``type``), then the body of that type.  ``scale`` converts integer FRAME counts.
    """
    view = memoryview(payload)
    if len(view) < MIN_MESSAGE_BYTES:
        raise ProtocolError("truncated", f"{len(view)} bytes is shorter than a header and CRC")
    (crc,) = _CRC.unpack_from(view, len(view) - CRC_BYTES)
    if zlib.crc32(view[:-CRC_BYTES]) != crc:
        raise ProtocolError("crc", f"CRC mismatch over {len(view) - CRC_BYTES} bytes")
    version, mtype, seq, t_us = _HEADER.unpack_from(view)
    if version != PROTOCOL_VERSION:
        raise ProtocolError("version", f"protocol version {version}, expected {PROTOCOL_VERSION}")
    decode_body = _BODY_DECODERS.get(mtype)
    if decode_body is None:
        raise ProtocolError("type", f"unknown message type {mtype}", seq=seq, device_t_us=t_us)
    try:
        return decode_body(view[HEADER_BYTES:-CRC_BYTES], seq, t_us, scale)
    except ProtocolError as exc:
        exc.seq, exc.device_t_us, exc.msg_type = seq, t_us, mtype
        raise


def decode_packet(packet: BytesLike, scale: float = 1.0) -> Message:
    """Decode one COBS packet (the bytes between two delimiters); raise :class:`ProtocolError`."""
    if not len(packet):
        raise ProtocolError("empty", "empty packet")
    try:
        payload = cobs.decode(packet)
    except cobs.DecodeError as exc:
        raise ProtocolError("cobs", str(exc)) from None
    return unpack_message(payload, scale)


class StreamDecoder:
    """Incremental decoder for a byte stream; :meth:`feed` never raises.

    Packets may be split across :meth:`feed` calls; runs of zero bytes are delimiters.
    More than ``max_packet_bytes`` without a delimiter is reported once as ``oversize``
    and discarded up to the next delimiter.  ``scale`` (units per count for integer
    FRAME samples) follows every INFO message decoded.
    """

    def __init__(self, scale: float = 1.0, max_packet_bytes: int = MAX_PACKET_BYTES) -> None:
        self.scale = scale
        self.max_packet_bytes = max_packet_bytes
        self._pending = bytearray()
        self._discarding = False

    def reset(self) -> None:
        """Forget any partial packet (after a reconnect)."""
        self._pending = bytearray()
        self._discarding = False

    def feed(self, data: BytesLike) -> list[Message | DecodeError]:
        data = bytes(data)
        if not data:
            return []
        out: list[Message | DecodeError] = []
        if self._discarding:
            end = data.find(0)
            if end < 0:
                return out
            data = data[end + 1 :]
            self._discarding = False
        limit = self.max_packet_bytes
        if DELIMITER not in data:  # a packet still arriving: append without rescanning it
            self._pending += data
            if len(self._pending) > limit:
                self._start_discarding(out)
            return out
        buffer = bytes(self._pending) + data if self._pending else data
        packets = buffer.split(DELIMITER)
        tail = packets.pop()
        for packet in packets:
            if not packet:
                continue
            if len(packet) > limit:
                out.append(DecodeError("oversize", f"{len(packet)} bytes without a delimiter"))
                continue
            try:
                msg = decode_packet(packet, self.scale)
            except ProtocolError as exc:
                out.append(exc.to_decode_error())
                continue
            except Exception as exc:  # a decoder bug must not take down the stream
                out.append(DecodeError("internal", f"{type(exc).__name__}: {exc}"))
                continue
            if type(msg) is InfoMessage:
                self.scale = msg.scale
            out.append(msg)
        self._pending = bytearray(tail)
        if len(tail) > limit:
            self._start_discarding(out)
        return out

    def _start_discarding(self, out: list[Message | DecodeError]) -> None:
        limit = self.max_packet_bytes
        out.append(DecodeError("oversize", f"more than {limit} bytes without a delimiter"))
        self._discarding = True
        self._pending = bytearray()
