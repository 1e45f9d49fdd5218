"""The native ``.wsrec`` recording format: one append-only, self-describing, crash-safe file.

Layout (byte-exact description in ``docs/recording-format.md``)::

    b"wovenskin.wsrec 1\\n"                                   magic + format version line
    record*   where record = SYNC(4) type(u8) length(u32 LE) payload crc32(u32 LE)

The CRC covers type, length and payload.  Every record but FRAMES carries a *document*:
JSON with numeric arrays stored as raw little-endian bytes after it (see
:func:`encode_document`).  The first record is the HEADER (skin info, provenance,
settings); then FRAMES blocks, CALIBRATION, LABEL and ANNOTATION records in write order;
a FOOTER marks a clean close.

Durability: :class:`RecordingWriter` hands frames to the operating system at least every
``flush_interval_s`` (0.25 s) of stream or wall time and ``fsync``\\ s at least every
``fsync_interval_s`` (0.5 s) of wall time, so a killed process loses at most 0.25 s and a
power cut about 0.75 s of data.  :func:`read_recording` keeps every intact record, resyncs
past a corrupt one on the SYNC marker, and reports what it skipped in
``Recording.warnings`` instead of failing.
"""

from __future__ import annotations

import getpass
import json
import math
import os
import re
import shlex
import socket
import struct
import sys
import threading
import time
import zlib
from dataclasses import dataclass, field, replace
from datetime import UTC, datetime
from enum import IntEnum
from pathlib import Path
from typing import Any

import numpy as np

from wovenskin import __version__
from wovenskin.outputs import open_new
from wovenskin.recording.formats import (
    WSREC_MAGIC_PREFIX,
    FormatError,
    LabelledStream,
    identify,
    loads_json,
)
from wovenskin.skin.frames import SkinInfo

FORMAT_VERSION = 1
MAGIC_PREFIX = WSREC_MAGIC_PREFIX
MAGIC = MAGIC_PREFIX + str(FORMAT_VERSION).encode() + b"\n"
SYNC = b"\xa7WR\x5e"
MAX_PAYLOAD_BYTES = 1 << 28
LABEL_KIND_TRIAL = "trial"

_RECORD_HEAD = struct.Struct("<4sBI")  # sync, type, payload length
_CRC = struct.Struct("<I")
_FRAMES_HEAD = struct.Struct("<IHH")  # frame count, rows, cols
_DOC_HEAD = struct.Struct("<I")  # JSON length
_ARRAY_REF = "__wsrec_array__"
_ARRAY_DTYPE = re.compile(r"[<>|=]?[biuf][1-9][0-9]?")  # plain numeric or boolean dtypes
MAX_CHANNELS_PER_SIDE = 0xFFFF  # FRAMES store rows and cols as u16
_MAX_FRAMES_PER_RECORD = 1024


class RecordType(IntEnum):
    HEADER = 1
    FRAMES = 2
    CALIBRATION = 3
    LABEL = 4
    ANNOTATION = 5
    FOOTER = 6


@dataclass
class RecordedLabel:
    """A labelled time span on the stream clock, e.g. one prompted gesture trial."""

    label: str
    start_s: float
    end_s: float
    kind: str = LABEL_KIND_TRIAL
    extra: dict = field(default_factory=dict)


@dataclass
class Annotation:
    """Anything a pipeline stage logged at stream time ``t`` on a named ``stream``."""

    stream: str
    t: float
    payload: Any


@dataclass
class Recording:
    """Everything read back from a ``.wsrec`` file."""

    info: SkinInfo
    provenance: dict
    settings: dict
    frames: np.ndarray  # (T, R, C) float32, [row, col]
    seq: np.ndarray  # (T,) int64 device sequence numbers
    t: np.ndarray  # (T,) float64 stream clock, seconds
    device_t_us: np.ndarray  # (T,) int64, -1 where the device gave no time
    calibrations: list[dict] = field(default_factory=list)
    labels: list[RecordedLabel] = field(default_factory=list)
    annotations: list[Annotation] = field(default_factory=list)
    clean_close: bool = False
    warnings: list[str] = field(default_factory=list)
    footer: dict = field(default_factory=dict)
    format_version: int = FORMAT_VERSION

    def annotations_of(self, stream: str) -> list[Annotation]:
        return [a for a in self.annotations if a.stream == stream]

    def to_labelled_stream(self, kinds: tuple[str, ...] = (LABEL_KIND_TRIAL,)) -> LabelledStream:
        """Export as a labelled stream: labels of the given kinds become events.

        Times stay on the recording's stream clock; info, provenance and settings go to
        ``metadata``.
        """
        labels = [label for label in self.labels if label.kind in kinds]
        return LabelledStream(
            frames=self.frames,
            t=self.t,
            sample_rate_hz=self.info.sample_rate_hz,
            event_start_s=np.array([label.start_s for label in labels], dtype=np.float64),
            event_end_s=np.array([label.end_s for label in labels], dtype=np.float64),
            event_labels=np.array([label.label for label in labels], dtype=str),
            metadata={
                "source_format": "wsrec",
                "info": self.info.to_dict(),
                "provenance": self.provenance,
                "settings": self.settings,
            },
        )


def stored_skin_info(stream: LabelledStream) -> SkinInfo:
    """The :class:`SkinInfo` a labelled stream's metadata keeps (an exported recording's),
    else the defaults; ``ValueError`` (one line) when the stored one is unusable."""
    stored = stream.metadata.get("info")
    if stored is None:
        return SkinInfo()
    try:
        return skin_info_from_document(stored)
    except ValueError as exc:
        raise ValueError(f"the stream's metadata 'info' is unusable: {exc}") from None


def recording_from_labelled_stream(
    stream: LabelledStream, info: SkinInfo | None = None, provenance: dict | None = None
) -> Recording:
    """An in-memory :class:`Recording` of a labelled stream (events become trial labels).

    ``info`` defaults to ``stream.metadata["info"]`` when present, else a :class:`SkinInfo`
    with the stream's grid size; its rate is always the stream's.
    """
    frames = np.asarray(stream.frames, dtype=np.float32)
    n, rows, cols = frames.shape
    if info is None:
        info = stored_skin_info(stream)
    info = replace(info, rows=rows, cols=cols, sample_rate_hz=float(stream.sample_rate_hz))
    stored_provenance = stream.metadata.get("provenance")
    settings = stream.metadata.get("settings")
    labels = [
        RecordedLabel(str(label), float(start), float(end))
        for label, start, end in zip(
            stream.event_labels, stream.event_start_s, stream.event_end_s, strict=True
        )
    ]
    return Recording(
        info=info,
        provenance=dict(
            provenance or (stored_provenance if isinstance(stored_provenance, dict) else {})
        ),
        settings=dict(settings) if isinstance(settings, dict) else {},
        frames=frames,
        seq=np.arange(n, dtype=np.int64),
        t=np.asarray(stream.t, dtype=np.float64),
        device_t_us=np.full(n, -1, dtype=np.int64),
        labels=labels,
        clean_close=True,
    )


def write_recording(
    path: str | os.PathLike, recording: Recording, *, overwrite: bool = False
) -> None:
    """Write a whole :class:`Recording` (e.g. an imported labelled stream) as ``.wsrec``."""
    with RecordingWriter(
        path, recording.info, recording.provenance, recording.settings, overwrite=overwrite
    ) as writer:
        for calibration in recording.calibrations:
            writer.add_calibration(calibration)
        for label in recording.labels:
            writer.add_label(
                label.label, label.start_s, label.end_s, kind=label.kind, **label.extra
            )
        for note in recording.annotations:
            writer.add_annotation(note.stream, note.t, note.payload)
        for i in range(0, len(recording.t), _MAX_FRAMES_PER_RECORD):
            block = slice(i, i + _MAX_FRAMES_PER_RECORD)
            writer.append_frames(
                recording.seq[block],
                recording.t[block],
                recording.frames[block],
                recording.device_t_us[block],
            )


def default_provenance() -> dict:
    """What the writer records about where and how a recording was made."""
    try:
        user = getpass.getuser()
    except (KeyError, OSError):
        user = ""
    return {
        "host": socket.gethostname(),
        "user": user,
        "wovenskin_version": __version__,
        "started_utc": datetime.now(UTC).isoformat(timespec="milliseconds"),
        "command_line": shlex.join(sys.argv),
    }


# ----------------------------------------------------------------------------- writer


class RecordingWriter:
    """Appends a recording to a new ``.wsrec`` file; see the module docstring for durability.

    ``provenance`` should name at least ``participant``, ``operator`` and ``skin_id`` where
    known, plus free ``notes``; host, user, version, start time and command line are added
    when missing.  ``settings`` holds configuration such as the conditioning settings.
    Methods are thread-safe.  Closing (also on leaving a ``with`` block) writes the FOOTER.
    """

    def __init__(
        self,
        path: str | os.PathLike,
        info: SkinInfo,
        provenance: dict | None = None,
        settings: dict | None = None,
        *,
        overwrite: bool = False,
        flush_interval_s: float = 0.25,
        fsync_interval_s: float = 0.5,
    ) -> None:
        self.path = Path(path)
        self.info = info
        self.flush_interval_s = flush_interval_s
        self.fsync_interval_s = fsync_interval_s
        self._lock = threading.Lock()
        self._pending: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = []
        self._pending_count = 0
        self._counts = {"frames": 0, "calibrations": 0, "labels": 0, "annotations": 0}
        self._closed = False
        header = encode_document(
            {
                "format": "wovenskin.wsrec",
                "format_version": FORMAT_VERSION,
                "info": info.to_dict(),
                "provenance": {**default_provenance(), **(provenance or {})},
                "settings": settings or {},
            }
        )
        self._file = open_new(self.path, overwrite, binary=True)
        self._file.write(MAGIC)
        self._write_record(RecordType.HEADER, header)
        self._file.flush()
        os.fsync(self._file.fileno())
        _fsync_directory(self.path.parent)
        self._last_flush = self._last_fsync = time.monotonic()
        self._unsynced = False

    # -- public API

    def append_frames(self, seq, t, values, device_t_us=None) -> None:
        """Buffer one frame (``values`` (R, C), scalar seq/t) or a block ((N, R, C), (N,))."""
        values = np.asarray(values, dtype=np.float32)
        if values.ndim == 2:
            values = values[None]
        rows, cols = self.info.rows, self.info.cols
        if values.ndim != 3 or values.shape[1:] != (rows, cols):
            raise ValueError(
                f"frames must be ({rows}, {cols}) or (N, {rows}, {cols}), got {values.shape}"
            )
        n = values.shape[0]
        if n == 0:
            return
        seq = np.atleast_1d(np.asarray(seq, dtype=np.int64))
        t = np.atleast_1d(np.asarray(t, dtype=np.float64))
        if device_t_us is None:
            device_t_us = np.full(n, -1, dtype=np.int64)
        device_t_us = np.atleast_1d(np.asarray(device_t_us, dtype=np.int64))
        if not seq.shape == t.shape == device_t_us.shape == (n,):
            raise ValueError(
                f"seq, t and device_t_us need {n} entries for {n} frames, got "
                f"{seq.shape}, {t.shape}, {device_t_us.shape}"
            )
        with self._lock:
            self._check_open()
            self._pending.append((seq, t, device_t_us, values))
            self._pending_count += n
            self._counts["frames"] += n
            self._keep_durable()

    def append_frame(self, frame) -> None:
        """Buffer one :class:`~wovenskin.skin.frames.Frame`."""
        device_t_us = -1 if frame.device_t_us is None else frame.device_t_us
        self.append_frames(frame.seq, frame.t, frame.values, device_t_us)

    def add_calibration(self, calibration: dict) -> None:
        """Record a calibration (e.g. ``baseline`` and ``noise`` arrays plus settings)."""
        self._add_document(RecordType.CALIBRATION, dict(calibration), "calibrations")

    def add_label(
        self, label: str, start_s: float, end_s: float, kind: str = LABEL_KIND_TRIAL, **extra
    ) -> None:
        """Label the span ``[start_s, end_s]`` of the stream clock (``kind``: trial, prompt...)."""
        if not end_s >= start_s:
            raise ValueError(f"label {label!r} ends at {end_s} before it starts at {start_s}")
        document = {
            "label": str(label),
            "start_s": float(start_s),
            "end_s": float(end_s),
            "kind": str(kind),
            "extra": extra,
        }
        self._add_document(RecordType.LABEL, document, "labels")

    def add_annotation(self, stream: str, t: float, payload: Any) -> None:
        """Log ``payload`` (JSON values and numeric arrays) on ``stream`` at stream time ``t``."""
        document = {"stream": str(stream), "t": float(t), "payload": payload}
        self._add_document(RecordType.ANNOTATION, document, "annotations")

    def tick(self) -> None:
        """Apply the flush/fsync schedule without new data.

        Call it while the stream is quiet (a stall, a pulled cable), so frames buffered
        before the silence still reach the disk within the promised time.
        """
        with self._lock:
            if not self._closed:
                self._keep_durable()

    def flush(self) -> None:
        """Write everything buffered and ``fsync`` it."""
        with self._lock:
            self._check_open()
            self._write_pending_frames()
            self._sync()

    def close(self, error: str | None = None) -> None:
        """Write buffered frames and the FOOTER, ``fsync`` and close; safe to call twice."""
        with self._lock:
            if self._closed:
                return
            try:
                self._write_pending_frames()
                footer = {
                    **self._counts,
                    "ended_utc": datetime.now(UTC).isoformat(timespec="milliseconds"),
                }
                if error:
                    footer["error"] = error
                self._write_record(RecordType.FOOTER, encode_document(footer))
                self._sync()
            finally:
                self._closed = True
                self._file.close()

    @property
    def closed(self) -> bool:
        return self._closed

    def __enter__(self) -> RecordingWriter:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        self.close(error=None if exc is None else f"{exc_type.__name__}: {exc}")

    # -- internals

    def _add_document(self, rtype: RecordType, document: dict, counter: str) -> None:
        payload = encode_document(document)
        with self._lock:
            self._check_open()
            self._write_record(rtype, payload)
            self._counts[counter] += 1
            self._keep_durable()

    def _keep_durable(self) -> None:
        now = time.monotonic()
        flush_due = now - self._last_flush >= self.flush_interval_s
        if self._pending:
            span = self._pending[-1][1][-1] - self._pending[0][1][0]
            full = self._pending_count >= _MAX_FRAMES_PER_RECORD
            if flush_due or full or span >= self.flush_interval_s:
                self._write_pending_frames()
                flush_due = True
        if flush_due:
            self._file.flush()
            self._last_flush = now
            self._unsynced = True
        if self._unsynced and now - self._last_fsync >= self.fsync_interval_s:
            os.fsync(self._file.fileno())
            self._last_fsync = now
            self._unsynced = False

    def _write_pending_frames(self) -> None:
        if not self._pending:
            return
        columns = zip(*self._pending, strict=True)
        seq, t, device_t_us, values = (np.concatenate(parts) for parts in columns)
        self._pending.clear()
        self._pending_count = 0
        rows, cols = values.shape[1:]
        for i in range(0, len(t), _MAX_FRAMES_PER_RECORD):
            block = slice(i, i + _MAX_FRAMES_PER_RECORD)
            payload = b"".join(
                (
                    _FRAMES_HEAD.pack(len(t[block]), rows, cols),
                    seq[block].astype("<i8").tobytes(),
                    t[block].astype("<f8").tobytes(),
                    device_t_us[block].astype("<i8").tobytes(),
                    values[block].astype("<f4").tobytes(),
                )
            )
            self._write_record(RecordType.FRAMES, payload)

    def _write_record(self, rtype: RecordType, payload: bytes) -> None:
        if len(payload) > MAX_PAYLOAD_BYTES:
            raise ValueError(f"{rtype.name} record of {len(payload)} bytes is too large")
        head = _RECORD_HEAD.pack(SYNC, int(rtype), len(payload))
        crc = zlib.crc32(payload, zlib.crc32(head[len(SYNC) :]))
        self._file.write(head)
        self._file.write(payload)
        self._file.write(_CRC.pack(crc))

    def _sync(self) -> None:
        self._file.flush()
        os.fsync(self._file.fileno())
        self._last_flush = self._last_fsync = time.monotonic()
        self._unsynced = False

    def _check_open(self) -> None:
        if self._closed:
            raise ValueError(f"recording {self.path} is closed")


def _fsync_directory(directory: Path) -> None:
    """Make a newly created file's directory entry durable (best effort, POSIX only)."""
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


# ----------------------------------------------------------------------------- documents


def encode_document(document: Any) -> bytes:
    """JSON with numeric numpy arrays (anywhere inside) stored as raw little-endian bytes.

    Layout: ``u32 json_length``, the UTF-8 JSON ``{"arrays": [{"dtype", "shape"}...],
    "doc": ...}`` in which each array is replaced by ``{"__wsrec_array__": index}``, then
    the arrays' bytes in index order.
    """
    arrays: list[np.ndarray] = []

    def to_json(value: Any) -> Any:
        if isinstance(value, np.ndarray):
            if value.dtype.kind not in "biuf":
                raise TypeError(f"cannot record an array of dtype {value.dtype}")
            arrays.append(np.ascontiguousarray(value, dtype=value.dtype.newbyteorder("<")))
            return {_ARRAY_REF: len(arrays) - 1}
        if isinstance(value, np.generic):
            return value.item()
        if isinstance(value, os.PathLike):
            return os.fspath(value)
        raise TypeError(f"cannot record a value of type {type(value).__name__}")

    doc_json = json.dumps(document, default=to_json)
    specs = [{"dtype": a.dtype.str, "shape": list(a.shape)} for a in arrays]
    text = ('{"arrays": ' + json.dumps(specs) + ', "doc": ' + doc_json + "}").encode()
    return b"".join((_DOC_HEAD.pack(len(text)), text, *(a.tobytes() for a in arrays)))


def decode_document(payload: bytes | memoryview) -> Any:
    """Inverse of :func:`encode_document`; ``ValueError`` (one line) if the payload is
    malformed: bad JSON, nesting past :data:`~wovenskin.recording.formats.MAX_JSON_DEPTH`,
    an envelope or array spec of the wrong type, a dtype that is not plain numeric, a shape
    whose bytes the record does not hold, or a reference to an array that does not exist."""
    payload = memoryview(payload)
    if len(payload) < _DOC_HEAD.size:
        raise ValueError("document shorter than its length field")
    (text_length,) = _DOC_HEAD.unpack_from(payload)
    end = _DOC_HEAD.size + text_length
    if end > len(payload):
        raise ValueError("document JSON runs past the record")
    envelope = loads_json(bytes(payload[_DOC_HEAD.size : end]), "document JSON")
    if not isinstance(envelope, dict) or not isinstance(envelope.get("arrays"), list):
        raise ValueError("document is not an object with an 'arrays' list")
    if "doc" not in envelope:
        raise ValueError("document has no 'doc'")
    arrays = []
    for spec in envelope["arrays"]:
        dtype, shape = _array_spec(spec)
        nbytes = dtype.itemsize * math.prod(shape)
        if end + nbytes > len(payload):
            raise ValueError(f"array {dtype} {shape} needs {nbytes} bytes the record does not hold")
        array = np.frombuffer(payload, dtype, math.prod(shape), end).reshape(shape)
        arrays.append(array.astype(dtype.newbyteorder("="), copy=True))
        end += nbytes
    if end != len(payload):
        raise ValueError(f"{len(payload) - end} stray bytes after the document")
    return _resolve_arrays(envelope["doc"], arrays)


def _array_spec(spec: Any) -> tuple[np.dtype, tuple[int, ...]]:
    """The dtype and shape of one ``{"dtype", "shape"}`` spec, checked before any use."""
    if not isinstance(spec, dict):
        raise ValueError("an array spec is not an object")
    text, shape = spec.get("dtype"), spec.get("shape")
    if not isinstance(text, str) or not _ARRAY_DTYPE.fullmatch(text):
        raise ValueError(f"array dtype {str(text)[:40]!r} is not a plain numeric dtype")
    try:
        dtype = np.dtype(text)
    except TypeError:
        raise ValueError(f"array dtype {text!r} is not a plain numeric dtype") from None
    if not isinstance(shape, list) or len(shape) > 32:
        raise ValueError("array shape is not a list of at most 32 sizes")
    if not all(type(n) is int and n >= 0 for n in shape):
        raise ValueError(f"array shape {str(shape)[:60]} is not a list of sizes >= 0")
    return dtype, tuple(shape)


def _resolve_arrays(value: Any, arrays: list[np.ndarray]) -> Any:
    if isinstance(value, dict):
        if len(value) == 1 and _ARRAY_REF in value:
            index = value[_ARRAY_REF]
            if type(index) is not int or not 0 <= index < len(arrays):
                count = len(arrays)
                raise ValueError(f"reference to array {str(index)[:20]}, but there are {count}")
            return arrays[index]
        return {k: _resolve_arrays(v, arrays) for k, v in value.items()}
    if isinstance(value, list):
        return [_resolve_arrays(v, arrays) for v in value]
    return value


# ----------------------------------------------------------------------------- reader


def read_recording(path: str | os.PathLike) -> Recording:
    """Read a ``.wsrec`` file, recovering everything before a truncated or corrupt part.

    Damage after the header is reported in ``Recording.warnings`` (one line each);
    :class:`FormatError` only for files that are not recordings or lack a readable header.
    """
    where = str(path)
    if identify(path) != "recording":
        raise FormatError(f"{where}: is an .npz file, not a .wsrec recording")
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise FormatError(f"{where}: cannot read ({exc.strerror or exc})") from None
    version, pos = _read_magic(where, data)
    first = _record_at(data, pos)
    if first is None or first[0] != RecordType.HEADER:
        if _extends_past_end(data, pos):
            raise FormatError(f"{where}: recording cut off inside its header; nothing to recover")
        raise FormatError(f"{where}: first record is not a valid HEADER")
    try:
        header = decode_document(first[1])
        if not isinstance(header, dict):
            raise ValueError("it is not an object")
        info = skin_info_from_document(header.get("info"))
        provenance, settings = (_optional_object(header, key) for key in ("provenance", "settings"))
    except ValueError as exc:
        raise FormatError(f"{where}: unreadable HEADER ({exc})") from None
    recording = Recording(
        info=info,
        provenance=provenance,
        settings=settings,
        frames=np.zeros((0, info.rows, info.cols), np.float32),
        seq=np.zeros(0, np.int64),
        t=np.zeros(0, np.float64),
        device_t_us=np.zeros(0, np.int64),
        format_version=version,
    )
    _read_body(data, first[2], recording)
    return recording


def skin_info_from_document(value: Any) -> SkinInfo:
    """A :class:`SkinInfo` from a stored ``info`` object, every field's type checked.

    ``ValueError`` (one line) for anything a crafted file could put there: not an object,
    a grid outside 1..65535 channels a side, a rate that is not a finite positive number,
    text fields that are not text.  Unknown fields are ignored (a newer writer's)."""
    if not isinstance(value, dict):
        raise ValueError("'info' is not an object")
    defaults = SkinInfo()
    fields: dict[str, Any] = {}
    for name in SkinInfo.__dataclass_fields__:
        if name not in value:
            continue
        given, default = value[name], getattr(defaults, name)
        if isinstance(default, str):
            if not isinstance(given, str):
                raise ValueError(f"info.{name} must be text, got {type(given).__name__}")
        elif isinstance(default, int):
            if type(given) is not int:
                raise ValueError(f"info.{name} must be an integer, got {str(given)[:30]}")
        elif type(given) not in (int, float) or not math.isfinite(given):
            raise ValueError(f"info.{name} must be a finite number, got {str(given)[:30]}")
        fields[name] = float(given) if isinstance(default, float) else given
    info = SkinInfo(**fields)
    sides_ok = all(1 <= n <= MAX_CHANNELS_PER_SIDE for n in (info.rows, info.cols))
    if not (sides_ok and info.sample_rate_hz > 0):
        raise ValueError(
            f"an impossible skin: {info.rows}x{info.cols} channels at {info.sample_rate_hz} Hz"
        )
    return info


def _optional_object(document: dict, key: str) -> dict:
    """``document[key]`` when it is an object, ``{}`` when absent or null; else ValueError."""
    value = document.get(key)
    if value is None:
        return {}
    if not isinstance(value, dict):
        raise ValueError(f"'{key}' is not an object")
    return dict(value)


def _read_magic(where: str, data: bytes) -> tuple[int, int]:
    if len(data) < len(MAGIC) and MAGIC.startswith(data):
        raise FormatError(f"{where}: recording cut off inside its header; nothing to recover")
    newline = data.find(b"\n", 0, 32)
    if not data.startswith(MAGIC_PREFIX) or newline < 0:
        raise FormatError(
            f"{where}: not a wovenskin recording (no '{MAGIC.decode().strip()}' line at the start)"
        )
    try:
        version = int(data[len(MAGIC_PREFIX) : newline])
    except ValueError:
        raise FormatError(f"{where}: not a wovenskin recording (bad version line)") from None
    if version > FORMAT_VERSION:
        raise FormatError(
            f"{where}: recording format version {version} is newer than this "
            f"wovenskin reads ({FORMAT_VERSION}); upgrade wovenskin"
        )
    return version, newline + 1


def _read_body(data: bytes, pos: int, recording: Recording) -> None:
    blocks: list[tuple[np.ndarray, ...]] = []
    unknown_types: dict[int, int] = {}
    rows, cols = recording.info.rows, recording.info.cols
    warnings = recording.warnings
    for offset, rtype, payload in _iter_records(data, pos, warnings):
        if recording.clean_close:
            warnings.append(f"records after the FOOTER at byte {offset} (kept)")
            recording.clean_close = False
        try:
            if rtype == RecordType.FRAMES:
                blocks.append(_decode_frames(payload, rows, cols))
            elif rtype == RecordType.CALIBRATION:
                recording.calibrations.append(_object_document(payload))
            elif rtype == RecordType.LABEL:
                recording.labels.append(_label_from_document(_object_document(payload)))
            elif rtype == RecordType.ANNOTATION:
                doc = _object_document(payload)
                recording.annotations.append(
                    Annotation(_text(doc, "stream"), _finite(doc, "t"), doc.get("payload"))
                )
            elif rtype == RecordType.FOOTER:
                recording.footer = _object_document(payload)
                recording.clean_close = True
            elif rtype == RecordType.HEADER:
                warnings.append(f"second HEADER at byte {offset} ignored")
            else:
                unknown_types[rtype] = unknown_types.get(rtype, 0) + 1
        except (ValueError, KeyError, TypeError) as exc:
            name = RecordType(rtype).name
            warnings.append(f"unreadable {name} record at byte {offset} skipped ({exc})")
    if not recording.clean_close and not warnings:
        warnings.append("no FOOTER: the recording was not closed cleanly")
    if unknown_types:
        kinds = ", ".join(f"{n} of type {k}" for k, n in sorted(unknown_types.items()))
        warnings.append(f"skipped records of unknown type ({kinds}); written by a newer wovenskin?")
    if blocks:
        recording.seq, recording.t, recording.device_t_us, recording.frames = (
            np.concatenate(parts) for parts in zip(*blocks, strict=True)
        )


def _object_document(payload: memoryview) -> dict:
    """A record's document, which must be a JSON object (ValueError otherwise)."""
    doc = decode_document(payload)
    if not isinstance(doc, dict):
        raise ValueError("its document is not an object")
    return doc


def _text(doc: dict, key: str) -> str:
    value = doc[key]
    if not isinstance(value, str):
        raise ValueError(f"'{key}' is not text")
    return value


def _finite(doc: dict, key: str) -> float:
    value = doc[key]
    if type(value) not in (int, float) or not math.isfinite(value):
        raise ValueError(f"'{key}' is not a finite number")
    return float(value)


def _label_from_document(doc: dict) -> RecordedLabel:
    """A LABEL record's label, its types and times checked (ValueError if bad)."""
    start_s, end_s = _finite(doc, "start_s"), _finite(doc, "end_s")
    if end_s < start_s:
        raise ValueError(f"label ends at {end_s} before it starts at {start_s}")
    kind = doc.get("kind", LABEL_KIND_TRIAL)
    extra = doc.get("extra") or {}
    if not isinstance(kind, str) or not isinstance(extra, dict):
        raise ValueError("'kind' is not text or 'extra' is not an object")
    return RecordedLabel(_text(doc, "label"), start_s, end_s, kind, dict(extra))


def _decode_frames(payload: memoryview, rows: int, cols: int) -> tuple[np.ndarray, ...]:
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


def _iter_records(data: bytes, pos: int, warnings: list[str]):
    """Yield ``(offset, type, payload)`` of intact records, resyncing past damage."""
    while pos < len(data):
        record = _record_at(data, pos)
        if record is not None:
            yield pos, record[0], record[1]
            pos = record[2]
            continue
        resume = _next_record(data, pos + 1)
        if resume is None:
            lost = len(data) - pos
            if _extends_past_end(data, pos):
                warnings.append(
                    f"cut off at byte {pos}: lost the last {lost} bytes (the writer did not finish)"
                )
            else:
                warnings.append(f"corrupt data from byte {pos} to the end: lost {lost} bytes")
            return
        warnings.append(f"skipped {resume - pos} corrupt bytes at byte {pos}")
        pos = resume


def _record_at(data: bytes, pos: int) -> tuple[int, memoryview, int] | None:
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
        if _record_at(data, pos) is not None:
            return pos
        pos = data.find(SYNC, pos + 1)
    return None


def _extends_past_end(data: bytes, pos: int) -> bool:
    """True where the bytes at ``pos`` could be the start of a record cut off by the EOF."""
    head = data[pos : pos + _RECORD_HEAD.size]
    if len(head) < _RECORD_HEAD.size:
        return SYNC.startswith(head[: len(SYNC)])
    sync, _, length = _RECORD_HEAD.unpack(head)
    return sync == SYNC and length <= MAX_PAYLOAD_BYTES and pos + len(head) + length + 4 > len(data)
