"""Writing a ``.wsrec`` recording as it happens: :class:`RecordingWriter` (durable, thread-safe).

Frames reach the operating system at least every ``flush_interval_s`` (0.25 s) of stream
or wall time and are ``fsync``\\ ed at least every ``fsync_interval_s`` (0.5 s) of wall
time, so a killed process loses at most 0.25 s and a power cut about 0.75 s of data.
"""

from __future__ import annotations

import getpass
import os
import shlex
import socket
import sys
import threading
import time
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from wovenskin import __version__
from wovenskin.outputs import open_new
from wovenskin.recording.documents import encode_document
from wovenskin.recording.records import (
    FORMAT_VERSION,
    LABEL_KIND_TRIAL,
    MAGIC,
    MAX_FRAMES_PER_RECORD,
    RecordType,
    pack_frames,
    pack_record,
)
from wovenskin.skin.frames import SkinInfo


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
    Until the first frame, :meth:`change_info` may describe another skin (a device whose
    INFO arrived after the recording was opened).
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
        self._header = {
            "format": "wovenskin.wsrec",
            "format_version": FORMAT_VERSION,
            "info": info.to_dict(),
            "provenance": {**default_provenance(), **(provenance or {})},
            "settings": settings or {},
        }
        self._before_frames: list[bytes] = []  # records written before the first frame
        self._file = open_new(self.path, overwrite, binary=True)
        self._file.write(MAGIC)
        self._write_record(RecordType.HEADER, encode_document(self._header))
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
            self._before_frames.clear()  # the header is final now
            self._keep_durable()

    def append_frame(self, frame) -> None:
        """Buffer one :class:`~wovenskin.skin.frames.Frame`."""
        device_t_us = -1 if frame.device_t_us is None else frame.device_t_us
        self.append_frames(frame.seq, frame.t, frame.values, device_t_us)

    def change_info(self, info: SkinInfo) -> None:
        """Describe the skin as ``info``: the HEADER is rewritten, the records written since
        kept.  Only before the first frame -- a serial skin declares its grid in INFO after
        the recording was opened -- and a ``ValueError`` after it."""
        with self._lock:
            self._check_open()
            if self._counts["frames"]:
                raise ValueError(
                    f"{self.path} already holds frames of a {self.info.rows}x{self.info.cols} skin"
                )
            self._header["info"] = info.to_dict()
            self._file.seek(len(MAGIC))
            self._file.truncate()
            self._write_record(RecordType.HEADER, encode_document(self._header))
            self._file.write(b"".join(self._before_frames))
            self.info = info
            self._sync()

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
            record = self._write_record(rtype, payload)
            if not self._counts["frames"]:  # kept for change_info
                self._before_frames.append(record)
            self._counts[counter] += 1
            self._keep_durable()

    def _keep_durable(self) -> None:
        now = time.monotonic()
        flush_due = now - self._last_flush >= self.flush_interval_s
        if self._pending:
            span = self._pending[-1][1][-1] - self._pending[0][1][0]
            full = self._pending_count >= MAX_FRAMES_PER_RECORD
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
        for i in range(0, len(t), MAX_FRAMES_PER_RECORD):
            block = slice(i, i + MAX_FRAMES_PER_RECORD)
            payload = pack_frames(seq[block], t[block], device_t_us[block], values[block])
            self._write_record(RecordType.FRAMES, payload)

    def _write_record(self, rtype: RecordType, payload: bytes) -> bytes:
        record = pack_record(rtype, payload)
        self._file.write(record)
        return record

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
