"""The record layer of a ``.wsrec`` file: magic line, record framing with CRC, FRAMES blocks.

A file is the magic line then ``record*``, each ``SYNC(4) type(u8) length(u32 LE)
payload crc32(u32 LE)`` with the CRC over type, length and payload
(``docs/recording-format.md``).  :func:`pack_record` writes one; :func:`iter_records`
reads the intact ones back, resyncing past damage on the SYNC marker.
"""

from __future__ import annotations

import struct
import zlib
from collections.abc import Iterator
from enum import IntEnum

import numpy as np

from wovenskin.recording.untrusted import WSREC_MAGIC_PREFIX

FORMAT_VERSION = 1
MAGIC_PREFIX = WSREC_MAGIC_PREFIX
MAGIC = MAGIC_PREFIX + str(FORMAT_VERSION).encode() + b"\n"
SYNC = b"\xa7WR\x5e"
MAX_PAYLOAD_BYTES = 1 << 28
LABEL_KIND_TRIAL = "trial"
MAX_CHANNELS_PER_SIDE = 0xFFFF  # FRAMES store rows and cols as u16
MAX_FRAMES_PER_RECORD = 1024

_RECORD_HEAD = struct.Struct("<4sBI")  # sync, type, payload length
_CRC = struct.Struct("<I")
_FRAMES_HEAD = struct.Struct("<IHH")  # frame count, rows, cols


class RecordType(IntEnum):
    HEADER = 1
    FRAMES = 2
    CALIBRATION = 3
    LABEL = 4
    ANNOTATION = 5
    FOOTER = 6


def pack_record(rtype: RecordType, payload: bytes) -> bytes:
    """The bytes of one record: head, ``payload`` and the CRC over type, length, payload."""
    if len(payload) > MAX_PAYLOAD_BYTES:
        raise ValueError(f"{rtype.name} record of {len(payload)} bytes is too large")
    head = _RECORD_HEAD.pack(SYNC, int(rtype), len(payload))
    crc = zlib.crc32(payload, zlib.crc32(head[len(SYNC) :]))
    return head + payload + _CRC.pack(crc)


def pack_frames(
    seq: np.ndarray, t: np.ndarray, device_t_us: np.ndarray, values: np.ndarray
) -> bytes:
    """The payload of a FRAMES record: count and grid, then each column in turn."""
    n, rows, cols = values.shape
    return b"".join(
        (
            _FRAMES_HEAD.pack(n, rows, cols),
            seq.astype("<i8").tobytes(),
            t.astype("<f8").tobytes(),
            device_t_us.astype("<i8").tobytes(),
            values.astype("<f4").tobytes(),
        )
    )


def unpack_frames(payload: memoryview, rows: int, cols: int) -> tuple[np.ndarray, ...]:
    if len(payload) < _FRAMES_HEAD.size:
        raise ValueError("shorter than its header")
    n, block_rows, block_cols = _FRAMES_HEAD.unpack_from(payload)
    if (block_rows, block_cols) != (rows, cols):
        raise ValueError(f"frames are {block_rows}x{block_cols}, the skin is {rows}x{cols}")
    if len(payload) != _FRAMES_HEAD.size + n * (24 + 4 * rows * cols):
        raise ValueError(f"length does not match {n} frames")
    offset = _FRAMES_HEAD.size
    seq = np.frombuffer(payload, "<i8", n, offset)
    t = np.frombuffer(payload, "<f8", n, offset + 8 * n)
    device_t_us = np.frombuffer(payload, "<i8", n, offset + 16 * n)
    values = np.frombuffer(payload, "<f4", n * rows * cols, offset + 24 * n)
    return seq, t, device_t_us, values.reshape(n, rows, cols)


def iter_records(
    data: bytes, pos: int, warnings: list[str]
) -> Iterator[tuple[int, int, memoryview]]:
    """Yield ``(offset, type, payload)`` of intact records, resyncing past damage."""
    while pos < len(data):
        record = record_at(data, pos)
        if record is not None:
            yield pos, record[0], record[1]
            pos = record[2]
            continue
        resume = _next_record(data, pos + 1)
        if resume is None:
            lost = len(data) - pos
            if extends_past_end(data, pos):
                warnings.append(
                    f"cut off at byte {pos}: lost the last {lost} bytes (the writer did not finish)"
                )
            else:
                warnings.append(f"corrupt data from byte {pos} to the end: lost {lost} bytes")
            return
        warnings.append(f"skipped {resume - pos} corrupt bytes at byte {pos}")
        pos = resume


def record_at(data: bytes, pos: int) -> tuple[int, memoryview, int] | None:
    """``(type, payload, next_pos)`` of a complete record with a good CRC at ``pos``."""
    body = pos + _RECORD_HEAD.size
    if body + _CRC.size > len(data):
        return None
    sync, rtype, length = _RECORD_HEAD.unpack_from(data, pos)
    end = body + length + _CRC.size
    if sync != SYNC or length > MAX_PAYLOAD_BYTES or end > len(data):
        return None
    view = memoryview(data)
    if zlib.crc32(view[pos + len(SYNC) : body + length]) != _CRC.unpack_from(data, end - 4)[0]:
        return None
    return rtype, view[body : body + length], end


def _next_record(data: bytes, start: int) -> int | None:
    pos = data.find(SYNC, start)
    while pos >= 0:
        if record_at(data, pos) is not None:
            return pos
        pos = data.find(SYNC, pos + 1)
    return None


def extends_past_end(data: bytes, pos: int) -> bool:
    """True where the bytes at ``pos`` could be the start of a record cut off by the EOF."""
    head = data[pos : pos + _RECORD_HEAD.size]
    if len(head) < _RECORD_HEAD.size:
        return SYNC.startswith(head[: len(SYNC)])
    sync, _, length = _RECORD_HEAD.unpack(head)
    return sync == SYNC and length <= MAX_PAYLOAD_BYTES and pos + len(head) + length + 4 > len(data)
