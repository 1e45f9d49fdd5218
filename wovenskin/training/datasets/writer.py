"""Writing a data set: a hidden partial directory filled recording by recording, then renamed.

Builders write into ``.NAME.partial-PID`` beside the target and rename it when complete,
so a crash never leaves a half-written data set under the real name.  Each recording's
windows land at a fixed offset whatever order the workers finish in.
"""

from __future__ import annotations

import os
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from wovenskin import __version__
from wovenskin.io import dumps
from wovenskin.outputs import OutputExistsError, check_writable
from wovenskin.training.datasets.store import (
    FORMAT,
    FORMAT_VERSION,
    GROUP_KEYS,
    WINDOW_DTYPES,
    DatasetError,
    WindowDataset,
    one_to_one,
    open_dataset,
)
from wovenskin.training.window_settings import SOURCE_NAMES

# The builders' defaults, each written once: generate_sim_dataset and
# build_dataset_from_streams (counts, workers, dtype), build_dataset_from_captures (dtype),
# runs.ensure_dataset (workers) and `wovenskin dataset` (its options fall through to them).
WINDOWS_PER_RECORDING = 1000
"""Gesture windows per recording, balanced over the gestures (the paper's 1,000)."""
INVALID_WINDOWS_PER_RECORDING = 400
"""Windows of the invalid class per recording."""
WORKERS = 2
"""Worker processes, one recording each at a time."""
DTYPE = "float16"
"""How the windows are stored (float16 or float32)."""


@dataclass
class RecordingWindows:
    """The windows of one recording, as a worker returns them."""

    windows: np.ndarray  # (n, W, R, C) in the data set's dtype
    labels: np.ndarray  # (n,) int16
    sources: np.ndarray  # (n,) int8
    recording: str
    person: str
    skin: str
    info: dict


class DatasetWriter:
    """Writes a data set into a hidden partial directory, then renames it into place."""

    def __init__(self, out_dir: Path, total: int, dtype: str):
        self.out_dir = out_dir
        self.partial = out_dir.with_name(f".{out_dir.name}.partial-{os.getpid()}")
        if self.partial.exists():
            shutil.rmtree(self.partial)
        self.partial.mkdir(parents=True)
        self.total = int(total)
        self.dtype = np.dtype(dtype)
        self.windows: np.ndarray | None = None

    def allocate(self, window_shape: tuple[int, ...]) -> np.ndarray:
        """The ``(total, W, R, C)`` windows memmap (created on first call)."""
        window_shape = tuple(int(v) for v in window_shape)
        if self.windows is None:
            self.windows = np.lib.format.open_memmap(
                self.partial / "windows.npy", mode="w+", dtype=self.dtype,
                shape=(self.total, *window_shape),
            )  # fmt: skip
        elif tuple(self.windows.shape[1:]) != window_shape:
            raise DatasetError(
                f"windows of shape {window_shape} do not match the data set's "
                f"{tuple(self.windows.shape[1:])} (recordings of different grid sizes?)"
            )
        return self.windows

    def finish(
        self,
        meta: dict,
        overwrite: bool,
        labels: np.ndarray,
        sources: np.ndarray,
        ids: dict[str, np.ndarray],
        tables: dict[str, list[str]],
        recordings: list[dict],
    ) -> WindowDataset:
        if self.windows is None:
            raise DatasetError("internal error: no windows were written")
        self.windows.flush()
        self.windows = None
        counts = np.bincount(labels, minlength=len(meta["class_names"]))
        source_counts = np.bincount(sources, minlength=len(SOURCE_NAMES))
        meta = {
            **meta,
            "n_windows": self.total,
            "n_recordings": len(tables["recording"]),
            "dtype": self.dtype.name,
            "class_counts": dict(zip(meta["class_names"], counts.tolist(), strict=True)),
            "source_names": list(SOURCE_NAMES),
            "source_counts": dict(zip(SOURCE_NAMES, source_counts.tolist(), strict=True)),
            "unique_per_recording": {
                key: one_to_one(ids["recording"], ids[key]) for key in ("person", "skin")
            },
        }
        np.save(self.partial / "labels.npy", labels.astype(np.int16))
        np.save(self.partial / "source.npy", sources.astype(np.int8))
        for key in GROUP_KEYS:
            np.save(self.partial / f"{key}.npy", ids[key].astype(np.int32))
        write_json(self.partial / "groups.json", tables)
        write_json(self.partial / "recordings.json", recordings)
        write_json(self.partial / "meta.json", meta)
        replace_dir(self.partial, self.out_dir, overwrite)
        return open_dataset(self.out_dir)

    def abort(self) -> None:
        self.windows = None
        shutil.rmtree(self.partial, ignore_errors=True)


class RecordingCollector:
    """Puts each recording's windows at its fixed offset, whatever order they arrive in."""

    def __init__(self, writer: DatasetWriter, n_recordings: int, per_recording: int):
        self.writer = writer
        self.per_recording = per_recording
        self.labels = np.zeros(writer.total, dtype=np.int16)
        self.sources = np.zeros(writer.total, dtype=np.int8)
        self.results: list[RecordingWindows | None] = [None] * n_recordings

    def put(self, index: int, result: RecordingWindows) -> None:
        if len(result.labels) != self.per_recording:
            raise DatasetError(
                f"recording {result.recording} gave {len(result.labels)} windows, "
                f"expected {self.per_recording}"
            )
        lo, hi = index * self.per_recording, (index + 1) * self.per_recording
        self.writer.allocate(result.windows.shape[1:])[lo:hi] = result.windows
        self.labels[lo:hi] = result.labels
        self.sources[lo:hi] = result.sources
        result.windows = np.zeros(0)  # the memmap holds them now
        self.results[index] = result

    def finish(self, meta: dict, overwrite: bool) -> WindowDataset:
        if any(r is None for r in self.results):
            raise DatasetError("internal error: data set finished before all recordings")
        results: list[RecordingWindows] = self.results  # type: ignore[assignment]
        tables: dict[str, list[str]] = {}
        ids: dict[str, np.ndarray] = {}
        for key in GROUP_KEYS:
            names = [getattr(r, key) for r in results]
            table = list(dict.fromkeys(names))  # in order of first appearance
            position = {name: i for i, name in enumerate(table)}
            per_recording = np.array([position[n] for n in names], dtype=np.int32)
            tables[key] = table
            ids[key] = np.repeat(per_recording, self.per_recording)
        if len(tables["recording"]) != len(results):
            raise DatasetError("two recordings have the same name; recording names must differ")
        return self.writer.finish(
            meta, overwrite, self.labels, self.sources, ids, tables, [r.info for r in results]
        )


def write_json(path: Path, document) -> None:
    """``document`` as indented JSON (numpy values made plain; NaN allowed as before)."""
    path.write_text(dumps(document, indent=1, allow_nan=True) + "\n", "utf-8")


def check_target(out_dir: Path, overwrite: bool) -> None:
    """Refuse to build over something that is not an empty directory or a data set, and
    over a data set unless ``overwrite`` (:class:`~wovenskin.outputs.OutputExistsError`),
    and where it could not be written (:func:`~wovenskin.outputs.check_writable`)."""
    check_writable(out_dir, folder=True)
    if not out_dir.exists():
        return
    if not out_dir.is_dir():
        raise DatasetError(f"{out_dir} exists and is not a directory")
    if not any(out_dir.iterdir()):
        return
    if not (out_dir / "meta.json").exists():
        raise DatasetError(f"{out_dir} is a non-empty directory that is not a window data set")
    if not overwrite:
        raise OutputExistsError(out_dir, "a data set")


def replace_dir(partial: Path, out_dir: Path, overwrite: bool) -> None:
    check_target(out_dir, overwrite)
    if out_dir.exists():
        shutil.rmtree(out_dir)
    os.replace(partial, out_dir)


def check_counts(windows_per_recording: int, invalid_windows_per_recording: int) -> None:
    for name, value in (
        ("windows_per_recording", windows_per_recording),
        ("invalid_windows_per_recording", invalid_windows_per_recording),
    ):
        if not (isinstance(value, int | np.integer) and value >= 0):
            raise DatasetError(f"{name} must be an integer >= 0, got {value!r}")
    if windows_per_recording + invalid_windows_per_recording == 0:
        raise DatasetError("a data set needs at least one window per recording")


def check_dtype(dtype: str) -> str:
    name = np.dtype(dtype).name
    if name not in WINDOW_DTYPES:
        raise DatasetError(f"windows are stored as float16 or float32, not {dtype}")
    return name


def base_meta(kind: str, class_names, rows, cols, rate, settings: dict, seed) -> dict:
    return {
        "format": FORMAT,
        "format_version": FORMAT_VERSION,
        "wovenskin_version": __version__,
        "kind": kind,
        "class_names": list(class_names),
        "rows": int(rows),
        "cols": int(cols),
        "window_frames": int(settings["window_frames"]),
        "sample_rate_hz": float(rate),
        "window_settings": settings,
        "seed": seed,
    }
