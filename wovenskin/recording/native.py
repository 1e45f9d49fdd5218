"""The native ``.wsrec`` recording: what it holds (:class:`Recording`) and reading it back.

Layout (byte-exact description in ``docs/recording-format.md``)::

    b"wovenskin.wsrec 1\\n"                                   magic + format version line
    record*   where record = SYNC(4) type(u8) length(u32 LE) payload crc32(u32 LE)

The CRC covers type, length and payload.  Every record but FRAMES carries a *document*:
JSON with numeric arrays stored as raw little-endian bytes after it.  The first record is
the HEADER (skin info, provenance, settings); then FRAMES blocks, CALIBRATION, LABEL and
ANNOTATION records in write order; a FOOTER marks a clean close.  The record layer is
:mod:`~wovenskin.recording.records`, the documents :mod:`~wovenskin.recording.documents`,
the crash-safe writer :mod:`~wovenskin.recording.writer`.

:func:`read_recording` keeps every intact record, resyncs past a corrupt one on the SYNC
marker, and reports what it skipped in ``Recording.warnings`` instead of failing.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from wovenskin.errors import DataError
from wovenskin.recording.documents import decode_document
from wovenskin.recording.formats import LabelledStream, skin_info_from_document
from wovenskin.recording.records import (
    FORMAT_VERSION,
    LABEL_KIND_TRIAL,
    MAGIC,
    MAGIC_PREFIX,
    MAX_FRAMES_PER_RECORD,
    RecordType,
    extends_past_end,
    iter_records,
    record_at,
    unpack_frames,
)
from wovenskin.recording.untrusted import FormatError, identify
from wovenskin.recording.writer import RecordingWriter
from wovenskin.skin.frames import SkinInfo


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
        raise DataError(f"the stream's metadata 'info' is unusable: {exc}") from None


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
        for i in range(0, len(recording.t), MAX_FRAMES_PER_RECORD):
            block = slice(i, i + MAX_FRAMES_PER_RECORD)
            writer.append_frames(
                recording.seq[block],
                recording.t[block],
                recording.frames[block],
                recording.device_t_us[block],
            )


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
    first = record_at(data, pos)
    if first is None or first[0] != RecordType.HEADER:
        if extends_past_end(data, pos):
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
    for offset, rtype, payload in iter_records(data, pos, warnings):
        if recording.clean_close:
            warnings.append(f"records after the FOOTER at byte {offset} (kept)")
            recording.clean_close = False
        try:
            if rtype == RecordType.FRAMES:
                blocks.append(unpack_frames(payload, rows, cols))
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
