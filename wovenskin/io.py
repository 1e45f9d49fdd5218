"""File writing that never leaves a torn file, and numpy values made JSON-ready.

Every writer in wovenskin goes through these helpers: :func:`atomic_write_bytes` and
:func:`atomic_write_text` write beside the target and rename over it (a crash leaves the
old file or the new one, never half of one); :func:`to_jsonable` turns numpy scalars and
arrays, paths and tuples into plain JSON values; :func:`dumps` is ``json.dumps`` with it;
:func:`plain_dict` reads a mapping or a settings object as a dict.
Whether an existing output may be replaced at all is :mod:`wovenskin.outputs`' rule.
"""

from __future__ import annotations

import dataclasses
import json
import os
import tempfile
from collections.abc import Callable, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any

import numpy as np


def _read_umask() -> int:
    mask = os.umask(0o022)  # os.umask both sets and returns: read it once, at import
    os.umask(mask)
    return mask


_NEW_FILE_MODE = 0o666 & ~_read_umask()  # what open(path, "w") would give a new file


@contextmanager
def atomic_writer(path: str | os.PathLike, *, binary: bool = True):
    """Open a temporary file beside ``path``; on a clean exit it replaces ``path``.

    On an exception the temporary file is removed and ``path`` is left as it was.  The
    file gets the permissions a plain ``open(path, "w")`` would give it (a temporary file
    is private, 0600, until then).
    """
    target = Path(path)
    if not target.parent.is_dir():  # never name the temporary file in the error
        raise FileNotFoundError(f"{target}: no such folder {str(target.parent)!r} to write into")
    try:
        fd, tmp = tempfile.mkstemp(dir=target.parent, prefix=f".{target.name}.", suffix=".partial")
    except OSError as exc:
        raise type(exc)(f"{target}: cannot write ({exc.strerror or exc})") from None
    try:
        os.chmod(fd, _NEW_FILE_MODE)
        text_options = {} if binary else {"encoding": "utf-8"}
        with os.fdopen(fd, "wb" if binary else "w", **text_options) as f:
            yield f
        os.replace(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file and a rename (no torn files)."""
    with atomic_writer(path) as f:
        f.write(data)


def atomic_write_text(path: str | os.PathLike, text: str) -> None:
    """Write UTF-8 ``text`` to ``path`` through a temporary file and a rename."""
    with atomic_writer(path, binary=False) as f:
        f.write(text)


def atomic_write_with(path: str | os.PathLike, write: Callable[[IO[bytes]], Any]) -> None:
    """Call ``write(file)`` on a temporary binary file that then replaces ``path``
    (e.g. ``lambda f: np.savez_compressed(f, **arrays)``)."""
    with atomic_writer(path) as f:
        write(f)


def to_jsonable(value: Any) -> Any:
    """``value`` with numpy scalars and arrays, tuples, paths and dataclasses made into
    plain JSON values (recursively through dicts and lists).  Anything else is returned
    as it is, for ``json`` to accept or refuse."""
    if isinstance(value, dict):
        return {str(k) if not isinstance(k, str) else k: to_jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [to_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return to_jsonable(dataclasses.asdict(value))
    return value


def plain_dict(value: Any, what: str) -> dict[str, Any]:
    """A mapping, or a settings object with ``to_dict()``, as a new plain dict; anything
    else is a ``TypeError`` naming ``what``."""
    if isinstance(value, Mapping):
        return dict(value)
    to_dict = getattr(value, "to_dict", None)
    if callable(to_dict):
        return dict(to_dict())
    raise TypeError(f"{what} must be a mapping or have to_dict(), got {type(value)}")


def dumps(value: Any, **kwargs: Any) -> str:
    """``json.dumps`` of :func:`to_jsonable` ``(value)``; non-finite floats are refused."""
    kwargs.setdefault("allow_nan", False)
    return json.dumps(to_jsonable(value), **kwargs)


def write_json(path: str | os.PathLike, value: Any, *, indent: int | None = 2) -> None:
    """Write ``value`` as JSON (with a final newline) to ``path`` atomically."""
    atomic_write_text(path, dumps(value, indent=indent) + "\n")
