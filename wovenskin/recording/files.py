"""One reader decides what a data file is; every command asks it.

wovenskin reads three kinds of file (``docs/recording-format.md``): a native ``.wsrec``
recording, a labelled-stream ``.npz`` and a labelled-captures ``.npz``.  :func:`file_kind`
decides which by content (never by suffix alone), and :func:`read_stream`,
:func:`read_as_recording`, :func:`read_captures` and :func:`read_any` read through it, so
``info``, ``convert``, ``replay``, ``eval-stream``, ``dataset``, ``train``, ``eval`` and
``run --skin replay:`` report the same one-line
:class:`~wovenskin.recording.untrusted.FormatError` for the same bad file (e.g.
:data:`~wovenskin.recording.untrusted.NOT_OURS` for random bytes).

:func:`unknown_labels` finds event labels that are none of the classes known (by default
wovenskin's 15 of ``docs/gestures.md``; a model's ``meta.json`` class names or a mapping's
custom gestures where given): ``info`` flags them, scoring refuses them.
"""

from __future__ import annotations

import os
import zipfile
from collections import Counter
from collections.abc import Iterable
from typing import Literal

from wovenskin.gestures import known_classes
from wovenskin.recording.formats import (
    LabelledCaptures,
    LabelledStream,
    read_labelled_captures,
    read_labelled_stream,
)
from wovenskin.recording.native import Recording, read_recording, recording_from_labelled_stream
from wovenskin.recording.untrusted import FormatError, identify

FileKind = Literal["recording", "stream", "captures"]
CAPTURES_ONLY_KEYS = ("lengths", "labels", "class_names", "groups")
"""Members only a labelled-captures ``.npz`` has (docs/formats.md)."""


def file_kind(path: str | os.PathLike) -> FileKind:
    """``"recording"``, ``"stream"`` or ``"captures"``, by content; FormatError otherwise.

    An ``.npz`` with any captures-only member (``lengths``, ``labels``, ...) is captures,
    any other ``.npz`` a stream (its reader then names what is missing).  Only member names
    are looked at: nothing is loaded.
    """
    if identify(path) == "recording":
        return "recording"
    try:
        with zipfile.ZipFile(path) as archive:
            names = {n.removesuffix(".npy") for n in archive.namelist()}
    except (OSError, zipfile.BadZipFile, ValueError) as exc:
        raise FormatError(f"{path}: corrupt .npz ({' '.join(str(exc).split())})") from None
    return "captures" if names & set(CAPTURES_ONLY_KEYS) else "stream"


def read_any(path: str | os.PathLike) -> Recording | LabelledStream | LabelledCaptures:
    """Whatever ``path`` holds, read by the reader of its kind."""
    kind = file_kind(path)
    if kind == "recording":
        return read_recording(path)
    if kind == "stream":
        return read_labelled_stream(path)
    return read_labelled_captures(path)


def _read_a_stream(path: str | os.PathLike, purpose: str) -> Recording | LabelledStream:
    """The recording (with frames) or labelled stream ``path`` holds; captures refused."""
    kind = file_kind(path)
    if kind == "recording":
        recording = read_recording(path)
        if len(recording.t) == 0:
            raise FormatError(f"{path}: recording holds no frames")
        return recording
    if kind == "stream":
        return read_labelled_stream(path)
    raise FormatError(
        f"{path}: holds labelled captures (separate clips), not a stream; {purpose} needs a "
        ".wsrec recording or a labelled-stream .npz"
    )


def read_stream(path: str | os.PathLike, purpose: str = "this") -> LabelledStream:
    """A labelled stream from a ``.wsrec`` (its trial labels become events) or a stream
    ``.npz``; labelled captures are refused in one line naming ``purpose`` (a command)."""
    data = _read_a_stream(path, purpose)
    return data.to_labelled_stream() if isinstance(data, Recording) else data


def read_as_recording(path: str | os.PathLike, purpose: str = "this") -> Recording:
    """A :class:`Recording` from a ``.wsrec`` (as it is) or a stream ``.npz`` (its events
    become trial labels, its stored skin info the info); captures refused like
    :func:`read_stream`."""
    data = _read_a_stream(path, purpose)
    if isinstance(data, Recording):
        return data
    try:
        return recording_from_labelled_stream(data)
    except ValueError as exc:
        raise FormatError(f"{path}: {exc}") from None


def read_captures(path: str | os.PathLike, purpose: str = "this") -> LabelledCaptures:
    """Labelled captures from ``path``; a recording or a stream is refused in one line."""
    kind = file_kind(path)
    if kind != "captures":
        what = "a .wsrec recording" if kind == "recording" else "a labelled stream"
        raise FormatError(
            f"{path}: holds {what}, not labelled captures; {purpose} needs a labelled-captures .npz"
        )
    return read_labelled_captures(path)


def unknown_labels(labels: Iterable[str], known: Iterable[str] = ()) -> Counter[str]:
    """How often each label that is none of wovenskin's 15 classes and of ``known`` (a
    model's class names, a mapping's custom gestures) occurs."""
    names = set(known_classes(known))
    return Counter(str(label) for label in labels if str(label) not in names)


def unknown_labels_message(where: str, unknown: Counter[str], known: Iterable[str] = ()) -> str:
    """One line naming the unknown labels of ``where`` and what is known (wovenskin's 15
    classes and ``known``)."""
    listed = ", ".join(f"{name!r} ({n} event{'s' if n > 1 else ''})" for name, n in
                       sorted(unknown.items()))  # fmt: skip
    return (
        f"{where}: unknown gesture label{'s' if len(unknown) > 1 else ''} {listed}; "
        f"wovenskin knows {', '.join(known_classes(known))}"
    )
