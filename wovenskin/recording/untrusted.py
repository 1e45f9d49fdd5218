"""Reading bytes a stranger may have crafted: what a file is, bounded JSON, safe ``.npz``.

:func:`identify` tells wovenskin's files from anything else with one message
(:data:`NOT_OURS`) for every reader; :func:`loads_json` never recurses out of its stack;
:func:`load_npz` never unpickles and checks every member's declared shape and dtype
against its size before allocating, so a crafted file cannot ask for terabytes.  Every
problem is one :class:`FormatError` line naming the file.
"""

from __future__ import annotations

import json
import math
import os
import zipfile
import zlib
from typing import IO, Any, NoReturn

import numpy as np

from wovenskin.errors import DataError


class FormatError(DataError):
    """A file does not follow the format it claims to be in (a ``ValueError``)."""


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
        fail(where, "no such file")
    except IsADirectoryError:
        fail(where, "is a folder, not a file")
    except OSError as exc:
        fail(where, f"cannot read ({exc.strerror or exc})")
    if not head:
        fail(where, "empty file (0 bytes)")
    if WSREC_MAGIC_PREFIX.startswith(head) or head.startswith(WSREC_MAGIC_PREFIX):
        return "recording"
    if is_zip:
        return "npz"
    if head.startswith(_ZIP_LOCAL_HEADER):
        fail(where, "damaged .npz: it starts as a zip file but has no zip directory (cut off?)")
    fail(where, NOT_OURS)


def loads_json(text: str | bytes, what: str) -> Any:
    """Parse JSON that came from a file: ``ValueError`` (one line) for anything bad.

    Never a ``RecursionError``: nesting deeper than :data:`MAX_JSON_DEPTH` levels is
    refused, so no reader (or printer) of the result can recurse out of its stack.
    ``NaN`` and ``Infinity`` are accepted (Python writes them).
    """
    try:
        value = json.loads(text)
    except RecursionError:
        raise DataError(f"{what} is nested deeper than {MAX_JSON_DEPTH} levels") from None
    except json.JSONDecodeError as exc:
        raise DataError(f"{what} is not valid JSON ({exc.msg} at character {exc.pos})") from None
    except UnicodeDecodeError:
        raise DataError(f"{what} is not UTF-8 text") from None
    if _json_depth(value) > MAX_JSON_DEPTH:
        raise DataError(f"{what} is nested deeper than {MAX_JSON_DEPTH} levels")
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


def load_npz(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """Every member of an ``.npz`` as an array, sizes checked before anything is allocated."""
    where = str(path)
    if identify(path) == "recording":
        fail(where, "is a .wsrec recording, not an .npz file")
    arrays: dict[str, np.ndarray] = {}
    try:
        with zipfile.ZipFile(path) as archive:
            for member in archive.infolist():
                if member.is_dir():
                    continue
                if not member.filename.endswith(".npy"):
                    fail(where, f"member {member.filename!r} is not a NumPy array")
                key = member.filename[: -len(".npy")]
                with archive.open(member) as f:
                    arrays[key] = _read_npy(where, key, f, member)
    except FormatError:
        raise
    except (
        OSError, EOFError, KeyError, ValueError, SyntaxError, RuntimeError,
        NotImplementedError, zipfile.BadZipFile, zlib.error,
    ) as exc:  # fmt: skip
        fail(where, f"corrupt .npz ({one_line(exc)})")
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
        fail(where, f"member {key!r} has an unreadable .npy header ({one_line(exc)[:120]})")
    fail(where, f"member {key!r} has .npy version {version}, which is not read")


def _read_npy(where: str, key: str, f: IO[bytes], member: zipfile.ZipInfo) -> np.ndarray:
    """One ``.npy`` member: header parsed, its shape x dtype checked against the member's
    size (and that size against what its compressed bytes can hold) before allocating."""
    if member.file_size > _MAX_DEFLATE_RATIO * member.compress_size + 65_536:
        fail(
            where,
            f"member {key!r} claims {member.file_size} bytes from {member.compress_size} "
            "compressed ones, more than compression can produce: corrupt, or a zip bomb",
        )
    shape, fortran_order, dtype = _npy_header(where, key, f)
    if dtype.hasobject:
        fail(where, "holds Python objects (pickled arrays), which are never loaded")
    if not all(isinstance(n, int) and n >= 0 for n in shape):
        fail(where, f"member {key!r} declares an impossible shape {shape}")
    count = math.prod(shape)
    nbytes = count * dtype.itemsize
    held = member.file_size - f.tell()
    if nbytes != held:
        fail(
            where,
            f"member {key!r} declares shape {shape} of {dtype} ({nbytes} bytes) but holds "
            f"{held} bytes",
        )
    try:
        buffer = bytearray(nbytes)
    except MemoryError:
        fail(where, f"member {key!r} needs {nbytes} bytes, more memory than is available")
    view, filled = memoryview(buffer), 0
    while filled < nbytes:
        got = f.readinto(view[filled:])
        if not got:
            fail(where, f"member {key!r} ends after {filled} of its {nbytes} bytes")
        filled += got
    array = np.frombuffer(buffer, dtype=dtype, count=count)
    return array.reshape(shape, order="F" if fortran_order else "C")


def one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split()) or type(exc).__name__


def fail(where: str, problem: str) -> NoReturn:
    raise FormatError(f"{where}: {problem}")
