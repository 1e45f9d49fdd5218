"""Output files are never replaced unless the caller asks: one rule for every writer.

Every wovenskin writer (recordings, labelled streams and captures, traces, view snapshots,
data sets, checkpoints) checks its target with :func:`check_new_output` or creates it with
:func:`open_new`, and refuses an existing one with :class:`OutputExistsError`.  The error
carries the path and the name of the switch that allows replacing, so the Python API says
``overwrite=True`` and the command line (which renders the error itself) says
``--overwrite``: the same refusal, in each caller's own words.

Before any long work, a command checks that its outputs can be written at all
(:func:`check_writable`, which :func:`check_new_output` calls): a target that is a folder
where a file is meant (or the reverse), a parent that is a file, or a folder that may not
be written is refused at once with :class:`OutputNotWritableError`, naming the user's
path, not after the work and not through an internal temporary file.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import IO

from wovenskin.errors import WovenskinError

PYTHON_SWITCH = "overwrite=True"
CLI_SWITCH = "--overwrite"


class OutputExistsError(WovenskinError, FileExistsError):
    """An output exists and replacing it was not asked for.

    ``str(error)`` names the Python keyword; :meth:`message` names any other switch (the
    command line passes ``--overwrite``).
    """

    def __init__(self, path: str | os.PathLike, what: str = "") -> None:
        self.path = Path(path)
        self.what = what
        super().__init__(self.message(PYTHON_SWITCH))

    def message(self, switch: str) -> str:
        """The one-line refusal, naming ``switch`` as the way to replace the output."""
        holds = f"already holds {self.what}" if self.what else "exists"
        return f"{self.path} {holds}; pass {switch} to replace it"


class OutputNotWritableError(WovenskinError):
    """An output could not be written where it was asked for (the reason in the message)."""

    def __init__(self, path: str | os.PathLike, reason: str) -> None:
        self.path = Path(path)
        self.reason = reason
        super().__init__(f"cannot write {self.path}: {reason}")


def check_writable(path: str | os.PathLike, *, folder: bool = False) -> Path:
    """``path`` as a :class:`Path` if it can be written: a file (``folder=False``) or a
    folder to write into (``folder=True``), created with any missing parents.

    The nearest existing folder on the way must be writable: for a file, its own folder
    (files are written through a temporary beside them); for a folder, the folder itself
    or the nearest existing parent.  Raises :class:`OutputNotWritableError` otherwise.
    """
    target = Path(path)
    if target.is_dir() and not folder:
        raise OutputNotWritableError(target, "it is a folder")
    if target.exists() and not target.is_dir() and folder:
        raise OutputNotWritableError(target, "it is a file, not a folder")
    start = target if folder else target.parent
    existing = next(p for p in (start, *start.parents) if p.exists() or p == p.parent)
    if not existing.is_dir():
        raise OutputNotWritableError(target, f"{existing} is a file, not a folder")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise OutputNotWritableError(target, f"the folder {existing} is not writable")
    return target


def check_new_output(
    path: str | os.PathLike, overwrite: bool, what: str = "", *, folder: bool = False
) -> Path:
    """``path`` as a :class:`Path` if it may be written: it does not exist or ``overwrite``,
    and it can be written (:func:`check_writable`; ``folder`` for an output folder).

    ``what`` says what the existing output holds when that is worth telling (e.g. "a
    trained model").  Raises :class:`OutputExistsError` or :class:`OutputNotWritableError`.
    """
    target = Path(path)
    if not overwrite and (target.exists() or target.is_symlink()):
        raise OutputExistsError(target, what)
    return check_writable(target, folder=folder)


def open_new(path: str | os.PathLike, overwrite: bool, *, binary: bool = False) -> IO:
    """Open ``path`` for writing: created new (atomically: ``x`` mode) unless ``overwrite``.

    Text files are UTF-8.  Raises :class:`OutputExistsError` for an existing file.
    """
    mode = ("w" if overwrite else "x") + ("b" if binary else "")
    try:
        if binary:
            return open(path, mode)  # noqa: SIM115 (the caller owns the file)
        return open(path, mode, encoding="utf-8")  # noqa: SIM115
    except FileExistsError:
        raise OutputExistsError(path) from None
