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
"""

from __future__ import annotations

import json
import math
import os
import zipfile
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any, NoReturn

import numpy as np

from wovenskin.outputs import check_new_output


class FormatError(ValueError):
    """A file does not follow the format it claims to be in."""


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

WSREC_MAGIC_PREFIX = b"wovenskin.wsrec "
"""How a native ``.wsrec`` recording starts (its magic line, before the version)."""
NOT_OURS = (
    "not a wovenskin data file (neither a .wsrec recording nor an .npz labelled stream "
    "or labelled captures)"
)
"""What every reader and command says of a file that is none of wovenskin's formats."""
MAX_JSON_DEPTH = 64
"""Deepest nesting of lists and objects accepted in JSON read from a file."""
_ZIP_LOCAL_HEADER = b"PK\x03\x04"
_MAX_DEFLATE_RATIO = 1100  # deflate cannot expand past ~1032:1


# ----------------------------------------------------------------------------- readers


def read_labelled_stream(path: str | os.PathLike) -> LabelledStream:
    """Read and validate a labelled-stream ``.npz``; :class:`FormatError` if it is bad."""
    where = str(path)
    arrays = _load_npz(path)
    missing = [k for k in STREAM_KEYS if k not in arrays]
    if missing and {"lengths", "labels"} <= arrays.keys():
        _fail(where, "is a labelled-captures file, not a labelled stream")
    _require_keys(where, arrays, STREAM_KEYS, "a labelled stream")
    return _stream_from_arrays(where, arrays)


def read_labelled_captures(path: str | os.PathLike) -> LabelledCaptures:
    """Read and validate a labelled-captures ``.npz``; :class:`FormatError` if it is bad."""
    where = str(path)
    arrays = _load_npz(path)
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
    _save_npz(path, arrays)


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
    _save_npz(path, arrays)


# ----------------------------------------------------------------------------- validation


def _stream_from_arrays(where: str, arrays: dict[str, np.ndarray]) -> LabelledStream:
    frames = _check_frames(where, arrays["frames"], "(T, R, C)")
    n_frames = frames.shape[0]
    t = _check_real(where, "t", arrays["t"], (n_frames,))
    if n_frames > 1 and not np.all(np.diff(t) > 0):
        i = int(np.argmin(np.diff(t) > 0))
        _fail(where, f"'t' must be strictly increasing, but t[{i + 1}]={t[i + 1]} <= t[{i}]={t[i]}")
    rate = _check_rate(where, arrays["sample_rate_hz"])
    if frames.dtype.kind == "f":
        _check_finite(where, "frames", frames)
    present = [k for k in EVENT_KEYS if k in arrays]
    if present and len(present) < len(EVENT_KEYS):
        absent = [k for k in EVENT_KEYS if k not in arrays]
        _fail(where, f"event keys come together: has {present} but not {absent}")
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
            _fail(where, problem)
    else:
        labels, starts, ends = np.zeros(0, dtype=str), np.zeros(0), np.zeros(0)
    known = (*STREAM_KEYS, *EVENT_KEYS)
    return LabelledStream(
        frames=frames,
        t=t,
        sample_rate_hz=rate,
        event_start_s=starts,
        event_end_s=ends,
        event_labels=labels,
        metadata=_metadata_from_arrays(where, arrays, known),
    )


def _captures_from_arrays(where: str, arrays: dict[str, np.ndarray]) -> LabelledCaptures:
    frames = _check_frames(where, arrays["frames"], "(N, T, R, C)")
    n, t_max = frames.shape[:2]
    lengths = _check_integers(where, "lengths", arrays["lengths"], n)
    out_of_range = np.flatnonzero((lengths < 1) | (lengths > t_max))
    if out_of_range.size:
        i = int(out_of_range[0])
        _fail(where, f"'lengths' must lie in [1, {t_max}], but capture {i} has {lengths[i]}")
    class_names = _check_strings(where, "class_names", arrays["class_names"])
    if class_names.size == 0:
        _fail(where, "'class_names' is empty")
    if len(set(class_names.tolist())) != class_names.size:
        _fail(where, f"'class_names' has duplicates: {class_names.tolist()}")
    labels = _check_integers(where, "labels", arrays["labels"], n)
    bad = np.flatnonzero((labels < 0) | (labels >= class_names.size))
    if bad.size:
        i = int(bad[0])
        _fail(
            where,
            f"'labels' must index class_names (0..{class_names.size - 1}), capture {i} "
            f"has {labels[i]}",
        )
    groups = _check_strings(where, "groups", arrays["groups"])
    if groups.shape != (n,):
        _fail(where, f"'groups' must have shape ({n},) matching frames, got {groups.shape}")
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
        _fail(where, f"'frames' must have shape {axes}, got {frames.shape}")
    if frames.dtype.kind not in "iuf":
        _fail(where, f"'frames' must be float or integer, got dtype {frames.dtype}")
    if 0 in frames.shape:
        _fail(where, f"'frames' is empty, shape {frames.shape}")
    return frames.astype(np.float32, copy=False) if frames.dtype.kind == "f" else frames


def _check_real(where: str, key: str, a: np.ndarray, shape: tuple[int, ...]) -> np.ndarray:
    if a.dtype.kind not in "iuf":
        _fail(where, f"'{key}' must be numeric, got dtype {a.dtype}")
    if a.shape != shape:
        _fail(where, f"'{key}' must have shape {shape}, got {a.shape}")
    a = a.astype(np.float64, copy=False)
    _check_finite(where, key, a)
    return a


def _check_integers(where: str, key: str, a: np.ndarray, n: int) -> np.ndarray:
    if a.dtype.kind not in "iu":
        _fail(where, f"'{key}' must be integers, got dtype {a.dtype}")
    if a.shape != (n,):
        _fail(where, f"'{key}' must have shape ({n},) matching frames, got {a.shape}")
    return a.astype(np.int64, copy=False)


def _check_strings(where: str, key: str, a: np.ndarray) -> np.ndarray:
    if a.dtype.kind != "U":
        _fail(where, f"'{key}' must be strings, got dtype {a.dtype}")
    if a.ndim != 1:
        _fail(where, f"'{key}' must be one-dimensional, got shape {a.shape}")
    return a


def _check_rate(where: str, a: np.ndarray) -> float:
    if a.dtype.kind not in "iuf" or a.size != 1 or a.ndim > 1:
        _fail(where, f"'sample_rate_hz' must be a scalar number, got {a.dtype} shape {a.shape}")
    rate = float(a.reshape(()))
    if not (np.isfinite(rate) and rate > 0):
        _fail(where, f"'sample_rate_hz' must be finite and > 0, got {rate}")
    return rate


def _check_finite(where: str, key: str, a: np.ndarray) -> None:
    bad = a.size - int(np.count_nonzero(np.isfinite(a)))
    if bad:
        _fail(where, f"'{key}' holds {bad} NaN or infinite value{'s' if bad > 1 else ''}")


def _require_keys(where: str, arrays: dict, keys: tuple[str, ...], kind: str) -> None:
    missing = [k for k in keys if k not in arrays]
    if missing:
        names = ", ".join(repr(k) for k in missing)
        _fail(where, f"missing key{'s' if len(missing) > 1 else ''} {names} (needed by {kind})")


# ----------------------------------------------------------------------------- metadata


def _metadata_from_arrays(where: str, arrays: dict[str, np.ndarray], known) -> dict:
    metadata: dict = {}
    if METADATA_JSON_KEY in arrays:
        text = arrays[METADATA_JSON_KEY]
        if text.dtype.kind != "U" or text.ndim != 0:
            _fail(where, f"'{METADATA_JSON_KEY}' must be a string, got {text.dtype} {text.shape}")
        try:
            metadata = loads_json(str(text), f"'{METADATA_JSON_KEY}'")
        except ValueError as exc:
            _fail(where, str(exc))
        if not isinstance(metadata, dict):
            _fail(where, f"'{METADATA_JSON_KEY}' must hold a JSON object")
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
            _fail(where, f"metadata array {key!r} clashes with a reserved key")
        elif value.dtype.kind not in "biufcUS":
            _fail(where, f"metadata array {key!r} has dtype {value.dtype}, which needs pickle")
        else:
            arrays[key] = value
    if document:
        try:
            arrays[METADATA_JSON_KEY] = np.array(json.dumps(document, default=_json_default))
        except (TypeError, ValueError) as exc:
            _fail(where, f"metadata is not JSON-serialisable ({exc})")
    return arrays


def _json_default(value):
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    raise TypeError(f"{type(value).__name__} is not JSON-serialisable")


# ----------------------------------------------------------------------------- file access


def identify(path: str | os.PathLike) -> str:
    """What a file is by its content: ``"recording"`` (``.wsrec``) or ``"npz"``.

    The one place that tells wovenskin's files from anything else, so that every reader and
    every command reports the same one-line :class:`FormatError` for the same bad file: no
    such file, unreadable, empty, a damaged ``.npz`` (a zip start without a directory), or
    :data:`NOT_OURS`.  A file that starts with (a prefix of) the ``.wsrec`` magic line is a
    recording, to be judged by its reader (e.g. "cut off inside its header").
    """
    where = str(path)
    try:
        with open(path, "rb") as f:
            head = f.read(len(WSREC_MAGIC_PREFIX))
            is_zip = zipfile.is_zipfile(f)
    except FileNotFoundError:
        _fail(where, "no such file")
    except OSError as exc:
        _fail(where, f"cannot read ({exc.strerror or exc})")
    if not head:
        _fail(where, "empty file (0 bytes)")
    if WSREC_MAGIC_PREFIX.startswith(head) or head.startswith(WSREC_MAGIC_PREFIX):
        return "recording"
    if is_zip:
        return "npz"
    if head.startswith(_ZIP_LOCAL_HEADER):
        _fail(where, "damaged .npz: it starts as a zip file but has no zip directory (cut off?)")
    _fail(where, NOT_OURS)


def loads_json(text: str | bytes, what: str) -> Any:
    """Parse JSON that came from a file: ``ValueError`` (one line) for anything bad.

    Never a ``RecursionError``: nesting deeper than :data:`MAX_JSON_DEPTH` levels is
    refused, so no reader (or printer) of the result can recurse out of its stack.
    ``NaN`` and ``Infinity`` are accepted (Python writes them).
    """
    try:
        value = json.loads(text)
    except RecursionError:
        raise ValueError(f"{what} is nested deeper than {MAX_JSON_DEPTH} levels") from None
    except json.JSONDecodeError as exc:
        raise ValueError(f"{what} is not valid JSON ({exc.msg} at character {exc.pos})") from None
    except UnicodeDecodeError:
        raise ValueError(f"{what} is not UTF-8 text") from None
    if _json_depth(value) > MAX_JSON_DEPTH:
        raise ValueError(f"{what} is nested deeper than {MAX_JSON_DEPTH} levels")
    return value


def _json_depth(value: Any) -> int:
    """How deeply lists and objects nest in a parsed JSON value (iteratively: no recursion)."""
    deepest, todo = 0, [(value, 1)]
    while todo:
        item, depth = todo.pop()
        if isinstance(item, dict):
            children = item.values()
        elif isinstance(item, list):
            children = item
        else:
            continue
        deepest = max(deepest, depth)
        if deepest > MAX_JSON_DEPTH:
            return deepest
        todo.extend((child, depth + 1) for child in children)
    return deepest


def _load_npz(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """Every member of an ``.npz`` as an array, sizes checked before anything is allocated."""
    where = str(path)
    if identify(path) == "recording":
        _fail(where, "is a .wsrec recording, not an .npz file")
    arrays: dict[str, np.ndarray] = {}
    try:
        with zipfile.ZipFile(path) as archive:
            for member in archive.infolist():
                if member.is_dir():
                    continue
                if not member.filename.endswith(".npy"):
                    _fail(where, f"member {member.filename!r} is not a NumPy array")
                key = member.filename[: -len(".npy")]
                with archive.open(member) as f:
                    arrays[key] = _read_npy(where, key, f, member)
    except FormatError:
        raise
    except (
        OSError, EOFError, KeyError, ValueError, SyntaxError, RuntimeError,
        NotImplementedError, zipfile.BadZipFile, zlib.error,
    ) as exc:  # fmt: skip
        _fail(where, f"corrupt .npz ({_one_line(exc)})")
    return arrays


def _npy_header(where: str, key: str, f: IO[bytes]) -> tuple[tuple, bool, np.dtype]:
    """``(shape, fortran_order, dtype)`` from a member's ``.npy`` header.

    NumPy parses the header's Python literal with ``tokenize`` and ``ast``, which fail on
    garbage with whatever they raise (``TokenError``, ``SyntaxError``, ``ValueError``...):
    every such failure becomes one line here."""
    try:
        version = np.lib.format.read_magic(f)
        if version == (1, 0):
            return np.lib.format.read_array_header_1_0(f)
        if version in ((2, 0), (3, 0)):
            return np.lib.format.read_array_header_2_0(f)
    except Exception as exc:  # noqa: BLE001 - numpy's header parser on arbitrary bytes
        _fail(where, f"member {key!r} has an unreadable .npy header ({_one_line(exc)[:120]})")
    _fail(where, f"member {key!r} has .npy version {version}, which is not read")


def _read_npy(where: str, key: str, f: IO[bytes], member: zipfile.ZipInfo) -> np.ndarray:
    """One ``.npy`` member: header parsed, its shape x dtype checked against the member's
    size (and that size against what its compressed bytes can hold) before allocating."""
    if member.file_size > _MAX_DEFLATE_RATIO * member.compress_size + 65_536:
        _fail(
            where,
            f"member {key!r} claims {member.file_size} bytes from {member.compress_size} "
            "compressed ones, more than compression can produce: corrupt, or a zip bomb",
        )
    shape, fortran_order, dtype = _npy_header(where, key, f)
    if dtype.hasobject:
        _fail(where, "holds Python objects (pickled arrays), which are never loaded")
    if not all(isinstance(n, int) and n >= 0 for n in shape):
        _fail(where, f"member {key!r} declares an impossible shape {shape}")
    count = math.prod(shape)
    nbytes = count * dtype.itemsize
    held = member.file_size - f.tell()
    if nbytes != held:
        _fail(
            where,
            f"member {key!r} declares shape {shape} of {dtype} ({nbytes} bytes) but holds "
            f"{held} bytes",
        )
    try:
        buffer = bytearray(nbytes)
    except MemoryError:
        _fail(where, f"member {key!r} needs {nbytes} bytes, more memory than is available")
    view, filled = memoryview(buffer), 0
    while filled < nbytes:
        got = f.readinto(view[filled:])
        if not got:
            _fail(where, f"member {key!r} ends after {filled} of its {nbytes} bytes")
        filled += got
    array = np.frombuffer(buffer, dtype=dtype, count=count)
    return array.reshape(shape, order="F" if fortran_order else "C")


def _save_npz(path: str | os.PathLike, arrays: dict[str, np.ndarray]) -> None:
    target = Path(path)
    partial = target.with_name(target.name + ".partial")
    try:
        with open(partial, "wb") as f:
            np.savez_compressed(f, **arrays)
        os.replace(partial, target)
    finally:
        partial.unlink(missing_ok=True)


def _as_str_array(values) -> np.ndarray:
    a = np.asarray(values)
    return a.astype(str) if a.size == 0 or a.dtype.kind in "OS" else a


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split()) or type(exc).__name__


def _fail(where: str, problem: str) -> NoReturn:
    raise FormatError(f"{where}: {problem}")
