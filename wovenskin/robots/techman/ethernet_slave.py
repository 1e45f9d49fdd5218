"""The Ethernet Slave's state frames (``TMSVR``): the data table in binary or JSON mode.

TMflow's Ethernet Slave (port 5891) pushes the items of its *data table* to every
connected client. Each frame is one ``TMSVR`` packet whose DATA is ``ID,MODE,CONTENT``:
``ID`` a transaction id, ``MODE`` how ``CONTENT`` is written. The modes (Techman's
``TmSvrData::Mode``): ``0`` a response to a write (``ID,0,EC,text``), ``1`` binary,
``2`` string, ``3`` JSON, and ``11``/``12``/``13`` answers to read requests. The pushed
table comes in binary mode (the table Techman's drivers use) or in JSON mode; both are
read here, string mode is refused.

Binary content is a sequence of items, each ``u16 name length, name, u16 value length,
value``, little-endian, the value in the item's C type: ``float32`` arrays for poses and
speeds, ``int32`` for codes, one byte for flags (see :data:`ITEM_TYPES`). JSON content is
a list of ``{"Item": name, "Value": value}``. Items not in :data:`ITEM_TYPES` are
skipped (their length is in the frame).

The backend needs :data:`REQUIRED_ITEMS`; :func:`read_state` checks them (six finite
numbers, a flag, an integer) and returns a :class:`TechmanState`. Every error is a
:class:`~wovenskin.robots.techman.protocol.PacketError` with a one-line message.
Sources: docs/techman.md.
"""

from __future__ import annotations

import json
import math
import struct
from collections.abc import Mapping
from dataclasses import dataclass
from enum import IntEnum

import numpy as np

from wovenskin.io import dumps
from wovenskin.robots.techman.protocol import CommError, Packet, PacketError


class SvrMode(IntEnum):
    """The MODE field of a ``TMSVR`` packet."""

    RESPONSE = 0
    BINARY = 1
    STRING = 2
    JSON = 3
    READ_BINARY = 11
    READ_STRING = 12
    READ_JSON = 13


@dataclass(frozen=True)
class ItemType:
    """How one data-table item is written in binary mode: ``count`` values of ``kind``."""

    kind: str  # "flag" (one byte), "int32" or "float32"
    count: int = 1

    @property
    def size(self) -> int:
        """The item's value length in bytes."""
        return self.count * (1 if self.kind == "flag" else 4)


_FLAG, _INT, _FLOAT, _SIX = (
    ItemType("flag"),
    ItemType("int32"),
    ItemType("float32"),
    ItemType("float32", 6),
)

ITEM_TYPES: dict[str, ItemType] = {
    "Robot_Link": _FLAG,
    "Robot_Error": _FLAG,
    "Project_Run": _FLAG,
    "Project_Pause": _FLAG,
    "Safeguard_A": _FLAG,
    "ESTOP": _FLAG,
    "Camera_Light": _FLAG,
    "Error_Code": _INT,
    "Project_Speed": _INT,
    "MA_Mode": _INT,
    "Joint_Angle": _SIX,  # deg
    "Coord_Robot_Flange": _SIX,  # mm, deg
    "Coord_Robot_Tool": _SIX,  # mm, deg (the TCP in the robot base frame)
    "TCP_Force": ItemType("float32", 3),  # N
    "TCP_Force3D": _FLOAT,  # N
    "TCP_Speed": _SIX,  # mm/s, deg/s: the TCP's velocity vector
    "TCP_Speed3D": _FLOAT,  # mm/s: the TCP's linear speed, one number
    "Joint_Speed": _SIX,  # deg/s
    "Joint_Torque": _SIX,  # mNm
}

REQUIRED_ITEMS = ("Joint_Angle", "Coord_Robot_Tool", "TCP_Speed", "Robot_Error", "Error_Code")
_MAX_ITEMS = 256
_MODES = frozenset(int(mode) for mode in SvrMode)


# -- the TMSVR envelope ------------------------------------------------------------------


@dataclass(frozen=True)
class SvrFrame:
    """A ``TMSVR`` DATA field split into its transaction id, mode and raw content."""

    transaction_id: str
    mode: SvrMode
    content: bytes


def split_frame(payload: bytes) -> SvrFrame:
    """Split ``ID,MODE,CONTENT``; raises :class:`PacketError` when it is not that."""
    first = payload.find(b",", 0, 64)
    second = payload.find(b",", first + 1, first + 4) if first > 0 else -1
    if first <= 0 or second == -1:
        raise PacketError(f"TMSVR data {payload[:24]!r} lacks ID,MODE,", CommError.PACKET_DATA)
    mode_text = payload[first + 1 : second]
    if not mode_text.isdigit() or int(mode_text) not in _MODES:
        raise PacketError(f"TMSVR mode {mode_text!r} is unknown", CommError.PACKET_DATA)
    try:
        transaction_id = payload[:first].decode("ascii")
    except UnicodeDecodeError:
        raise PacketError("TMSVR transaction id is not text", CommError.PACKET_DATA) from None
    return SvrFrame(transaction_id, SvrMode(int(mode_text)), payload[second + 1 :])


def state_packet(
    transaction_id: str, items: Mapping[str, object], mode: SvrMode = SvrMode.BINARY
) -> Packet:
    """A pushed ``TMSVR`` frame of ``items`` in binary (default) or JSON mode."""
    if mode is SvrMode.BINARY:
        content = encode_binary(items)
    elif mode is SvrMode.JSON:
        content = encode_json(items)
    else:
        raise PacketError(f"state frames are pushed in binary or JSON mode, not {mode.name}")
    return Packet("TMSVR", f"{transaction_id},{int(mode)},".encode("ascii") + content)


def read_items(payload: bytes) -> dict[str, object] | None:
    """The items of one pushed frame, or ``None`` for a response frame (nothing to read)."""
    frame = split_frame(payload)
    if frame.mode is SvrMode.BINARY:
        return decode_binary(frame.content)
    if frame.mode is SvrMode.JSON:
        return decode_json(frame.content)
    if frame.mode is SvrMode.STRING:
        raise PacketError(
            "TMSVR frame in string mode: set the Ethernet Slave to binary or JSON",
            CommError.PACKET_DATA,
        )
    return None  # RESPONSE / READ_*: answers to requests this client never makes


# -- binary mode -------------------------------------------------------------------------


def encode_binary(items: Mapping[str, object]) -> bytes:
    """Binary content of ``items``; a ``bytes`` value is written as is (any item name)."""
    out = bytearray()
    for name, value in items.items():
        raw_name = name.encode("ascii")
        if isinstance(value, bytes | bytearray):
            raw = bytes(value)
        else:
            item = ITEM_TYPES.get(name)
            if item is None:
                raise PacketError(f"no binary type for data-table item {name!r}")
            values = np.atleast_1d(np.asarray(value, dtype=float)).ravel()
            if values.size != item.count:
                raise PacketError(f"{name} needs {item.count} values, got {values.size}")
            if item.kind == "flag":
                raw = bytes([1 if values[0] else 0])
            elif item.kind == "int32":
                raw = struct.pack("<i", int(values[0]))
            else:
                raw = struct.pack(f"<{item.count}f", *values)
        out += struct.pack("<H", len(raw_name)) + raw_name + struct.pack("<H", len(raw)) + raw
    return bytes(out)


def decode_binary(content: bytes) -> dict[str, object]:
    """The known items of binary content; raises :class:`PacketError` on a corrupt table."""
    items: dict[str, object] = {}
    offset = 0
    count = 0
    while offset < len(content):
        count += 1
        if count > _MAX_ITEMS:
            raise PacketError(f"binary data table has over {_MAX_ITEMS} items")
        name_raw, offset = _field(content, offset, "item name")
        try:
            name = name_raw.decode("ascii")
        except UnicodeDecodeError:
            raise PacketError("binary data table has a non-ASCII item name") from None
        if not name.isprintable() or not name:
            raise PacketError(f"binary data table has a bad item name {name!r}")
        value, offset = _field(content, offset, f"item {name}")
        item = ITEM_TYPES.get(name)
        if item is None:
            continue
        if len(value) != item.size:
            raise PacketError(f"binary item {name} has {len(value)} bytes, expected {item.size}")
        if item.kind == "flag":
            items[name] = value[0] != 0
        elif item.kind == "int32":
            items[name] = struct.unpack("<i", value)[0]
        else:
            numbers = list(struct.unpack(f"<{item.count}f", value))
            items[name] = numbers if item.count > 1 else numbers[0]
    return items


def _field(content: bytes, offset: int, what: str) -> tuple[bytes, int]:
    if offset + 2 > len(content):
        raise PacketError(f"binary data table ends inside the length of {what}")
    (length,) = struct.unpack_from("<H", content, offset)
    end = offset + 2 + length
    if end > len(content):
        raise PacketError(f"binary data table ends inside {what} ({length} bytes announced)")
    return content[offset + 2 : end], end


# -- JSON mode ---------------------------------------------------------------------------


def encode_json(items: Mapping[str, object]) -> bytes:
    """JSON content of ``items``: ``[{"Item": name, "Value": value}, ...]``."""
    entries = [{"Item": name, "Value": value} for name, value in items.items()]
    return dumps(entries).encode("utf-8")


def decode_json(content: bytes) -> dict[str, object]:
    """The items of JSON content; raises :class:`PacketError` when it is not an item list."""
    try:
        entries = json.loads(content.decode("utf-8"))
        return {str(entry["Item"]): entry["Value"] for entry in entries}
    except (ValueError, TypeError, KeyError) as exc:
        message = f"TMSVR JSON content is not an item list: {' '.join(str(exc).split())}"
        raise PacketError(message[:160], CommError.PACKET_DATA) from None


# -- the state the backend reads ---------------------------------------------------------


@dataclass(frozen=True)
class TechmanState:
    """The checked items of one frame, in the robot's units (mm, deg, s)."""

    joint_deg: np.ndarray  # (6,)
    tool_wire: np.ndarray  # (6,) X, Y, Z mm and RX, RY, RZ deg (Coord_Robot_Tool)
    tcp_speed: np.ndarray  # (6,) mm/s and deg/s, base frame (TCP_Speed)
    robot_error: bool
    error_code: int
    tcp_speed3d: float | None = None  # mm/s (TCP_Speed3D), when the table has it
    joint_speed_deg_s: np.ndarray | None = None  # (6,) when the table has Joint_Speed
    estop: bool | None = None
    project_run: bool | None = None

    @property
    def linear_speed_mm_s(self) -> float:
        """The TCP's linear speed: ``TCP_Speed3D`` if present, else from ``TCP_Speed``."""
        if self.tcp_speed3d is not None:
            return self.tcp_speed3d
        return float(np.linalg.norm(self.tcp_speed[:3]))


def read_state(items: Mapping[str, object]) -> TechmanState:
    """Check the items the backend needs; raises :class:`PacketError` naming the bad item."""
    missing = [name for name in REQUIRED_ITEMS if name not in items]
    if missing:
        raise PacketError(
            f"the Ethernet Slave data table lacks {', '.join(missing)} (add them in TMflow)",
            CommError.PACKET_DATA,
        )
    joint_speed = items.get("Joint_Speed")
    return TechmanState(
        joint_deg=_vector(items, "Joint_Angle", 6),
        tool_wire=_vector(items, "Coord_Robot_Tool", 6),
        tcp_speed=_vector(items, "TCP_Speed", 6),
        robot_error=_flag(items, "Robot_Error"),
        error_code=_integer(items, "Error_Code"),
        tcp_speed3d=None if "TCP_Speed3D" not in items else _scalar(items, "TCP_Speed3D"),
        joint_speed_deg_s=None if joint_speed is None else _vector(items, "Joint_Speed", 6),
        estop=_flag(items, "ESTOP") if "ESTOP" in items else None,
        project_run=_flag(items, "Project_Run") if "Project_Run" in items else None,
    )


def _bad(name: str, value: object, why: str) -> PacketError:
    shown = repr(value)
    shown = shown if len(shown) <= 60 else shown[:57] + "..."
    return PacketError(f"state item {name} = {shown} {why}", CommError.PACKET_DATA)


def _vector(items: Mapping[str, object], name: str, size: int) -> np.ndarray:
    value = items[name]
    if not isinstance(value, list | tuple | np.ndarray) or len(value) != size:
        raise _bad(name, value, f"is not {size} numbers")
    if not all(_is_number(v) for v in value):
        raise _bad(name, value, f"is not {size} numbers")
    vector = np.asarray(value, dtype=float)
    if not np.all(np.isfinite(vector)):
        raise _bad(name, value, "has non-finite values")
    return vector


def _scalar(items: Mapping[str, object], name: str) -> float:
    value = items[name]
    if isinstance(value, list | tuple) and len(value) == 1:  # a one-element array
        value = value[0]
    if not _is_number(value) or not math.isfinite(float(value)):  # type: ignore[arg-type]
        raise _bad(name, value, "is not one finite number")
    return float(value)  # type: ignore[arg-type]


def _flag(items: Mapping[str, object], name: str) -> bool:
    value = items[name]
    if isinstance(value, bool):
        return value
    if isinstance(value, int) and value in (0, 1):
        return bool(value)
    raise _bad(name, value, "is not true/false")


def _integer(items: Mapping[str, object], name: str) -> int:
    value = items[name]
    if isinstance(value, int) and not isinstance(value, bool):
        return value
    if isinstance(value, float) and value.is_integer():
        return int(value)
    raise _bad(name, value, "is not an integer")


def _is_number(value: object) -> bool:
    return isinstance(value, int | float | np.floating | np.integer) and not isinstance(value, bool)
