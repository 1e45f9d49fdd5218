"""The captures data set: labelled captures (e.g. HAART) normalised and cut at a stride."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from wovenskin.recording.files import read_captures
from wovenskin.training.capture_prep import capture_window_ends, capture_windows
from wovenskin.training.datasets.jobs import one_line
from wovenskin.training.datasets.normalisation import CaptureNormalisation
from wovenskin.training.datasets.store import DatasetError, WindowDataset
from wovenskin.training.datasets.writer import (
    DTYPE,
    DatasetWriter,
    base_meta,
    check_dtype,
    check_target,
)
from wovenskin.training.window_settings import SOURCE_CODES


def build_dataset_from_captures(
    out_dir: str | os.PathLike,
    path: str | os.PathLike,
    window_frames: int = 30,
    stride: int | None = None,
    normalisation: CaptureNormalisation | None = None,
    dtype: str = DTYPE,
    overwrite: bool = False,
) -> WindowDataset:
    """Window data set from a labelled-captures ``.npz`` (e.g. HAART).

    Each capture is normalised (:class:`CaptureNormalisation`) and cut into windows of
    ``window_frames`` ending every ``stride`` frames (default: half a window) and at its
    last frame (:func:`~.windows.capture_windows`).  Labels, class names and the sample
    rate come from the file; the person group is the file's ``groups`` (participant),
    each capture is its own recording (``capture-00012``: windows of one capture stay on
    one side of every split, and per-capture accuracy can be scored), and the skin is the
    file (one sensor).  Extra per-capture keys of the file (e.g. substrate, cover) go to
    ``recordings.json``.
    """
    out = Path(out_dir)
    check_target(out, overwrite)
    dtype = check_dtype(dtype)
    if not (isinstance(window_frames, int | np.integer) and window_frames >= 1):
        raise DatasetError(f"window_frames must be an integer >= 1, got {window_frames!r}")
    stride = int(stride) if stride is not None else max(1, int(window_frames) // 2)
    if stride < 1:
        raise DatasetError(f"stride must be >= 1, got {stride}")
    try:
        captures = read_captures(path, "a data set of captures")
    except ValueError as exc:
        raise DatasetError(one_line(exc)) from exc
    norm = (normalisation or CaptureNormalisation()).resolved(captures)
    group_spreads = norm.group_spreads(captures) if norm.per_group else {}
    n, _, rows, cols = captures.frames.shape
    counts = [capture_window_ends(int(length), window_frames, stride).size
              for length in captures.lengths]  # fmt: skip
    bounds = np.concatenate(([0], np.cumsum(counts)))
    skin = Path(path).stem
    people = list(dict.fromkeys(str(g) for g in captures.groups))
    person_id = {name: i for i, name in enumerate(people)}
    extra = {
        key: value
        for key, value in captures.metadata.items()
        if isinstance(value, np.ndarray) and value.shape == (n,)
    }
    writer = DatasetWriter(out, int(bounds[-1]), dtype)
    try:
        windows = writer.allocate((window_frames, rows, cols))
        infos = []
        for i in range(n):
            length = int(captures.lengths[i])
            normalised = norm.apply(
                captures.frames[i, :length], group_spreads.get(str(captures.groups[i]))
            )
            windows[bounds[i] : bounds[i + 1]] = capture_windows(
                normalised, length, window_frames, stride
            )
            infos.append(
                {
                    "recording": f"capture-{i:05d}",
                    "person": str(captures.groups[i]),
                    "skin": skin,
                    "label": captures.class_names[int(captures.labels[i])],
                    "frames": length,
                    "windows": int(counts[i]),
                    **{k: v[i].item() for k, v in extra.items()},
                }
            )
        per_capture = np.asarray(counts)
        ids = {
            "recording": np.repeat(np.arange(n, dtype=np.int32), per_capture),
            "person": np.repeat(
                np.array([person_id[str(g)] for g in captures.groups], np.int32), per_capture
            ),
            "skin": np.zeros(int(bounds[-1]), dtype=np.int32),
        }
        tables = {"recording": [info["recording"] for info in infos], "person": people,
                  "skin": [skin]}  # fmt: skip
        meta = base_meta(
            "captures", captures.class_names, rows, cols, captures.sample_rate_hz,
            {"window_frames": int(window_frames), "stride": stride}, None,
        )  # fmt: skip
        meta["conditioning"] = None
        meta["normalisation"] = norm.to_dict()
        meta["generation"] = {
            "builder": "build_dataset_from_captures",
            "path": str(path),
            "stride": stride,
            "n_captures": int(n),
        }
        labels = np.repeat(captures.labels.astype(np.int16), per_capture)
        sources = np.full(int(bounds[-1]), SOURCE_CODES["capture"], dtype=np.int8)
        return writer.finish(meta, overwrite, labels, sources, ids, tables, infos)
    except BaseException:
        writer.abort()
        raise
