"""The window data set on disk: its format, :class:`WindowDataset` and :func:`open_dataset`.

A :class:`WindowDataset` is a directory (format ``wovenskin.window-dataset`` version 1)::

    windows.npy     (N, W, R, C) float16 or float32  the windows, memory-mapped on reading
    labels.npy      (N,) int16   index into meta["class_names"]
    recording.npy   (N,) int32   index into groups.json["recording"]
    person.npy      (N,) int32   index into groups.json["person"]
    skin.npy        (N,) int32   index into groups.json["skin"]
    source.npy      (N,) int8    how the window was made, index into meta["source_names"]
    groups.json     {"recording": [names], "person": [names], "skin": [names]}
    recordings.json one object per recording: its groups, events used and dropped, and
                    (simulated) the person's traits and the skin's physics
    meta.json       class names, grid rows/cols, window length, sample rate, conditioning
                    settings (or the capture normalisation), window settings, generation
                    settings, seed, counts per class and per source, wovenskin version

Windows hold conditioned frames, ``(C - C0) / C0`` smoothed, exactly what the live
pipeline feeds the recogniser (labelled captures: see
:class:`~wovenskin.training.datasets.normalisation.CaptureNormalisation`).
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from wovenskin.errors import DataError
from wovenskin.signal.config import ConditioningConfig
from wovenskin.training.window_settings import SOURCE_NAMES

FORMAT = "wovenskin.window-dataset"
FORMAT_VERSION = 1
GROUP_KEYS: tuple[str, ...] = ("recording", "person", "skin")
WINDOW_DTYPES = ("float16", "float32")

ProgressCallback = Callable[[int, int], None]
"""Called as ``progress(recordings_done, recordings_total)``, first with ``done = 0``."""


class DatasetError(DataError):
    """A window data set cannot be built, read or split; the message says why."""


@dataclass
class WindowDataset:
    """A window data set; ``windows`` is memory-mapped when opened from disk."""

    windows: np.ndarray  # (N, W, R, C) float16 / float32
    labels: np.ndarray  # (N,) int16
    recording: np.ndarray  # (N,) int32
    person: np.ndarray  # (N,) int32
    skin: np.ndarray  # (N,) int32
    source: np.ndarray  # (N,) int8
    group_names: dict[str, list[str]]  # key -> names, indexed by the id arrays
    meta: dict
    recordings: list[dict] = field(default_factory=list)
    path: Path | None = None

    def __len__(self) -> int:
        return int(self.labels.size)

    @property
    def class_names(self) -> list[str]:
        return list(self.meta["class_names"])

    @property
    def rows(self) -> int:
        return int(self.meta["rows"])

    @property
    def cols(self) -> int:
        return int(self.meta["cols"])

    @property
    def window_frames(self) -> int:
        return int(self.meta["window_frames"])

    @property
    def sample_rate_hz(self) -> float:
        return float(self.meta["sample_rate_hz"])

    @property
    def conditioning(self) -> ConditioningConfig | None:
        """The conditioning the windows went through (``None`` for labelled captures)."""
        stored = self.meta.get("conditioning")
        return ConditioningConfig.from_dict(stored) if stored is not None else None

    def group_ids(self, key: str) -> np.ndarray:
        """Per-window group ids for ``key`` ("recording", "person" or "skin")."""
        check_group_key(key)
        return getattr(self, key)

    def class_counts(self) -> dict[str, int]:
        counts = np.bincount(self.labels, minlength=len(self.class_names))
        return {name: int(c) for name, c in zip(self.class_names, counts, strict=True)}

    def unique_per_recording(self, key: str) -> bool:
        """True when every recording has its own ``key`` group, seen in no other recording.

        Holds for "person" and "skin" in simulated sets (one new person on one new skin
        per recording), so there a split by recording is also a split by person and skin.
        """
        return one_to_one(self.recording, self.group_ids(key))


def open_dataset(path: str | os.PathLike, mmap: bool = True) -> WindowDataset:
    """Open a data set directory; ``windows`` is memory-mapped (read-only) unless ``mmap=False``.

    Raises :class:`DatasetError` naming the directory and the problem.
    """
    root = Path(path)
    where = str(root)
    if not root.is_dir():
        raise DatasetError(f"{where}: no such data set directory")
    meta = _read_json(root / "meta.json", where)
    if not isinstance(meta, dict) or meta.get("format") != FORMAT:
        raise DatasetError(f"{where}: meta.json does not describe a {FORMAT}")
    if meta.get("format_version") != FORMAT_VERSION:
        raise DatasetError(
            f"{where}: format version {meta.get('format_version')!r} is not supported "
            f"(this wovenskin reads version {FORMAT_VERSION})"
        )
    for key in ("class_names", "rows", "cols", "window_frames", "sample_rate_hz"):
        if key not in meta:
            raise DatasetError(f"{where}: meta.json lacks {key!r}")
    groups = _read_json(root / "groups.json", where)
    if not isinstance(groups, dict) or any(not isinstance(groups.get(k), list) for k in GROUP_KEYS):
        raise DatasetError(f"{where}: groups.json must map {', '.join(GROUP_KEYS)} to name lists")
    recordings_path = root / "recordings.json"
    recordings = _read_json(recordings_path, where) if recordings_path.exists() else []
    windows = _load_array(root, "windows", where, mmap)
    expected = (meta["window_frames"], meta["rows"], meta["cols"])
    if windows.ndim != 4 or tuple(windows.shape[1:]) != tuple(expected):
        raise DatasetError(
            f"{where}: windows.npy has shape {windows.shape}, meta.json says (N, "
            f"{expected[0]}, {expected[1]}, {expected[2]})"
        )
    if windows.dtype.name not in WINDOW_DTYPES:
        raise DatasetError(f"{where}: windows.npy has dtype {windows.dtype}, not float16/32")
    n = windows.shape[0]
    labels = _load_int_array(root, "labels", where, n, len(meta["class_names"]))
    ids = {k: _load_int_array(root, k, where, n, len(groups[k])) for k in GROUP_KEYS}
    source = _load_int_array(root, "source", where, n, len(SOURCE_NAMES))
    return WindowDataset(
        windows=windows,
        labels=labels,
        recording=ids["recording"],
        person=ids["person"],
        skin=ids["skin"],
        source=source,
        group_names={k: [str(name) for name in groups[k]] for k in GROUP_KEYS},
        meta=meta,
        recordings=recordings if isinstance(recordings, list) else [],
        path=root,
    )


def _read_json(path: Path, where: str):
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise DatasetError(f"{where}: missing {path.name}") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise DatasetError(f"{where}: cannot read {path.name} ({exc})") from None


def _load_array(root: Path, name: str, where: str, mmap: bool) -> np.ndarray:
    try:
        return np.load(root / f"{name}.npy", mmap_mode="r" if mmap else None, allow_pickle=False)
    except FileNotFoundError:
        raise DatasetError(f"{where}: missing {name}.npy") from None
    except (OSError, ValueError, EOFError) as exc:
        raise DatasetError(f"{where}: {name}.npy is corrupt ({exc})") from None


def _load_int_array(root: Path, name: str, where: str, n: int, n_values: int) -> np.ndarray:
    a = np.asarray(_load_array(root, name, where, mmap=False))
    if a.dtype.kind not in "iu" or a.shape != (n,):
        raise DatasetError(
            f"{where}: {name}.npy must be integers of shape ({n},), got {a.dtype} {a.shape}"
        )
    if n and (a.min() < 0 or a.max() >= n_values):
        raise DatasetError(
            f"{where}: {name}.npy holds ids outside [0, {n_values - 1}] ({a.min()}..{a.max()})"
        )
    return a


def one_to_one(recording: np.ndarray, group: np.ndarray) -> bool:
    """True when ``recording`` ids and ``group`` ids pair one-to-one."""
    if recording.size == 0:
        return True
    pairs = np.unique(np.stack([recording, group], axis=1), axis=0)
    return bool(
        np.unique(pairs[:, 0]).size == len(pairs) and np.unique(pairs[:, 1]).size == len(pairs)
    )


def check_group_key(key: str) -> None:
    """Refuse a group key other than "recording", "person" and "skin"."""
    if key not in GROUP_KEYS:
        raise DatasetError(f"unknown group key {key!r}; known: {', '.join(GROUP_KEYS)}")
