"""The messages of the skin wire protocol (``docs/protocol.md``) in decoded form.

Message and sample types, the commands and ACK codes, the INFO channel-order flags, the
decoded messages themselves, :class:`DecodeError` / :class:`ProtocolError` for what cannot
be decoded, and the conversion of samples to and from integer counts.  The bytes on the
wire are :mod:`wovenskin.skin.protocol`'s business.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import IntEnum

import numpy as np

from wovenskin.errors import DataError
from wovenskin.skin.frames import SkinInfo
from wovenskin.skin.layout import (
    DEFAULT_COL_PITCH_MM,
    DEFAULT_COLS,
    DEFAULT_ROW_PITCH_MM,
    DEFAULT_ROWS,
    DEFAULT_SAMPLE_RATE_HZ,
    ROW_MAJOR,
    ChannelOrder,
    SkinLayout,
)

PROTOCOL_VERSION = 1

BytesLike = bytes | bytearray | memoryview


class MessageType(IntEnum):
    """The ``type`` byte of the header."""

    FRAME = 1
    INFO = 2
    ACK = 3
    LOG = 4
    COMMAND = 5


class SampleDtype(IntEnum):
    """How FRAME samples are stored; integer types are counts, scaled by INFO's ``scale``."""

    U16 = 1
    U32 = 2
    F32 = 3

    @property
    def numpy(self) -> np.dtype:
        return NUMPY_DTYPES[self]

    @property
    def is_integer(self) -> bool:
        return self is not SampleDtype.F32


NUMPY_DTYPES: dict[int, np.dtype] = {
    SampleDtype.U16: np.dtype("<u2"),
    SampleDtype.U32: np.dtype("<u4"),
    SampleDtype.F32: np.dtype("<f4"),
}


class CommandId(IntEnum):
    """Host-to-device commands.  START/STOP/RECALIBRATE are ACKed; GET_INFO is answered by INFO."""

    START = 1
    STOP = 2
    RECALIBRATE = 3
    GET_INFO = 4


class AckStatus(IntEnum):
    """The ``status`` byte of an ACK; anything but ``OK`` is an error code."""

    OK = 0
    UNKNOWN_COMMAND = 1
    BUSY = 2
    FAILED = 3


# Channel-order flags byte of INFO.
ORDER_COL_MAJOR = 0x01
ORDER_FLIP_ROWS = 0x02
ORDER_FLIP_COLS = 0x04
_ORDER_KNOWN_BITS = ORDER_COL_MAJOR | ORDER_FLIP_ROWS | ORDER_FLIP_COLS


def order_to_flags(order: ChannelOrder) -> int:
    """The INFO channel-order byte for ``order``."""
    return (
        (ORDER_COL_MAJOR if order.major == "col" else 0)
        | (ORDER_FLIP_ROWS if order.flip_rows else 0)
        | (ORDER_FLIP_COLS if order.flip_cols else 0)
    )


def flags_to_order(flags: int) -> ChannelOrder:
    """The :class:`ChannelOrder` an INFO channel-order byte declares."""
    if flags & ~_ORDER_KNOWN_BITS:
        raise ProtocolError("order", f"unknown channel-order bits 0x{flags:02x}")
    return ChannelOrder(
        "col" if flags & ORDER_COL_MAJOR else "row",
        bool(flags & ORDER_FLIP_ROWS),
        bool(flags & ORDER_FLIP_COLS),
    )


# --------------------------------------------------------------------------- messages


@dataclass(eq=False, slots=True)
class FrameMessage:
    """One skin sample: ``rows * cols`` float32 values in device channel order, physical units.

    ``dtype`` and ``scale`` say how the samples travel on the wire: integer dtypes carry
    ``round(value / scale)`` counts (``scale`` = units per count, from INFO); F32 ignores
    ``scale``.
    """

    seq: int
    device_t_us: int
    rows: int
    cols: int
    samples: np.ndarray
    dtype: SampleDtype = SampleDtype.F32
    scale: float = 1.0


@dataclass(slots=True)
class InfoMessage:
    """What the device says about itself (sent at boot and in answer to GET_INFO)."""

    seq: int = 0
    device_t_us: int = 0
    protocol_version: int = PROTOCOL_VERSION
    firmware: str = ""
    device_id: str = ""
    rows: int = DEFAULT_ROWS
    cols: int = DEFAULT_COLS
    sample_rate_hz: float = DEFAULT_SAMPLE_RATE_HZ
    dtype: SampleDtype = SampleDtype.F32
    channel_order: ChannelOrder = field(default_factory=lambda: ROW_MAJOR)
    scale: float = 1.0
    units: str = "pF"
    row_pitch_mm: float = DEFAULT_ROW_PITCH_MM
    col_pitch_mm: float = DEFAULT_COL_PITCH_MM

    @property
    def layout(self) -> SkinLayout:
        return SkinLayout(self.rows, self.cols, self.row_pitch_mm, self.col_pitch_mm)

    def to_skin_info(self, source: str = "") -> SkinInfo:
        return SkinInfo(
            rows=self.rows,
            cols=self.cols,
            sample_rate_hz=float(self.sample_rate_hz),
            firmware=self.firmware,
            protocol_version=self.protocol_version,
            device_id=self.device_id,
            channel_order=str(self.channel_order),
            units=self.units,
            source=source,
            row_pitch_mm=float(self.row_pitch_mm),
            col_pitch_mm=float(self.col_pitch_mm),
        )


@dataclass(slots=True)
class AckMessage:
    """The device's answer to a COMMAND; the header ``seq`` echoes the command's ``seq``."""

    seq: int
    device_t_us: int
    command: int
    status: int = AckStatus.OK

    @property
    def ok(self) -> bool:
        return self.status == AckStatus.OK


@dataclass(slots=True)
class LogMessage:
    """Free text from the firmware (diagnostics); never affects the stream."""

    seq: int
    device_t_us: int
    text: str


@dataclass(slots=True)
class CommandMessage:
    """A host-to-device command; ``host_t_us`` is the host's clock, informational only."""

    seq: int
    host_t_us: int
    command: int


Message = FrameMessage | InfoMessage | AckMessage | LogMessage | CommandMessage


@dataclass(slots=True)
class DecodeError:
    """A packet (or line) that could not be decoded: ``reason`` is a short stable keyword.

    ``seq``/``device_t_us``/``msg_type`` are set when the header was intact (its CRC
    matched), so a consumer can still account for the sequence number of a rejected frame.
    """

    reason: str
    detail: str = ""
    seq: int | None = None
    device_t_us: int | None = None
    msg_type: int | None = None

    def __str__(self) -> str:
        return f"{self.reason}: {self.detail}" if self.detail else self.reason


class ProtocolError(DataError):
    """Raised by :func:`~wovenskin.skin.protocol.decode_packet` (a ``ValueError``);
    ``reason`` is a short keyword such as ``"crc"``."""

    def __init__(
        self,
        reason: str,
        detail: str = "",
        *,
        seq: int | None = None,
        device_t_us: int | None = None,
        msg_type: int | None = None,
    ) -> None:
        super().__init__(f"{reason}: {detail}" if detail else reason)
        self.reason = reason
        self.detail = detail
        self.seq = seq
        self.device_t_us = device_t_us
        self.msg_type = msg_type

    def to_decode_error(self) -> DecodeError:
        return DecodeError(self.reason, self.detail, self.seq, self.device_t_us, self.msg_type)


# --------------------------------------------------------------------------- samples


def quantize(values: np.ndarray, dtype: SampleDtype, scale: float = 1.0) -> np.ndarray:
    """Physical values to the wire representation of ``dtype`` (counts for integer types)."""
    values = np.asarray(values)
    if not dtype.is_integer:
        return values.astype("<f4")
    if not (math.isfinite(scale) and scale > 0):
        raise ValueError(f"scale must be a positive finite number, got {scale}")
    counts = np.rint(values.astype(np.float64) / scale)
    info = np.iinfo(dtype.numpy)
    if counts.size and not (np.all(np.isfinite(counts)) and info.min <= counts.min()):
        raise ValueError(f"values do not fit {dtype.name} counts at scale {scale}")
    if counts.size and counts.max() > info.max:
        raise ValueError(f"values do not fit {dtype.name} counts at scale {scale}")
    return counts.astype(dtype.numpy)


def dequantize(raw: np.ndarray, scale: float = 1.0) -> np.ndarray:
    """Wire samples to float32 physical values (integer counts times ``scale``)."""
    if raw.dtype.kind == "f":
        return raw.astype(np.float32)
    return (raw.astype(np.float64) * scale).astype(np.float32)
