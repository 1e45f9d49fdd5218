"""Interchange formats of ``docs/formats.md``: labelled streams and labelled captures.

Readers validate keys, dtypes and shapes and raise :class:`FormatError` with a one-line
message naming the file and the problem; they never fail with a bare traceback and never
unpickle (object arrays are refused from their ``.npy`` header).  Every member's declared
shape and dtype are checked against its size before memory is allocated, so a crafted file
cannot ask for terabytes.  :func:`identify` tells wovenskin's files from anything else, with
one message (:data:`NOT_OURS`) for every reader.  Writers run the same checks before
writing, so they cannot produce a file the readers would reject; they refuse an existing
target unless ``overwrite`` (:mod:`wovenskin.outputs`) and replace it atomically.

Conventions beyond docs/formats.md (documented in ``docs/recording-format.md``):

- floating-point frames are returned as float32; integer frames are kept exactly as read
  (signal conditioning converts them to float);
- ``metadata`` round-trips: its array values are stored as extra ``.npz`` keys and the rest
  as one JSON string under :data:`METADATA_JSON_KEY`, which other tools ignore;
- keys a reader does not know are kept in ``metadata`` (e.g. ``substrate``, ``cover``).
- a stream's ``metadata["info"]`` (the skin of an exported recording, which replay and
  conversion use) is checked as a recording's header is: a crafted one is refused on read.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from wovenskin.io import atomic_write_with, dumps
from wovenskin.outputs import check_new_output
from wovenskin.recording.records import MAX_CHANNELS_PER_SIDE
from wovenskin.recording.untrusted import fail, load_npz, loads_json
from wovenskin.skin.frames import SkinInfo


@dataclass
class LabelledStream:
    """A continuous recording from one skin (docs/formats.md "Labelled stream")."""

    frames: np.ndarray  # (T, R, C) raw values, float32 or integer
    t: np.ndarray  # (T,) float64 seconds, increasing
    sample_rate_hz: float
    event_start_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    event_end_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    event_labels: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=str))
    metadata: dict = field(default_factory=dict)


@dataclass
class LabelledCaptures:
    """Separate captures with one label each (docs/formats.md "Labelled captures")."""

    frames: np.ndarray  # (N, T, R, C)
    lengths: np.ndarray  # (N,) int64
    labels: np.ndarray  # (N,) int64 into class_names
    class_names: list[str]
    groups: np.ndarray  # (N,) str
    sample_rate_hz: float
    metadata: dict = field(default_factory=dict)


METADATA_JSON_KEY = "metadata_json"
"""Extension key: the JSON-serialisable part of ``metadata``, as one string."""

STREAM_KEYS = ("frames", "t", "sample_rate_hz")
EVENT_KEYS = ("event_start_s", "event_end_s", "event_labels")
CAPTURES_KEYS = ("frames", "lengths", "labels", "class_names", "groups", "sample_rate_hz")
# Names np.savez cannot take as keyword keys.
_SAVEZ_RESERVED = ("file", "allow_pickle")


# ----------------------------------------------------------------------------- readers


def read_labelled_stream(path: str | os.PathLike) -> LabelledStream:
    """Read and validate a labelled-stream ``.npz``; :class:`FormatError` if it is bad."""
    where = str(path)
    arrays = load_npz(path)
    missing = [k for k in STREAM_KEYS if k not in arrays]
    if missing and {"lengths", "labels"} <= arrays.keys():
        fail(where, "is a labelled-captures file, not a labelled stream")
    _require_keys(where, arrays, STREAM_KEYS, "a labelled stream")
    return _stream_from_arrays(where, arrays)


def read_labelled_captures(path: str | os.PathLike) -> LabelledCaptures:
    """Read and validate a labelled-captures ``.npz``; :class:`FormatError` if it is bad."""
    where = str(path)
    arrays = load_npz(path)
    _require_keys(where, arrays, CAPTURES_KEYS, "labelled captures")
    return _captures_from_arrays(where, arrays)


# ----------------------------------------------------------------------------- writers


def write_labelled_stream(
    path: str | os.PathLike, stream: LabelledStream, *, overwrite: bool = False
) -> None:
    """Write ``stream`` as a labelled-stream ``.npz`` (validated first, written atomically).

    An existing ``path`` is replaced only with ``overwrite`` (else
    :class:`~wovenskin.outputs.OutputExistsError`).
    """
    check_new_output(path, overwrite)
    where = f"cannot write {path}"
    arrays = {
        "frames": np.asarray(stream.frames),
        "t": np.asarray(stream.t, dtype=np.float64),
        "sample_rate_hz": np.float64(stream.sample_rate_hz),
        "event_start_s": np.asarray(stream.event_start_s, dtype=np.float64),
        "event_end_s": np.asarray(stream.event_end_s, dtype=np.float64),
        "event_labels": _as_str_array(stream.event_labels),
    }
    arrays.update(_metadata_to_arrays(where, stream.metadata, reserved=arrays.keys()))
    _stream_from_arrays(where, arrays)
    atomic_write_with(path, lambda f: np.savez_compressed(f, **arrays))


def write_labelled_captures(
    path: str | os.PathLike, captures: LabelledCaptures, *, overwrite: bool = False
) -> None:
    """Write ``captures`` as a labelled-captures ``.npz`` (validated first, atomic); an
    existing ``path`` is replaced only with ``overwrite``."""
    check_new_output(path, overwrite)
    where = f"cannot write {path}"
    arrays = {
        "frames": np.asarray(captures.frames),
        "lengths": np.asarray(captures.lengths),
        "labels": np.asarray(captures.labels),
        "class_names": _as_str_array(captures.class_names),
        "groups": _as_str_array(captures.groups),
        "sample_rate_hz": np.float64(captures.sample_rate_hz),
    }
    arrays.update(_metadata_to_arrays(where, captures.metadata, reserved=arrays.keys()))
    _captures_from_arrays(where, arrays)
    atomic_write_with(path, lambda f: np.savez_compressed(f, **arrays))


# ----------------------------------------------------------------------------- validation


def _stream_from_arrays(where: str, arrays: dict[str, np.ndarray]) -> LabelledStream:
    frames = _check_frames(where, arrays["frames"], "(T, R, C)")
    n_frames = frames.shape[0]
    t = _check_real(where, "t", arrays["t"], (n_frames,))
    if n_frames > 1 and not np.all(np.diff(t) > 0):
        i = int(np.argmin(np.diff(t) > 0))
        fail(where, f"'t' must be strictly increasing, but t[{i + 1}]={t[i + 1]} <= t[{i}]={t[i]}")
    rate = _check_rate(where, arrays["sample_rate_hz"])
    if frames.dtype.kind == "f":
        _check_finite(where, "frames", frames)
    present = [k for k in EVENT_KEYS if k in arrays]
    if present and len(present) < len(EVENT_KEYS):
        absent = [k for k in EVENT_KEYS if k not in arrays]
        fail(where, f"event keys come together: has {present} but not {absent}")
    if present:
        labels = _check_strings(where, "event_labels", arrays["event_labels"])
        shape = (len(labels),)
        starts = _check_real(where, "event_start_s", arrays["event_start_s"], shape)
        ends = _check_real(where, "event_end_s", arrays["event_end_s"], shape)
        backwards = np.flatnonzero(ends < starts)
        if backwards.size:
            i = int(backwards[0])
            problem = (
                f"event {i} ({str(labels[i])!r}) ends at {ends[i]} before it starts at {starts[i]}"
            )
            fail(where, problem)
    else:
        labels, starts, ends = np.zeros(0, dtype=str), np.zeros(0), np.zeros(0)
    known = (*STREAM_KEYS, *EVENT_KEYS)
    metadata = _metadata_from_arrays(where, arrays, known)
    if "info" in metadata:  # an exported recording's skin: what replay and convert use
        try:
            skin_info_from_document(metadata["info"])
        except ValueError as exc:
            fail(where, f"the stream's metadata 'info' is unusable: {exc}")
    return LabelledStream(
        frames=frames,
        t=t,
        sample_rate_hz=rate,
        event_start_s=starts,
        event_end_s=ends,
        event_labels=labels,
        metadata=metadata,
    )


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


def _captures_from_arrays(where: str, arrays: dict[str, np.ndarray]) -> LabelledCaptures:
    frames = _check_frames(where, arrays["frames"], "(N, T, R, C)")
    n, t_max = frames.shape[:2]
    lengths = _check_integers(where, "lengths", arrays["lengths"], n)
    out_of_range = np.flatnonzero((lengths < 1) | (lengths > t_max))
    if out_of_range.size:
        i = int(out_of_range[0])
        fail(where, f"'lengths' must lie in [1, {t_max}], but capture {i} has {lengths[i]}")
    class_names = _check_strings(where, "class_names", arrays["class_names"])
    if class_names.size == 0:
        fail(where, "'class_names' is empty")
    if len(set(class_names.tolist())) != class_names.size:
        fail(where, f"'class_names' has duplicates: {class_names.tolist()}")
    labels = _check_integers(where, "labels", arrays["labels"], n)
    bad = np.flatnonzero((labels < 0) | (labels >= class_names.size))
    if bad.size:
        i = int(bad[0])
        fail(
            where,
            f"'labels' must index class_names (0..{class_names.size - 1}), capture {i} "
            f"has {labels[i]}",
        )
    groups = _check_strings(where, "groups", arrays["groups"])
    if groups.shape != (n,):
        fail(where, f"'groups' must have shape ({n},) matching frames, got {groups.shape}")
    rate = _check_rate(where, arrays["sample_rate_hz"])
    if frames.dtype.kind == "f":
        valid = np.arange(t_max)[None, :] < lengths[:, None]
        _check_finite(where, "frames", frames[valid])
    return LabelledCaptures(
        frames=frames,
        lengths=lengths,
        labels=labels,
        class_names=class_names.tolist(),
        groups=groups,
        sample_rate_hz=rate,
        metadata=_metadata_from_arrays(where, arrays, CAPTURES_KEYS),
    )


def _check_frames(where: str, frames: np.ndarray, axes: str) -> np.ndarray:
    ndim = axes.count(",") + 1
    if frames.ndim != ndim:
        fail(where, f"'frames' must have shape {axes}, got {frames.shape}")
    if frames.dtype.kind not in "iuf":
        fail(where, f"'frames' must be float or integer, got dtype {frames.dtype}")
    if 0 in frames.shape:
        fail(where, f"'frames' is empty, shape {frames.shape}")
    return frames.astype(np.float32, copy=False) if frames.dtype.kind == "f" else frames


def _check_real(where: str, key: str, a: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    if a.dtype.kind not in "iuf":
        fail(where, f"'{key}' must be numeric, got dtype {a.dtype}")
    if a.shape != shape:
        fail(where, f"'{key}' must have shape {shape}, got {a.shape}")
    a = a.astype(np.float64, copy=False)
    _check_finite(where, key, a)
    return a


def _check_integers(where: str, key: str, a: np.ndarray, n: int) -> np.ndarray:
    if a.dtype.kind not in "iu":
        fail(where, f"'{key}' must be integers, got dtype {a.dtype}")
    if a.shape != (n,):
        fail(where, f"'{key}' must have shape ({n},) matching frames, got {a.shape}")
    return a.astype(np.int64, copy=False)


def _check_strings(where: str, key: str, a: np.ndarray) -> np.ndarray:
    if a.dtype.kind != "U":
        fail(where, f"'{key}' must be strings, got dtype {a.dtype}")
    if a.ndim != 1:
        fail(where, f"'{key}' must be one-dimensional, got shape {a.shape}")
    return a


def _check_rate(where: str, a: np.ndarray) -> float:
    if a.dtype.kind not in "iuf" or a.size != 1 or a.ndim > 1:
        fail(where, f"'sample_rate_hz' must be a scalar number, got {a.dtype} shape {a.shape}")
    rate = float(a.reshape(()))
    if not (np.isfinite(rate) and rate > 0):
        fail(where, f"'sample_rate_hz' must be finite and > 0, got {rate}")
    return rate


def _check_finite(where: str, key: str, a: np.ndarray) -> None:
    bad = a.size - int(np.count_nonzero(np.isfinite(a)))
    if bad:
        fail(where, f"'{key}' holds {bad} NaN or infinite value{'s' if bad > 1 else ''}")


def _require_keys(where: str, arrays: dict, keys: tuple[str, ...], kind: str) -> None:
    missing = [k for k in keys if k not in arrays]
    if missing:
        names = ", ".join(repr(k) for k in missing)
        fail(where, f"missing key{'s' if len(missing) > 1 else ''} {names} (needed by {kind})")


# ----------------------------------------------------------------------------- metadata


def _metadata_from_arrays(where: str, arrays: dict[str, np.ndarray], known) -> dict:
    metadata: dict = {}
    if METADATA_JSON_KEY in arrays:
        text = arrays[METADATA_JSON_KEY]
        if text.dtype.kind != "U" or text.ndim != 0:
            fail(where, f"'{METADATA_JSON_KEY}' must be a string, got {text.dtype} {text.shape}")
        try:
            metadata = loads_json(str(text), f"'{METADATA_JSON_KEY}'")
        except ValueError as exc:
            fail(where, str(exc))
        if not isinstance(metadata, dict):
            fail(where, f"'{METADATA_JSON_KEY}' must hold a JSON object")
    for key, value in arrays.items():
        if key not in known and key != METADATA_JSON_KEY:
            metadata[key] = value
    return metadata


def _metadata_to_arrays(where: str, metadata: dict, reserved) -> dict[str, np.ndarray]:
    arrays: dict[str, np.ndarray] = {}
    document: dict = {}
    taken = {*reserved, METADATA_JSON_KEY, *_SAVEZ_RESERVED}
    for key, value in metadata.items():
        if not isinstance(value, np.ndarray):
            document[key] = value
        elif key in taken:
            fail(where, f"metadata array {key!r} clashes with a reserved key")
        elif value.dtype.kind not in "biufcUS":
            fail(where, f"metadata array {key!r} has dtype {value.dtype}, which needs pickle")
        else:
            arrays[key] = value
    if document:
        try:
            arrays[METADATA_JSON_KEY] = np.array(dumps(document, allow_nan=True))
        except (TypeError, ValueError) as exc:
            fail(where, f"metadata is not JSON-serialisable ({exc})")
    return arrays


def _as_str_array(values) -> np.ndarray:
    a = np.asarray(values)
    return a.astype(str) if a.size == 0 or a.dtype.kind in "OS" else a
