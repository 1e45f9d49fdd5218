"""The TMflow Listen Node / Ethernet Slave packet format: build, check and split packets.

A packet is ``$HEADER,LENGTH,DATA,*CS\\r\\n``: ``HEADER`` names the packet kind (``TMSCT``
script, ``TMSTA`` status, ``CPERR`` communication error, ``TMSVR`` Ethernet Slave data),
``LENGTH`` is the byte length of ``DATA`` as a decimal number, and ``CS`` is the XOR of
every byte between ``$`` and ``*`` (exclusive), written as two hex digits. Techman's manual
prints the checksum in upper case, its own ROS driver writes it in lower case: both are
read, and :func:`encode_packet` writes upper case unless asked otherwise. ``DATA`` is text
(UTF-8) for scripts and status, but raw bytes for an Ethernet Slave frame in binary mode;
it may hold commas, ``*`` and line breaks, so packets are delimited by ``LENGTH``, never
by searching for the trailer.

A ``TMSCT`` packet from the robot is either the answer to a script (``ID,OK`` or
``ID,ERROR;line;...``) or, with ID ``0``, the message the flow sends when it enters the
Listen Node (``0,Listen1``: the node's name). :func:`parse_tmsct` tells them apart.

This module knows the byte format and the Listen Node payloads; the Ethernet Slave data
table is :mod:`.ethernet_slave`. It opens no sockets. Errors are :class:`PacketError`
with a one-line message. Sources: docs/techman.md.
"""

from __future__ import annotations

import re
import warnings
from dataclasses import dataclass, field
from enum import Enum

import numpy as np
from scipy.spatial.transform import Rotation

from wovenskin.robots.base import Pose

LISTEN_NODE_PORT = 5890
ETHERNET_SLAVE_PORT = 5891

HEADERS = frozenset({"TMSCT", "TMSTA", "CPERR", "TMSVR"})
MAX_DATA_BYTES = 65536  # larger LENGTH fields are treated as corrupt
_MAX_HEADER_CHARS = 8
_MAX_LENGTH_DIGITS = 6
_TRAILER = re.compile(rb",\*[0-9A-Fa-f]{2}\r\n")


class CommError(Enum):
    """The codes a Listen Node answers in a ``CPERR`` packet."""

    NO_ERROR = "00"
    PACKET = "01"  # the packet's framing or LENGTH is wrong
    CHECKSUM = "02"
    HEADER = "03"
    PACKET_DATA = "04"  # the DATA field cannot be understood
    NOT_IN_LISTEN_NODE = "F1"  # the flow is not (or no longer) in a Listen Node

    def describe(self) -> str:
        """A few words for a log line."""
        return self.name.lower().replace("_", " ")

    def explain(self) -> str:
        """What the code means to a user, one line (docs/techman.md lists them)."""
        return _COMM_ERROR_MEANING[self]


_COMM_ERROR_MEANING = {
    CommError.NO_ERROR: "no error (CPERR 00)",
    CommError.PACKET: "the controller could not frame a packet (CPERR 01: LENGTH or layout)",
    CommError.CHECKSUM: "the controller found a wrong checksum (CPERR 02)",
    CommError.HEADER: "the controller does not accept that packet header (CPERR 03)",
    CommError.PACKET_DATA: "the controller could not read a packet's data (CPERR 04)",
    CommError.NOT_IN_LISTEN_NODE: (
        "the TMflow project is not in a Listen Node (CPERR F1): start the project and let "
        "its flow reach the Listen Node"
    ),
}


class PacketError(ValueError):
    """A packet that does not follow the format; ``code`` says which CPERR answers it."""

    def __init__(self, message: str, code: CommError = CommError.PACKET) -> None:
        super().__init__(message)
        self.code = code


@dataclass(frozen=True, init=False)
class Packet:
    """One packet: its header and its DATA field (``payload``: the bytes on the wire)."""

    header: str
    payload: bytes

    def __init__(self, header: str, data: str | bytes) -> None:
        raw = data.encode("utf-8") if isinstance(data, str) else bytes(data)
        object.__setattr__(self, "header", header)
        object.__setattr__(self, "payload", raw)

    @property
    def data(self) -> str:
        """DATA as text; raises :class:`PacketError` when it is not UTF-8 (binary frames)."""
        try:
            return self.payload.decode("utf-8")
        except UnicodeDecodeError:
            message = f"{self.header} packet data is not text"
            raise PacketError(message, CommError.PACKET_DATA) from None

    def encode(self, lowercase: bool = False) -> bytes:
        """The packet's bytes on the wire (``lowercase``: the checksum's hex digits)."""
        return encode_packet(self.header, self.payload, lowercase=lowercase)


def checksum(body: bytes) -> int:
    """XOR of all bytes of ``body`` (the bytes between ``$`` and ``*``)."""
    value = 0
    for byte in body:
        value ^= byte
    return value


def encode_packet(header: str, data: str | bytes, *, lowercase: bool = False) -> bytes:
    """Build ``$HEADER,LENGTH,DATA,*CS\\r\\n``; raises :class:`PacketError` on a bad header.

    ``data`` is text (sent as UTF-8) or raw bytes; ``lowercase`` writes the checksum as
    Techman's ROS driver does (``*5c``) instead of the manual's ``*5C``.
    """
    if header not in HEADERS:
        raise PacketError(f"unknown packet header {header!r}", CommError.HEADER)
    payload = data.encode("utf-8") if isinstance(data, str) else bytes(data)
    if len(payload) > MAX_DATA_BYTES:
        raise PacketError(f"packet data of {len(payload)} bytes exceeds {MAX_DATA_BYTES}")
    body = header.encode("ascii") + b"," + str(len(payload)).encode("ascii") + b","
    body += payload + b","
    digits = f"{checksum(body):02x}" if lowercase else f"{checksum(body):02X}"
    return b"$" + body + b"*" + digits.encode("ascii") + b"\r\n"


def decode_packet(raw: bytes) -> Packet:
    """Check and decode exactly one complete packet; raises :class:`PacketError`."""
    parser = PacketParser()
    items = parser.feed(raw)
    if parser.pending:
        items.append(PacketError(f"incomplete packet ({parser.pending} bytes left over)"))
    if len(items) != 1:
        errors = [item for item in items if isinstance(item, PacketError)]
        if errors:
            raise errors[0]
        raise PacketError(f"expected one packet, found {len(items)}")
    item = items[0]
    if isinstance(item, PacketError):
        raise item
    return item


@dataclass
class PacketParser:
    """Splits a byte stream into packets; a corrupt packet becomes a :class:`PacketError`.

    ``feed`` returns packets and errors in stream order. After an error the parser skips to
    the end of the corrupt packet (its trailer) or, failing that, to the next ``$``.
    """

    _buffer: bytearray = field(default_factory=bytearray)

    @property
    def pending(self) -> int:
        """Bytes held back waiting for the rest of a packet."""
        return len(self._buffer)

    def feed(self, chunk: bytes) -> list[Packet | PacketError]:
        """Add ``chunk`` and return every packet (or error) completed by it."""
        self._buffer += chunk
        out: list[Packet | PacketError] = []
        while self._buffer:
            result = self._next()
            if result is None:
                break
            out.append(result)
        return out

    def _drop(self, count: int) -> None:
        del self._buffer[:count]

    def _skip_corrupt(self, start: int) -> None:
        """Drop the corrupt packet: through its trailer if one follows, else to the next '$'."""
        buf = bytes(self._buffer)
        trailer = _TRAILER.search(buf, start)
        next_dollar = buf.find(b"$", start)
        if trailer is not None and (next_dollar == -1 or trailer.start() < next_dollar):
            self._drop(trailer.end())
        elif next_dollar != -1:
            self._drop(next_dollar)
        else:
            self._drop(len(buf))

    def _next(self) -> Packet | PacketError | None:
        buf = bytes(self._buffer)
        if buf[0:1] != b"$":
            start = buf.find(b"$")
            junk = len(buf) if start == -1 else start
            self._drop(junk)
            return PacketError(f"{junk} stray bytes outside any packet")
        header_end = buf.find(b",", 1, 2 + _MAX_HEADER_CHARS)
        if header_end == -1:
            if len(buf) < 2 + _MAX_HEADER_CHARS and b"$" not in buf[1:]:
                return None
            self._skip_corrupt(1)
            return PacketError("packet header is missing or too long", CommError.HEADER)
        header = buf[1:header_end].decode("ascii", errors="replace")
        length_end = buf.find(b",", header_end + 1, header_end + 2 + _MAX_LENGTH_DIGITS)
        if length_end == -1:
            if len(buf) < header_end + 2 + _MAX_LENGTH_DIGITS and b"$" not in buf[1:]:
                return None
            self._skip_corrupt(1)
            return PacketError(f"{header} packet has no LENGTH field")
        length_text = buf[header_end + 1 : length_end]
        if not length_text.isdigit():
            self._skip_corrupt(1)
            return PacketError(f"{header} packet LENGTH {length_text!r} is not a number")
        length = int(length_text)
        if length > MAX_DATA_BYTES:
            self._skip_corrupt(1)
            return PacketError(f"{header} packet LENGTH {length} exceeds {MAX_DATA_BYTES}")
        data_start = length_end + 1
        data_end = data_start + length
        packet_end = data_end + 6  # ",*CS\r\n"
        if len(buf) < packet_end:
            early = _TRAILER.search(buf, data_start)
            if early is not None and (early.end() == len(buf) or buf[early.end()] == 0x24):
                self._drop(early.end())
                actual = early.start() - data_start
                return PacketError(f"{header} packet LENGTH {length} but data has {actual} bytes")
            return None
        trailer = buf[data_end:packet_end]
        if _TRAILER.fullmatch(trailer) is None:
            found = _TRAILER.search(buf, data_start)
            self._skip_corrupt(1)
            if found is not None:
                actual = found.start() - data_start
                return PacketError(f"{header} packet LENGTH {length} but data has {actual} bytes")
            return PacketError(f"{header} packet trailer {trailer!r} is not ',*CS\\r\\n'")
        self._drop(packet_end)
        expected = checksum(buf[1 : data_end + 1])
        received = int(trailer[2:4], 16)
        if expected != received:
            return PacketError(
                f"{header} packet checksum {received:02X}, computed {expected:02X}",
                CommError.CHECKSUM,
            )
        if header not in HEADERS:
            return PacketError(f"unknown packet header {header!r}", CommError.HEADER)
        return Packet(header, buf[data_start:data_end])


# -- payload layouts -----------------------------------------------------------------------


def script_packet(script_id: str, script: str) -> Packet:
    """A ``TMSCT`` packet running ``script`` (lines joined by CR LF) under ``script_id``."""
    if not script_id or "," in script_id or not script_id.isprintable():
        raise PacketError(f"bad script id {script_id!r}", CommError.PACKET_DATA)
    return Packet("TMSCT", f"{script_id},{script}")


@dataclass(frozen=True)
class ScriptReply:
    """The robot's answer to a ``TMSCT`` packet: ``ID,OK`` or ``ID,ERROR;line;line``.

    ``lines`` are the script lines the answer names (1-based): the failing lines of an
    ``ERROR``; an ``OK`` may name lines too (warnings), which are kept but not an error.
    """

    script_id: str
    ok: bool
    error_lines: tuple[int, ...] = ()

    def to_packet(self) -> Packet:
        """The ``TMSCT`` packet carrying this reply."""
        lines = "".join(f";{n}" for n in self.error_lines)
        return Packet("TMSCT", f"{self.script_id},{'OK' if self.ok else 'ERROR'}{lines}")


ENTER_NODE_ID = "0"  # the script ID of the message the flow sends on entering the node


@dataclass(frozen=True)
class NodeEntered:
    """The flow entered a Listen Node: ``TMSCT`` data ``0,NAME`` (``NAME``: the node's name)."""

    node: str

    def to_packet(self) -> Packet:
        """The ``TMSCT`` packet the controller sends for it."""
        return Packet("TMSCT", f"{ENTER_NODE_ID},{self.node}")


def parse_script_reply(data: str) -> ScriptReply:
    """Read a ``TMSCT`` reply's DATA; raises :class:`PacketError` when it is neither form."""
    script_id, sep, verdict = data.partition(",")
    if not sep or not script_id:
        raise PacketError(f"script reply {data[:60]!r} has no id", CommError.PACKET_DATA)
    word, *numbers = verdict.split(";")
    if word in ("OK", "ERROR") and all(n.strip().isdigit() for n in numbers):
        return ScriptReply(script_id, word == "OK", tuple(int(n) for n in numbers))
    message = f"script reply {data[:60]!r} is neither OK nor ERROR"
    raise PacketError(message, CommError.PACKET_DATA)


def parse_tmsct(data: str) -> ScriptReply | NodeEntered:
    """Read a ``TMSCT`` packet from the robot: a script's answer or the enter-node message."""
    script_id, sep, rest = data.partition(",")
    if script_id == ENTER_NODE_ID and sep and rest.split(";")[0] not in ("OK", "ERROR"):
        if not rest.strip() or not rest.isprintable():
            raise PacketError(f"enter-node message {data[:60]!r} has no node name")
        return NodeEntered(rest)
    return parse_script_reply(data)


def parse_comm_error(data: str) -> CommError:
    """Read a ``CPERR`` packet's DATA (a two-character code)."""
    for code in CommError:
        if code.value == data.strip().upper():
            return code
    raise PacketError(f"unknown CPERR code {data!r}", CommError.PACKET_DATA)


def status_packet(subcommand: str, *args: str) -> Packet:
    """A ``TMSTA`` packet: ``00`` asks whether the Listen Node runs, ``01,TAG`` a tag's state."""
    return Packet("TMSTA", ",".join((subcommand, *args)))


def split_status(data: str) -> tuple[str, list[str]]:
    """Split a ``TMSTA`` DATA field into its subcommand and arguments."""
    subcommand, *args = data.split(",")
    if len(subcommand) != 2:
        raise PacketError(f"status data {data!r} has no subcommand", CommError.PACKET_DATA)
    return subcommand, args


def format_number(value: float, decimals: int = 3) -> str:
    """A number as the robot's script language reads it (fixed point, no exponent)."""
    text = f"{value:.{decimals}f}"
    if "." in text:
        text = text.rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def call(function: str, *args: float | int | str | bool) -> str:
    """One script line ``function(arg,...)``; strings are quoted, floats fixed-point."""
    parts = []
    for arg in args:
        if isinstance(arg, bool):
            parts.append("true" if arg else "false")
        elif isinstance(arg, str):
            parts.append(f'"{arg}"')
        elif isinstance(arg, int):
            parts.append(str(arg))
        else:
            parts.append(format_number(float(arg)))
    return f"{function}({','.join(parts)})"


# -- units on the wire ---------------------------------------------------------------------


def pose_to_wire(pose: Pose) -> list[float]:
    """``[X, Y, Z, RX, RY, RZ]`` in mm and degrees, TM's fixed-axis X-Y-Z Euler angles."""
    rotation = Rotation.from_quat(pose.quat[[1, 2, 3, 0]])
    with warnings.catch_warnings():  # at gimbal lock any valid angle triple will do
        warnings.simplefilter("ignore", UserWarning)
        angles = rotation.as_euler("xyz", degrees=True)
    return [*(np.asarray(pose.position) * 1000.0).tolist(), *angles.tolist()]


def pose_from_wire(values: object) -> Pose:
    """The inverse of :func:`pose_to_wire`; raises :class:`PacketError` on a bad vector."""
    vector = np.asarray(values, dtype=float)
    if vector.shape != (6,) or not np.all(np.isfinite(vector)):
        raise PacketError(f"pose {values!r} is not six finite numbers", CommError.PACKET_DATA)
    quat_xyzw = Rotation.from_euler("xyz", vector[3:], degrees=True).as_quat()
    return Pose(vector[:3] / 1000.0, quat_xyzw[[3, 0, 1, 2]])
