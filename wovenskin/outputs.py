"""Output files are never replaced unless the caller asks: one rule for every writer.

Every wovenskin writer (recordings, labelled streams and captures, traces, view snapshots,
data sets, checkpoints) checks its target with :func:`check_new_output` or creates it with
:func:`open_new`, and refuses an existing one with :class:`OutputExistsError`.  The error
carries the path and the name of the switch that allows replacing, so the Python API says
``overwrite=True`` and the command line (which renders the error itself) says
``--overwrite``: the same refusal, in each caller's own words.
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


def check_new_output(path: str | os.PathLike, overwrite: bool, what: str = "") -> Path:
    """``path`` as a :class:`Path` if it may be written: it does not exist or ``overwrite``.

    ``what`` says what the existing output holds when that is worth telling (e.g. "a
    trained model").  Raises :class:`OutputExistsError` otherwise.
    """
    target = Path(path)
    if not overwrite and (target.exists() or target.is_symlink()):
        raise OutputExistsError(target, what)
    return target


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
