"""``wovenskin info`` and ``wovenskin convert``: describe and convert data files.

Knows the three kinds of file wovenskin reads: labelled streams and labelled captures
(``.npz``, docs/formats.md) and native recordings (``.wsrec``).  The kind is decided by
:func:`wovenskin.recording.files.file_kind`, by content, so a mis-named file is still
described correctly and a bad one gets the same message as from every other command.
ROS 2 bags written by wovenskin (``.mcap`` or a rosbag2 directory,
:mod:`wovenskin.recording.bag`) are described and converted too.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterable
from pathlib import Path

import numpy as np
from rich.markup import escape
from rich.table import Table

from wovenskin.custom_gestures import custom_from_settings
from wovenskin.outputs import check_new_output
from wovenskin.recording.bag import is_bag, read_bag, write_bag
from wovenskin.recording.files import (
    file_kind,
    read_as_recording,
    read_stream,
    unknown_labels,
    unknown_labels_message,
)
from wovenskin.recording.formats import (
    read_labelled_captures,
    read_labelled_stream,
    write_labelled_stream,
)
from wovenskin.recording.native import (
    Recording,
    read_recording,
    recording_from_labelled_stream,
    write_recording,
)
from wovenskin.recording.records import LABEL_KIND_TRIAL
from wovenskin.recording.untrusted import FormatError

__all__ = ["convert_file", "describe_file", "file_kind"]


def describe_file(path: Path) -> Table:
    """A two-column table of what ``path`` holds (FormatError if it is not a data file)."""
    path = Path(path)
    bag = is_bag(path)
    kind = "ROS 2 bag" if bag else file_kind(path)
    table = Table(title=f"{path} ({kind})", show_header=False)
    table.add_column(style="dim", justify="right")
    table.add_column()
    if bag:
        _recording_rows(table, read_bag(path), str(path))
    elif kind == "stream":
        s = read_labelled_stream(path)
        _rows(table, s.frames, s.sample_rate_hz, float(s.t[-1] - s.t[0]) if len(s.t) else 0.0)
        known = custom_from_settings((s.metadata or {}).get("settings"))
        _label_rows(table, [str(x) for x in s.event_labels], str(path), known=known)
        if s.metadata:
            table.add_row("metadata", ", ".join(sorted(s.metadata))[:200])
    elif kind == "captures":
        c = read_labelled_captures(path)
        table.add_row("captures", f"{len(c.lengths)} x {c.frames.shape[1]} frames")
        table.add_row("grid", f"{c.frames.shape[2]} x {c.frames.shape[3]}, {c.frames.dtype}")
        table.add_row("rate", f"{c.sample_rate_hz:g} Hz")
        counts = Counter(c.class_names[i] for i in c.labels)
        table.add_row("classes", ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))
        groups = Counter(str(g) for g in c.groups)
        table.add_row("groups", ", ".join(f"{k} {v}" for k, v in sorted(groups.items())))
    else:
        _recording_rows(table, read_recording(path), str(path))
    return table


def _recording_rows(table: Table, rec: Recording, where: str) -> None:
    duration = float(rec.t[-1] - rec.t[0]) if len(rec.t) else 0.0
    _rows(table, rec.frames, rec.info.sample_rate_hz, duration)
    table.add_row("device", f"{rec.info.source} {rec.info.device_id} {rec.info.firmware}")
    for key in ("participant", "operator", "skin_id", "started_utc", "host"):
        if rec.provenance.get(key):
            table.add_row(key, str(rec.provenance[key]))
    table.add_row("calibrations", str(len(rec.calibrations)))
    trials = [lab.label for lab in rec.labels if lab.kind == LABEL_KIND_TRIAL]
    known = custom_from_settings(rec.settings)  # a recording's own custom gestures
    _label_rows(table, [lab.label for lab in rec.labels], where, trials, known)
    table.add_row("annotations", str(len(rec.annotations)))
    table.add_row("closed cleanly", "yes" if rec.clean_close else "[yellow]no[/]")
    for warning in rec.warnings:
        table.add_row("warning", f"[yellow]{escape(warning)}[/]")


def _rows(table: Table, frames: np.ndarray, rate: float, duration: float) -> None:
    n, rows, cols = frames.shape
    table.add_row("frames", f"{n} ({duration:.2f} s)")
    table.add_row("grid", f"{rows} x {cols}, {frames.dtype}")
    table.add_row("rate", f"{rate:g} Hz")
    if n:
        table.add_row("values", f"min {np.nanmin(frames):.4g}, max {np.nanmax(frames):.4g}")


def _label_rows(
    table: Table,
    labels: list[str],
    where: str,
    events: list[str] | None = None,
    known: Iterable[str] = (),
) -> None:
    """Label counts, and a warning row for ``events`` (default: all labels) that are
    neither gestures wovenskin knows nor ``known`` (the custom gestures the file defines)."""
    counts = Counter(labels)
    table.add_row("events", str(len(labels)))
    if counts:
        table.add_row("labels", ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))
    unknown = unknown_labels(labels if events is None else events, known)
    if unknown:
        message = unknown_labels_message(where, unknown, known)
        table.add_row("warning", f"[yellow]{escape(message)}[/]")


def convert_file(src: Path, dst: Path, overwrite: bool = False) -> str:
    """Convert between a recording, a labelled stream and a ROS 2 bag; returns a one-line
    summary.

    ``dst`` must end in ``.npz``, ``.wsrec`` or ``.mcap`` and not exist unless
    ``overwrite`` (:class:`~wovenskin.outputs.OutputExistsError`).  A bag ``src`` (an
    ``.mcap`` or a rosbag2 directory) is read by :func:`~wovenskin.recording.bag.read_bag`;
    anything else through :mod:`wovenskin.recording.files`, so labelled captures are
    refused there.  ``.wsrec <-> .mcap`` is lossless; ``.npz`` keeps frames, times and
    trial labels.
    """
    src, dst = Path(src), Path(dst)
    if dst.suffix not in (".npz", ".wsrec", ".mcap"):
        raise FormatError(f"{dst}: output must end in .npz, .wsrec or .mcap")
    check_new_output(dst, overwrite)
    if is_bag(src):
        if dst.suffix == ".mcap":
            raise FormatError(f"{src}: already a ROS 2 bag; convert it to .wsrec or .npz")
        recording = read_bag(src)
        if dst.suffix == ".wsrec":
            write_recording(dst, recording, overwrite=overwrite)
            return f"wrote {dst}: {_counts(recording)}"
        stream = recording.to_labelled_stream()
        write_labelled_stream(dst, stream, overwrite=overwrite)
        return f"wrote {dst}: {len(stream.t)} frames, {len(stream.event_labels)} events"
    if dst.suffix == ".mcap":
        recording = read_as_recording(src, "convert")
        write_bag(dst, recording, overwrite=overwrite)
        return f"wrote {dst}: {_counts(recording)}"
    if dst.suffix == ".wsrec" and file_kind(src) == "recording":
        raise FormatError(f"{src}: already a .wsrec recording; convert it to .npz (or copy it)")
    stream = read_stream(src, "convert")
    if dst.suffix == ".npz":
        write_labelled_stream(dst, stream, overwrite=overwrite)
        return f"wrote {dst}: {len(stream.t)} frames, {len(stream.event_labels)} events"
    try:
        recording = recording_from_labelled_stream(stream)
    except ValueError as exc:
        raise FormatError(f"{src}: {exc}") from None
    write_recording(dst, recording, overwrite=overwrite)
    return f"wrote {dst}: {len(stream.t)} frames, {len(stream.event_labels)} labels"


def _counts(recording: Recording) -> str:
    return (
        f"{len(recording.t)} frames, {len(recording.labels)} labels, "
        f"{len(recording.calibrations)} calibrations, {len(recording.annotations)} annotations"
    )
