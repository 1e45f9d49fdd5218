"""Builders of hostile data files: valid checksums and zip structure, crafted contents.

Used by ``test_recording_hostile.py``: each builder returns the bytes of a file that passes
the outer checks (CRC-32 of every ``.wsrec`` record, a well-formed zip) so that the
readers' inner validation is what gets tested.
"""

from __future__ import annotations

import io
import json
import struct
import zipfile
import zlib

import numpy as np

from wovenskin.recording.documents import encode_document
from wovenskin.recording.records import MAGIC, SYNC, RecordType
from wovenskin.skin.frames import SkinInfo


def record(rtype: int, payload: bytes) -> bytes:
    """One ``.wsrec`` record with a correct CRC."""
    head = struct.pack("<4sBI", SYNC, rtype, len(payload))
    crc = zlib.crc32(payload, zlib.crc32(head[4:]))
    return head + payload + struct.pack("<I", crc)


def document(text: bytes | str, tail: bytes = b"") -> bytes:
    """A document payload: the JSON envelope ``text`` verbatim, then raw array bytes."""
    text = text.encode() if isinstance(text, str) else text
    return struct.pack("<I", len(text)) + text + tail


def header(info: object = None, **fields: object) -> bytes:
    """A HEADER document (a default skin unless ``info`` is given; ``fields`` override)."""
    doc = {
        "format": "wovenskin.wsrec",
        "format_version": 1,
        "info": SkinInfo(rows=2, cols=2).to_dict() if info is None else info,
        "provenance": {},
        "settings": {},
        **fields,
    }
    return encode_document(doc)


def frames_payload(n: int = 3, rows: int = 2, cols: int = 2, t0: float = 0.0) -> bytes:
    """A valid FRAMES payload of ``n`` frames at 100 Hz."""
    return b"".join(
        (
            struct.pack("<IHH", n, rows, cols),
            np.arange(n, dtype="<i8").tobytes(),
            (t0 + np.arange(n) / 100.0).astype("<f8").tobytes(),
            np.full(n, -1, dtype="<i8").tobytes(),
            np.ones(n * rows * cols, dtype="<f4").tobytes(),
        )
    )


def wsrec(header_payload: bytes, *records: tuple[int, bytes]) -> bytes:
    """A whole ``.wsrec`` file: magic line, the HEADER, then ``(type, payload)`` records."""
    body = b"".join(record(rtype, payload) for rtype, payload in records)
    return MAGIC + record(RecordType.HEADER, header_payload) + body


def npy_header(shape: tuple[int, ...], dtype: str = "<f4", version: int = 1) -> bytes:
    """The header of a ``.npy`` member declaring ``shape`` and ``dtype`` (no data after)."""
    buf = io.BytesIO()
    writer = np.lib.format.write_array_header_1_0
    if version == 2:
        writer = np.lib.format.write_array_header_2_0
    writer(buf, {"descr": dtype, "fortran_order": False, "shape": shape})
    return buf.getvalue()


def npy(array: np.ndarray) -> bytes:
    """A whole ``.npy`` member."""
    buf = io.BytesIO()
    np.save(buf, array, allow_pickle=False)
    return buf.getvalue()


def npz(members: dict[str, bytes], compress: bool = False) -> bytes:
    """A zip of raw members (``name`` gets ``.npy`` unless it has a suffix)."""
    buf = io.BytesIO()
    mode = zipfile.ZIP_DEFLATED if compress else zipfile.ZIP_STORED
    with zipfile.ZipFile(buf, "w", mode) as archive:
        for name, data in members.items():
            archive.writestr(name if "." in name else f"{name}.npy", data)
    return buf.getvalue()


def stream_members(n: int = 4) -> dict[str, bytes]:
    """The members of a small valid labelled stream."""
    return {
        "frames": npy(np.ones((n, 2, 2), np.float32)),
        "t": npy(np.arange(n) / 100.0),
        "sample_rate_hz": npy(np.float64(100.0)),
        "event_start_s": npy(np.array([0.0])),
        "event_end_s": npy(np.array([0.01])),
        "event_labels": npy(np.array(["push"])),
    }


def deep_json(depth: int) -> str:
    return "[" * depth + "]" * depth


CRAFTED: dict[str, bytes] = {
    # the cases of the hostile probe (issue 13), each once per reader
    "array index out of range.wsrec": wsrec(
        document('{"arrays": [], "doc": {"info": {"__wsrec_array__": 3}}}')
    ),
    "shape 1e400.wsrec": wsrec(
        document('{"arrays": [{"dtype": "<f4", "shape": [1e400]}], "doc": {}}')
    ),
    "huge shape.wsrec": wsrec(
        document('{"arrays": [{"dtype": "<f8", "shape": [4611686018427387904, 8]}], "doc": {}}')
    ),
    "deep json header.wsrec": wsrec(document(f'{{"arrays": [], "doc": {deep_json(3000)}}}')),
    "wrong types in header.wsrec": wsrec(header(info={"rows": "ten", "cols": [1]})),
    "header not an object.wsrec": wsrec(document('{"arrays": "x", "doc": 5}')),
    "provenance a list.wsrec": wsrec(header(provenance=[1, 2])),
    "rate infinite.wsrec": wsrec(header(info={"rows": 2, "cols": 2, "sample_rate_hz": 1e400})),
    "object dtype.wsrec": wsrec(document('{"arrays": [{"dtype": "|O", "shape": [1]}], "doc": 1}')),
    "npy 364 TiB.npz": npz(
        {
            **stream_members(),
            "frames": npy_header((1 << 20, 1 << 20, 100)),  # 400 TB of float32, 0 bytes given
        }
    ),
    "npy shape lies.npz": npz({**stream_members(), "t": npy_header((10**12,), "<f8")}),
    "npy object dtype.npz": npz({**stream_members(), "t": npy_header((3,), "|O")}),
    "deep metadata json.npz": npz(
        {**stream_members(), "metadata_json": npy(np.array(deep_json(3000)))}
    ),
    "metadata info a list.npz": npz(
        {**stream_members(), "metadata_json": npy(np.array(json.dumps({"info": [2, 2]})))}
    ),
    "header info a list.wsrec": wsrec(header(info=[2, 2])),
    "metadata info wrong types.npz": npz(
        {**stream_members(), "metadata_json": npy(np.array(json.dumps({"info": {"rows": "x"}})))}
    ),
    "stray member.npz": npz({**stream_members(), "README.txt": b"hello"}),
    "captures label out of range.npz": npz(
        {
            "frames": npy(np.ones((2, 3, 2, 2), np.float32)),
            "lengths": npy(np.array([3, 3])),
            "labels": npy(np.array([0, 7])),
            "class_names": npy(np.array(["push"])),
            "groups": npy(np.array(["p", "q"])),
            "sample_rate_hz": npy(np.float64(10.0)),
        }
    ),
    "random bytes.bin": bytes(range(256)) * 4,
    "empty.npz": b"",
    "cut zip.npz": npz(stream_members())[:100],
}
"""Files every reader must refuse in one line (name -> bytes)."""
