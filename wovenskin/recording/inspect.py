"""``wovenskin info`` and ``wovenskin convert``: describe and convert data files.

Knows the three kinds of file wovenskin reads: labelled streams and labelled captures
(``.npz``, FORMATS.md) and native recordings (``.wsrec``).  The kind is decided by content,
not only by suffix, so a mis-named file is still described correctly.
"""

from __future__ import annotations

import zipfile
from collections import Counter
from pathlib import Path

import numpy as np
from rich.table import Table

from wovenskin.recording.formats import (
    FormatError,
    read_labelled_captures,
    read_labelled_stream,
    write_labelled_stream,
)
from wovenskin.recording.native import (
    read_recording,
    recording_from_labelled_stream,
    write_recording,
)


def file_kind(path: Path) -> str:
    """``"stream"``, ``"captures"`` or ``"recording"``; FormatError for anything else."""
    path = Path(path)
    if not path.exists():
        raise FormatError(f"{path}: no such file")
    if zipfile.is_zipfile(path):
        try:
            with np.load(path, allow_pickle=False) as data:
                keys = set(data.files)
        except (OSError, ValueError, zipfile.BadZipFile) as exc:
            raise FormatError(f"{path}: not a readable .npz file ({exc})") from None
        return "captures" if "lengths" in keys else "stream"
    return "recording"


def describe_file(path: Path) -> Table:
    """A two-column table of what ``path`` holds (FormatError if it is not a data file)."""
    path = Path(path)
    kind = file_kind(path)
    table = Table(title=f"{path} ({kind})", show_header=False)
    table.add_column(style="dim", justify="right")
    table.add_column()
    if kind == "stream":
        s = read_labelled_stream(path)
        _rows(table, s.frames, s.sample_rate_hz, float(s.t[-1] - s.t[0]) if len(s.t) else 0.0)
        _label_rows(table, [str(x) for x in s.event_labels])
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
        rec = read_recording(path)
        duration = float(rec.t[-1] - rec.t[0]) if len(rec.t) else 0.0
        _rows(table, rec.frames, rec.info.sample_rate_hz, duration)
        table.add_row("device", f"{rec.info.source} {rec.info.device_id} {rec.info.firmware}")
        for key in ("participant", "operator", "skin_id", "started_utc", "host"):
            if rec.provenance.get(key):
                table.add_row(key, str(rec.provenance[key]))
        table.add_row("calibrations", str(len(rec.calibrations)))
        _label_rows(table, [lab.label for lab in rec.labels])
        table.add_row("annotations", str(len(rec.annotations)))
        table.add_row("closed cleanly", "yes" if rec.clean_close else "[yellow]no[/]")
        for warning in rec.warnings:
            table.add_row("warning", f"[yellow]{warning}[/]")
    return table


def _rows(table: Table, frames: np.ndarray, rate: float, duration: float) -> None:
    n, rows, cols = frames.shape
    table.add_row("frames", f"{n} ({duration:.2f} s)")
    table.add_row("grid", f"{rows} x {cols}, {frames.dtype}")
    table.add_row("rate", f"{rate:g} Hz")
    if n:
        table.add_row("values", f"min {np.nanmin(frames):.4g}, max {np.nanmax(frames):.4g}")


def _label_rows(table: Table, labels: list[str]) -> None:
    counts = Counter(labels)
    table.add_row("events", str(len(labels)))
    if counts:
        table.add_row("labels", ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))


def convert_file(src: Path, dst: Path, overwrite: bool = False) -> str:
    """Convert a recording to a labelled stream or back; returns a one-line summary."""
    src, dst = Path(src), Path(dst)
    if dst.exists() and not overwrite:
        raise FileExistsError(f"{dst} exists (use --overwrite to replace it)")
    kind = file_kind(src)
    if dst.suffix == ".npz":
        if kind == "recording":
            stream = read_recording(src).to_labelled_stream()
        elif kind == "stream":
            stream = read_labelled_stream(src)
        else:
            raise FormatError(f"{src}: labelled captures cannot become a stream")
        write_labelled_stream(dst, stream)
        return f"wrote {dst}: {len(stream.t)} frames, {len(stream.event_labels)} events"
    if dst.suffix == ".wsrec":
        if kind != "stream":
            raise FormatError(f"{src}: only a labelled stream converts to .wsrec")
        stream = read_labelled_stream(src)
        write_recording(dst, recording_from_labelled_stream(stream), overwrite=overwrite)
        return f"wrote {dst}: {len(stream.t)} frames, {len(stream.event_labels)} labels"
    raise FormatError(f"{dst}: output must end in .npz or .wsrec")
