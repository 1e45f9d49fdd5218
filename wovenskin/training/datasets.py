"""Window data sets: generation, storage on disk, and train/validation splits.

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
pipeline feeds the recogniser (labelled captures: see :class:`CaptureNormalisation`).
Builders write into a hidden ``.NAME.partial-PID`` directory beside the target and rename
it when complete, so a crash never leaves a half-written data set under the real name.

Builders:

- :func:`generate_sim_dataset`: simulated recordings, each ONE randomly drawn person
  (:meth:`Person.sample`) on ONE randomly drawn skin (:meth:`SkinPhysics.sample`)
  performing the 14 gestures in shuffled rounds with invalid touches between them; each
  recording is conditioned and cut into windows (:mod:`~.windows`).  Recording ``i``
  draws everything from ``SeedSequence(seed, spawn_key=(i,))``, so it does not depend on
  the worker that made it or on ``n_recordings`` (a small set is a prefix of a larger one
  with the same seed), and results land at fixed offsets: the files are byte-identical
  for a seed whatever ``workers`` is.
- :func:`build_dataset_from_streams`: labelled-stream ``.npz`` files or native ``.wsrec``
  recordings, the same windowing.
- :func:`build_dataset_from_captures`: labelled captures (e.g. HAART), windows cut at a
  stride from each normalised capture; class names and rate come from the file, the person
  group is the file's ``groups``, each capture is its own recording.

Splits return index arrays (:class:`Split`): :func:`random_split` (the paper's 85/15),
:func:`grouped_split` (validation recordings, people and skins never appear in training)
and :func:`leave_one_group_out`.
"""

from __future__ import annotations

import hashlib
import json
import multiprocessing
import os
import shutil
import sys
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from wovenskin import __version__
from wovenskin.gestures import CLASS_NAMES, INVALID
from wovenskin.outputs import OutputExistsError
from wovenskin.recording.files import read_captures, read_stream
from wovenskin.recording.formats import (
    LabelledCaptures,
    LabelledStream,
)
from wovenskin.signal.conditioner import condition_recording
from wovenskin.signal.config import ConditioningConfig
from wovenskin.sim.person import Person
from wovenskin.sim.physics import SkinPhysics
from wovenskin.sim.stream import simulate_stream
from wovenskin.skin.layout import SkinLayout
from wovenskin.training.stream_windows import characteristic_spans, sample_stream_windows
from wovenskin.training.windows import (
    SOURCE_CODES,
    SOURCE_NAMES,
    FrameEvents,
    WindowSettings,
    align_to_contact,
    capture_window_ends,
    capture_windows,
    events_to_frames,
    sample_windows,
)

FORMAT = "wovenskin.window-dataset"
FORMAT_VERSION = 1
GROUP_KEYS: tuple[str, ...] = ("recording", "person", "skin")
WINDOW_DTYPES = ("float16", "float32")

ProgressCallback = Callable[[int, int], None]
"""Called as ``progress(recordings_done, recordings_total)``, first with ``done = 0``."""


class DatasetError(ValueError):
    """A window data set cannot be built, read or split; the message says why."""


# ================================================================================ storage


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
        _check_group_key(key)
        return getattr(self, key)

    def class_counts(self) -> dict[str, int]:
        counts = np.bincount(self.labels, minlength=len(self.class_names))
        return {name: int(c) for name, c in zip(self.class_names, counts, strict=True)}

    def unique_per_recording(self, key: str) -> bool:
        """True when every recording has its own ``key`` group, seen in no other recording.

        Holds for "person" and "skin" in simulated sets (one new person on one new skin
        per recording), so there a split by recording is also a split by person and skin.
        """
        pairs = np.unique(np.stack([self.recording, self.group_ids(key)], axis=1), axis=0)
        return bool(
            np.unique(pairs[:, 0]).size == len(pairs) and np.unique(pairs[:, 1]).size == len(pairs)
        )


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


# ================================================================================ building


@dataclass
class _RecordingWindows:
    """The windows of one recording, as a worker returns them."""

    windows: np.ndarray  # (n, W, R, C) in the data set's dtype
    labels: np.ndarray  # (n,) int16
    sources: np.ndarray  # (n,) int8
    recording: str
    person: str
    skin: str
    info: dict


class _DatasetWriter:
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
                key: _unique_per_recording(ids["recording"], ids[key]) for key in ("person", "skin")
            },
        }
        np.save(self.partial / "labels.npy", labels.astype(np.int16))
        np.save(self.partial / "source.npy", sources.astype(np.int8))
        for key in GROUP_KEYS:
            np.save(self.partial / f"{key}.npy", ids[key].astype(np.int32))
        _write_json(self.partial / "groups.json", tables)
        _write_json(self.partial / "recordings.json", recordings)
        _write_json(self.partial / "meta.json", meta)
        _replace_dir(self.partial, self.out_dir, overwrite)
        return open_dataset(self.out_dir)

    def abort(self) -> None:
        self.windows = None
        shutil.rmtree(self.partial, ignore_errors=True)


class _RecordingCollector:
    """Puts each recording's windows at its fixed offset, whatever order they arrive in."""

    def __init__(self, writer: _DatasetWriter, n_recordings: int, per_recording: int):
        self.writer = writer
        self.per_recording = per_recording
        self.labels = np.zeros(writer.total, dtype=np.int16)
        self.sources = np.zeros(writer.total, dtype=np.int8)
        self.results: list[_RecordingWindows | None] = [None] * n_recordings

    def put(self, index: int, result: _RecordingWindows) -> None:
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
        results: list[_RecordingWindows] = self.results  # type: ignore[assignment]
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


def _unique_per_recording(recording: np.ndarray, group: np.ndarray) -> bool:
    """True when recordings and ``group`` ids pair one-to-one."""
    if recording.size == 0:
        return True
    pairs = np.unique(np.stack([recording, group], axis=1), axis=0)
    return bool(
        np.unique(pairs[:, 0]).size == len(pairs) and np.unique(pairs[:, 1]).size == len(pairs)
    )


def _write_json(path: Path, document) -> None:
    path.write_text(json.dumps(document, indent=1, default=_json_default) + "\n", "utf-8")


def _json_default(value):
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"{type(value).__name__} is not JSON-serialisable")


def _check_target(out_dir: Path, overwrite: bool) -> None:
    """Refuse to build over something that is not an empty directory or a data set, and
    over a data set unless ``overwrite`` (:class:`~wovenskin.outputs.OutputExistsError`)."""
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


def _replace_dir(partial: Path, out_dir: Path, overwrite: bool) -> None:
    _check_target(out_dir, overwrite)
    if out_dir.exists():
        shutil.rmtree(out_dir)
    os.replace(partial, out_dir)


def _run_jobs(
    jobs: Sequence,
    worker: Callable,
    workers: int,
    collector: _RecordingCollector,
    progress: ProgressCallback | None,
    describe: Callable[[object], str],
) -> None:
    """Run ``worker(job)`` for every job on ``workers`` processes into ``collector``."""
    total = len(jobs)
    if progress is not None:
        progress(0, total)
    done = 0

    def accept(index: int, result: _RecordingWindows) -> None:
        nonlocal done
        collector.put(index, result)
        done += 1
        if progress is not None:
            progress(done, total)

    if workers <= 1 or total <= 1:
        for index, job in enumerate(jobs):
            accept(index, _call(worker, job, describe))
        return
    pool = ProcessPoolExecutor(max_workers=min(workers, total), mp_context=_pool_context())
    try:
        pending: dict[Future, int] = {
            pool.submit(worker, job): index for index, job in enumerate(jobs)
        }
        while pending:
            finished, _ = wait(pending, return_when=FIRST_COMPLETED)
            for future in sorted(finished, key=pending.__getitem__):
                index = pending.pop(future)
                try:
                    result = future.result()
                except Exception as exc:
                    raise DatasetError(f"{describe(jobs[index])}: {_one_line(exc)}") from exc
                accept(index, result)
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def _pool_context() -> multiprocessing.context.BaseContext:
    """``fork`` on Linux, ``spawn`` elsewhere.

    Forked workers start at once and work from any caller, including a script without an
    ``if __name__ == "__main__"`` guard, which spawned (and forkserver) workers re-run
    and fail on.  The workers use numpy and scipy only and never touch the parent's
    threads (a progress display) or locks.  macOS and Windows cannot fork safely.
    """
    method = "fork" if sys.platform.startswith("linux") else "spawn"
    return multiprocessing.get_context(method)


def _call(worker: Callable, job, describe: Callable[[object], str]) -> _RecordingWindows:
    try:
        return worker(job)
    except Exception as exc:
        raise DatasetError(f"{describe(job)}: {_one_line(exc)}") from exc


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split()) or type(exc).__name__


def _check_counts(windows_per_recording: int, invalid_windows_per_recording: int) -> None:
    for name, value in (
        ("windows_per_recording", windows_per_recording),
        ("invalid_windows_per_recording", invalid_windows_per_recording),
    ):
        if not (isinstance(value, int | np.integer) and value >= 0):
            raise DatasetError(f"{name} must be an integer >= 0, got {value!r}")
    if windows_per_recording + invalid_windows_per_recording == 0:
        raise DatasetError("a data set needs at least one window per recording")


def _check_dtype(dtype: str) -> str:
    name = np.dtype(dtype).name
    if name not in WINDOW_DTYPES:
        raise DatasetError(f"windows are stored as float16 or float32, not {dtype}")
    return name


def _base_meta(kind: str, class_names, rows, cols, rate, settings: dict, seed) -> dict:
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


# -------------------------------------------------------------------- streams -> windows


@dataclass(frozen=True)
class _WindowingJob:
    """What every worker needs to window a recording (plain data, cheap to send)."""

    conditioning: dict
    settings: dict
    class_names: tuple[str, ...]
    n_gesture: int
    n_invalid: int
    dtype: str


def _window_stream(
    stream: LabelledStream,
    job: _WindowingJob,
    rng: np.random.Generator,
    names: tuple[str, str, str],
    info: dict,
) -> _RecordingWindows:
    """Condition one labelled stream and cut its windows."""
    config = ConditioningConfig.from_dict(job.conditioning)
    settings = WindowSettings.from_dict(job.settings)
    if not np.isclose(stream.sample_rate_hz, config.sample_rate_hz, rtol=1e-6):
        raise ValueError(
            f"the stream runs at {stream.sample_rate_hz:g} Hz but the data set's conditioning "
            f"is set for {config.sample_rate_hz:g} Hz"
        )
    index = {name: i for i, name in enumerate(job.class_names)}
    unknown = sorted({str(label) for label in stream.event_labels} - index.keys())
    if unknown:
        raise ValueError(f"event label(s) {', '.join(map(repr, unknown))} are not known classes")
    if INVALID not in index:
        raise ValueError(f"the class list has no {INVALID!r} class")
    _, conditioned = condition_recording(stream.frames, config)
    events = events_to_frames(
        stream.t,
        stream.event_start_s,
        stream.event_end_s,
        [index[str(label)] for label in stream.event_labels],
        _motion_end_s(stream),
        settings.rest_context_frames,
    )
    # A gesture the conditioning never saw touch the skin (a missed trial) teaches nothing.
    events, keep = align_to_contact(events, conditioned.touched, index[INVALID])
    dropped = [str(stream.event_labels[i]) for i in np.flatnonzero(~keep)]
    kept = FrameEvents(
        events.labels[keep], events.start[keep], events.stop[keep], events.informative_stop[keep]
    )
    if settings.recipe == "stream":
        motion_start, motion_stop = _motion_frames(stream)
        if motion_start is not None and motion_stop is not None:
            motion_start, motion_stop = motion_start[keep], motion_stop[keep]
        span_start, span_stop = characteristic_spans(kept, motion_start, motion_stop, settings)
        batch = sample_stream_windows(
            conditioned.signal,
            conditioned.touched,
            kept,
            span_start,
            span_stop,
            job.n_gesture,
            job.n_invalid,
            index[INVALID],
            settings,
            rng,
        )
    else:
        batch = sample_windows(
            conditioned.signal,
            conditioned.touched,
            kept,
            job.n_gesture,
            job.n_invalid,
            index[INVALID],
            settings,
            rng,
        )
    labels, counts = np.unique(np.asarray(stream.event_labels, dtype=str)[keep], return_counts=True)
    info = {
        "recording": names[0],
        "person": names[1],
        "skin": names[2],
        "frames": int(len(stream.frames)),
        "seconds": round(len(stream.frames) / stream.sample_rate_hz, 6),
        "events": dict(zip(labels.tolist(), counts.tolist(), strict=True)),
        "dropped_events": dropped,
        **info,
    }
    return _RecordingWindows(
        windows=batch.windows.astype(job.dtype, copy=False),
        labels=batch.labels,
        sources=batch.sources,
        recording=names[0],
        person=names[1],
        skin=names[2],
        info=info,
    )


def _motion_end_s(stream: LabelledStream) -> np.ndarray | None:
    """Per-event motion end from simulator metadata (NaN where unknown), or ``None``."""
    details = stream.metadata.get("events")
    if not isinstance(details, list) or len(details) != len(stream.event_labels):
        return None
    out = np.full(len(details), np.nan)
    for i, (detail, label) in enumerate(zip(details, stream.event_labels, strict=True)):
        try:
            if detail["label"] == str(label) and detail["label"] != INVALID:
                out[i] = float(detail["phases"]["motion_end_s"])
        except (KeyError, TypeError, ValueError):
            continue
    return out


def _motion_frames(stream: LabelledStream) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Per-event first and one-past-last frame of the characteristic motion (simulator
    metadata; -1 where unknown), or ``(None, None)`` for a stream without it."""
    details = stream.metadata.get("events")
    if not isinstance(details, list) or len(details) != len(stream.event_labels):
        return None, None
    start = np.full(len(details), -1, dtype=np.int64)
    stop = np.full(len(details), -1, dtype=np.int64)
    t = np.asarray(stream.t, dtype=np.float64)
    for i, (detail, label) in enumerate(zip(details, stream.event_labels, strict=True)):
        try:
            if detail["label"] != str(label) or detail["label"] == INVALID:
                continue
            begin = float(detail["phases"]["motion_start_s"])
            end = float(detail["phases"]["motion_end_s"])
        except (KeyError, TypeError, ValueError):
            continue
        if np.isfinite(begin) and np.isfinite(end) and end > begin:
            start[i] = int(np.searchsorted(t, begin, side="left"))
            stop[i] = int(np.searchsorted(t, end, side="left"))
    return start, stop


def _digest(document) -> str:
    text = json.dumps(document, sort_keys=True, default=_json_default)
    return hashlib.sha1(text.encode()).hexdigest()[:10]


def sim_person_name(person: Person) -> str:
    """Group name of a simulated person: a digest of all its traits."""
    return f"sim-person-{_digest(person.to_dict())}"


def sim_skin_name(physics: SkinPhysics) -> str:
    """Group name of a simulated skin: a digest of all its physics parameters."""
    return f"sim-skin-{_digest(physics.to_dict())}"


# ------------------------------------------------------------------------ simulated set


@dataclass(frozen=True)
class _SimJob:
    index: int
    seed: int
    seconds: float
    layout: dict
    invalid_fraction: float
    windowing: _WindowingJob


def _simulate_recording(job: _SimJob) -> _RecordingWindows:
    """Worker: one simulated person on one simulated skin, conditioned and windowed."""
    rng = np.random.default_rng(np.random.SeedSequence(job.seed, spawn_key=(job.index,)))
    physics = SkinPhysics.sample(rng)
    person = Person.sample(rng)
    stream_seed = int(rng.integers(2**31))
    stream = simulate_stream(
        job.seconds,
        stream_seed,
        layout=SkinLayout.from_dict(job.layout),
        physics=physics,
        person=person,
        invalid_fraction=job.invalid_fraction,
        sample_rate_hz=job.windowing.conditioning["sample_rate_hz"],
    )
    names = (f"sim-{job.seed}-{job.index:05d}", sim_person_name(person), sim_skin_name(physics))
    info = {
        "stream_seed": stream_seed,
        "invalid_kinds": sorted({k for k in stream.metadata["invalid_kinds"] if k}),
        "person_traits": person.to_dict(),
        "skin_physics": physics.to_dict(),
    }
    return _window_stream(stream, job.windowing, rng, names, info)


def generate_sim_dataset(
    out_dir: str | os.PathLike,
    n_recordings: int = 140,
    windows_per_recording: int = 1000,
    invalid_windows_per_recording: int = 400,
    seconds_per_recording: float = 120.0,
    seed: int = 0,
    workers: int = 2,
    progress: ProgressCallback | None = None,
    settings: WindowSettings | None = None,
    conditioning: ConditioningConfig | None = None,
    layout: SkinLayout | None = None,
    invalid_fraction: float = 0.25,
    dtype: str = "float16",
    overwrite: bool = False,
) -> WindowDataset:
    """Generate a simulated window data set in ``out_dir`` (see the module doc).

    Each recording is ``seconds_per_recording`` of one new person on one new skin doing
    the 14 gestures (about 3 rounds in 120 s) with invalid touches (``invalid_fraction``
    of the events); it yields ``windows_per_recording`` gesture windows, balanced over the
    gestures, and ``invalid_windows_per_recording`` invalid ones.  The default is the
    paper's 140 x 1,000 = 140,000 gesture windows plus 28,000 invalid ones (about 1 GB
    as float16).  ``progress(done, total)`` reports finished recordings.
    """
    out = Path(out_dir)
    _check_target(out, overwrite)
    _check_counts(windows_per_recording, invalid_windows_per_recording)
    if not (isinstance(n_recordings, int | np.integer) and n_recordings >= 1):
        raise DatasetError(f"n_recordings must be an integer >= 1, got {n_recordings!r}")
    if not (np.isfinite(seconds_per_recording) and seconds_per_recording > 0):
        raise DatasetError(f"seconds_per_recording must be positive, got {seconds_per_recording}")
    settings = settings or WindowSettings()
    conditioning = conditioning or ConditioningConfig()
    layout = layout or SkinLayout()
    dtype = _check_dtype(dtype)
    windowing = _WindowingJob(
        conditioning.to_dict(),
        settings.to_dict(),
        CLASS_NAMES,
        int(windows_per_recording),
        int(invalid_windows_per_recording),
        dtype,
    )
    jobs = [
        _SimJob(i, int(seed), float(seconds_per_recording), layout.to_dict(),
                float(invalid_fraction), windowing)
        for i in range(n_recordings)
    ]  # fmt: skip
    meta = _base_meta(
        "sim",
        CLASS_NAMES,
        layout.rows,
        layout.cols,
        conditioning.sample_rate_hz,
        settings.to_dict(),
        seed,
    )
    meta["conditioning"] = conditioning.to_dict()
    meta["generation"] = {
        "builder": "generate_sim_dataset",
        "n_recordings": int(n_recordings),
        "windows_per_recording": int(windows_per_recording),
        "invalid_windows_per_recording": int(invalid_windows_per_recording),
        "seconds_per_recording": float(seconds_per_recording),
        "invalid_fraction": float(invalid_fraction),
        "layout": layout.to_dict(),
        "recording_seed": "numpy SeedSequence(seed, spawn_key=(recording index,))",
    }
    per_recording = int(windows_per_recording + invalid_windows_per_recording)
    writer = _DatasetWriter(out, n_recordings * per_recording, dtype)
    try:
        writer.allocate((settings.window_frames, layout.rows, layout.cols))
        collector = _RecordingCollector(writer, n_recordings, per_recording)
        _run_jobs(
            jobs, _simulate_recording, workers, collector, progress,
            lambda job: f"simulated recording {job.index}",
        )  # fmt: skip
        return collector.finish(meta, overwrite)
    except BaseException:
        writer.abort()
        raise


# ------------------------------------------------------------------ recorded streams set


@dataclass(frozen=True)
class _StreamJob:
    index: int
    path: str
    seed: int
    person: str | None
    skin: str | None
    windowing: _WindowingJob


def load_stream(path: str | os.PathLike) -> LabelledStream:
    """A labelled stream from a labelled-stream ``.npz`` or a native ``.wsrec`` recording
    (the kind decided by content: :func:`wovenskin.recording.files.read_stream`)."""
    return read_stream(path, "a data set")


def stream_identity(stream: LabelledStream) -> tuple[str, str]:
    """(person, skin) group names from a stream's metadata; "unknown" where absent.

    Simulated streams name the person and skin by a digest of their parameters, as
    :func:`generate_sim_dataset` does; native recordings use the provenance's
    ``participant`` and ``skin_id`` (or the device id).  Every stream without a name
    shares "unknown", so a grouped split never mistakes them for different people.
    """
    md = stream.metadata
    person, skin = "unknown", "unknown"
    provenance = md.get("provenance") if isinstance(md.get("provenance"), dict) else {}
    info = md.get("info") if isinstance(md.get("info"), dict) else {}
    if isinstance(md.get("person"), dict):
        try:
            person = sim_person_name(Person.from_dict(md["person"]))
        except (TypeError, ValueError):
            person = str(md["person"].get("person_id", "unknown"))
    elif provenance.get("participant"):
        person = str(provenance["participant"])
    if isinstance(md.get("physics"), dict):
        try:
            skin = sim_skin_name(SkinPhysics.from_dict(md["physics"]))
        except (TypeError, ValueError):
            skin = f"sim-skin-{_digest(md['physics'])}"
    elif provenance.get("skin_id"):
        skin = str(provenance["skin_id"])
    elif info.get("device_id"):
        skin = str(info["device_id"])
    return person, skin


def _window_stream_file(job: _StreamJob) -> _RecordingWindows:
    """Worker: read one recording, condition it and cut its windows."""
    stream = load_stream(job.path)
    person, skin = stream_identity(stream)
    rng = np.random.default_rng(np.random.SeedSequence(job.seed, spawn_key=(job.index,)))
    names = (_recording_name(job.index, job.path), job.person or person, job.skin or skin)
    return _window_stream(stream, job.windowing, rng, names, {"path": job.path})


def _recording_name(index: int, path: str) -> str:
    return f"{index:05d}-{Path(path).name}"


def build_dataset_from_streams(
    out_dir: str | os.PathLike,
    paths: Sequence[str | os.PathLike],
    windows_per_recording: int = 1000,
    invalid_windows_per_recording: int = 400,
    seed: int = 0,
    workers: int = 2,
    progress: ProgressCallback | None = None,
    settings: WindowSettings | None = None,
    conditioning: ConditioningConfig | None = None,
    persons: Sequence[str] | None = None,
    skins: Sequence[str] | None = None,
    dtype: str = "float16",
    overwrite: bool = False,
) -> WindowDataset:
    """Window data set from labelled streams (``.npz``) or native recordings (``.wsrec``).

    Every file is one recording, conditioned with ``conditioning`` (default: the default
    settings at the first file's rate; every file must run at that rate) and windowed
    like a simulated one.  People and skins come from each file's metadata
    (:func:`stream_identity`) unless ``persons`` / ``skins`` give one name per file.  A
    gesture event during which the conditioning never saw a touch (a missed trial) is
    dropped and listed in ``recordings.json``.
    """
    out = Path(out_dir)
    _check_target(out, overwrite)
    _check_counts(windows_per_recording, invalid_windows_per_recording)
    paths = [str(p) for p in paths]
    if not paths:
        raise DatasetError("no recordings given")
    for name, values in (("persons", persons), ("skins", skins)):
        if values is not None and len(values) != len(paths):
            raise DatasetError(f"{name} must give one name per recording ({len(paths)})")
    missing = [p for p in paths if not Path(p).is_file()]
    if missing:
        raise DatasetError(f"{missing[0]}: no such file")
    if conditioning is None:
        try:
            rate = load_stream(paths[0]).sample_rate_hz
        except ValueError as exc:
            raise DatasetError(_one_line(exc)) from exc
        conditioning = ConditioningConfig(sample_rate_hz=rate)
    settings = settings or WindowSettings()
    dtype = _check_dtype(dtype)
    windowing = _WindowingJob(
        conditioning.to_dict(),
        settings.to_dict(),
        CLASS_NAMES,
        int(windows_per_recording),
        int(invalid_windows_per_recording),
        dtype,
    )
    jobs = [
        _StreamJob(i, p, int(seed), persons[i] if persons else None,
                   skins[i] if skins else None, windowing)
        for i, p in enumerate(paths)
    ]  # fmt: skip
    per_recording = int(windows_per_recording + invalid_windows_per_recording)
    writer = _DatasetWriter(out, len(jobs) * per_recording, dtype)
    try:
        collector = _RecordingCollector(writer, len(jobs), per_recording)
        _run_jobs(jobs, _window_stream_file, workers, collector, progress, lambda job: job.path)
        assert writer.windows is not None
        _, rows, cols = writer.windows.shape[1:]
        meta = _base_meta(
            "streams",
            CLASS_NAMES,
            rows,
            cols,
            conditioning.sample_rate_hz,
            settings.to_dict(),
            seed,
        )
        meta["conditioning"] = conditioning.to_dict()
        meta["generation"] = {
            "builder": "build_dataset_from_streams",
            "paths": paths,
            "windows_per_recording": int(windows_per_recording),
            "invalid_windows_per_recording": int(invalid_windows_per_recording),
            "recording_seed": "numpy SeedSequence(seed, spawn_key=(file index,))",
        }
        return collector.finish(meta, overwrite)
    except BaseException:
        writer.abort()
        raise


# ------------------------------------------------------------------------ captures set


@dataclass(frozen=True)
class CaptureNormalisation:
    """Robust scaling of labelled captures, which are raw sensor values, not conditioned.

    Capture files hold raw values, larger = more pressure, with an untouched reading near
    a constant (HAART: ``1023 - ADC``, no touch ~0-5), and a capture need not start
    contact-free, so the conditioner's baseline-from-a-quiet-start does not apply.  Each
    capture's valid frames become ``(x - offset) / scale``:

    - ``offset``: the ``offset_quantile`` (5 %) of all the capture's values, channels and
      frames together.  A hand never covers the whole grid for the whole capture, so this
      is an untouched reading.  One scalar per capture, not per channel, so a channel
      pressed for the entire capture (a sustained press) keeps its signal.
    - the capture's *spread*: the ``scale_quantile`` (99 %) of ``x - offset``, its strong
      readings.  ``reference_scale`` is the median spread of the file's captures (set
      from the file when ``None``: a statistic of raw values, labels unused; the value
      used is stored with the data set so evaluation can apply the same).
    - ``per_capture=True`` (default): ``scale = max(spread, floor_fraction *
      reference_scale)``.  Scaling every capture by its own strong readings removes the
      large differences of force between people; the floor keeps a capture without
      touch from being blown up to look like one.  ``per_capture=False``: every capture
      is divided by ``reference_scale``, keeping absolute levels (and force differences).
    """

    offset_quantile: float = 0.05
    scale_quantile: float = 0.99
    per_capture: bool = True
    floor_fraction: float = 0.5
    reference_scale: float | None = None

    def __post_init__(self) -> None:
        if not 0.0 <= self.offset_quantile < self.scale_quantile <= 1.0:
            raise ValueError(
                "need 0 <= offset_quantile < scale_quantile <= 1, got "
                f"{self.offset_quantile} and {self.scale_quantile}"
            )
        if self.reference_scale is not None and not (
            np.isfinite(self.reference_scale) and self.reference_scale > 0
        ):
            raise ValueError(f"reference_scale must be positive, got {self.reference_scale}")
        if not (np.isfinite(self.floor_fraction) and self.floor_fraction > 0):
            raise ValueError(f"floor_fraction must be positive, got {self.floor_fraction}")
        if not isinstance(self.per_capture, bool):
            raise ValueError(f"per_capture must be true or false, got {self.per_capture!r}")

    def offset_and_spread(self, frames: np.ndarray) -> tuple[float, float]:
        """``(offset, spread)`` of one capture's valid frames."""
        x = np.asarray(frames, dtype=np.float64).ravel()
        offset, high = np.quantile(x, [self.offset_quantile, self.scale_quantile])
        return float(offset), float(high - offset)

    def resolved(self, captures: LabelledCaptures) -> CaptureNormalisation:
        """This normalisation with ``reference_scale`` taken from ``captures`` if ``None``."""
        if self.reference_scale is not None:
            return self
        spreads = [
            self.offset_and_spread(captures.frames[i, : captures.lengths[i]])[1]
            for i in range(len(captures.lengths))
        ]
        reference = float(np.median(spreads))
        return replace(self, reference_scale=reference if reference > 0 else 1.0)

    def scale(self, spread: float) -> float:
        """The divisor for a capture of this ``spread``."""
        if self.reference_scale is None:
            raise ValueError("resolve the reference scale first (CaptureNormalisation.resolved)")
        if not self.per_capture:
            return self.reference_scale
        return max(spread, self.floor_fraction * self.reference_scale)

    def apply(self, frames: np.ndarray) -> np.ndarray:
        """One capture's valid frames ``(T, R, C)``, normalised, as float32."""
        offset, spread = self.offset_and_spread(frames)
        scale = self.scale(spread)
        return ((np.asarray(frames, dtype=np.float64) - offset) / scale).astype(np.float32)

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> CaptureNormalisation:
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(d) - known)
        if unknown:
            raise ValueError(f"unknown capture normalisation setting(s): {', '.join(unknown)}")
        return cls(**d)


def build_dataset_from_captures(
    out_dir: str | os.PathLike,
    path: str | os.PathLike,
    window_frames: int = 30,
    stride: int | None = None,
    normalisation: CaptureNormalisation | None = None,
    dtype: str = "float16",
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
    _check_target(out, overwrite)
    dtype = _check_dtype(dtype)
    if not (isinstance(window_frames, int | np.integer) and window_frames >= 1):
        raise DatasetError(f"window_frames must be an integer >= 1, got {window_frames!r}")
    stride = int(stride) if stride is not None else max(1, int(window_frames) // 2)
    if stride < 1:
        raise DatasetError(f"stride must be >= 1, got {stride}")
    try:
        captures = read_captures(path, "a data set of captures")
    except ValueError as exc:
        raise DatasetError(_one_line(exc)) from exc
    norm = (normalisation or CaptureNormalisation()).resolved(captures)
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
    writer = _DatasetWriter(out, int(bounds[-1]), dtype)
    try:
        windows = writer.allocate((window_frames, rows, cols))
        infos = []
        for i in range(n):
            length = int(captures.lengths[i])
            normalised = norm.apply(captures.frames[i, :length])
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
        meta = _base_meta(
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


# ================================================================================ splits


@dataclass(frozen=True)
class Split:
    """Window indices for training and validation (sorted, disjoint, covering the set)."""

    name: str
    train: np.ndarray
    val: np.ndarray
    held_out: dict[str, list[str]] = field(default_factory=dict)  # key -> validation groups


def random_split(ds: WindowDataset, val_fraction: float = 0.15, seed: int = 0) -> Split:
    """The paper's split: a random ``val_fraction`` of all windows for validation.

    Windows of one recording land on both sides, so this measures fit to seen people and
    skins, not generalisation: report :func:`grouped_split` as the headline.
    """
    n = len(ds)
    n_val = _val_count(n, val_fraction)
    order = np.random.default_rng(seed).permutation(n)
    return Split("random", np.sort(order[n_val:]), np.sort(order[:n_val]))


def grouped_split(
    ds: WindowDataset,
    val_fraction: float = 0.15,
    seed: int = 0,
    by: Sequence[str] = ("person", "skin", "recording"),
) -> Split:
    """Validation groups never seen in training, for every key in ``by``.

    Windows linked through any shared group of ``by`` (the same person, the same skin or
    the same recording) form one component; whole components are drawn at random until
    validation holds the closest possible share to ``val_fraction``.  In simulated sets
    each recording has its own person and skin (:meth:`WindowDataset.unique_per_recording`),
    so the components are the recordings, and ``by=("recording",)`` gives the same split.
    Raises :class:`DatasetError` when everything forms one component.
    """
    keys = tuple(dict.fromkeys(by))
    if not keys:
        raise DatasetError("grouped_split needs at least one group key")
    for key in keys:
        _check_group_key(key)
    n = len(ds)
    _val_count(n, val_fraction)
    component = _components(ds, keys)
    sizes = np.bincount(component)
    if sizes.size < 2:
        raise DatasetError(
            f"cannot split by {'+'.join(keys)}: every window shares a group with every other "
            "(one component); group by fewer keys"
        )
    order = np.random.default_rng(seed).permutation(sizes.size)
    cumulative = np.cumsum(sizes[order])[:-1]
    take = int(np.argmin(np.abs(cumulative - val_fraction * n))) + 1
    is_val = np.isin(component, order[:take])
    split = Split(
        f"grouped by {'+'.join(keys)}",
        np.flatnonzero(~is_val),
        np.flatnonzero(is_val),
        {key: _names(ds, key, np.flatnonzero(is_val)) for key in GROUP_KEYS},
    )
    for key in keys:
        leaked = shared_groups(ds, split, key)
        if leaked:
            raise DatasetError(f"internal error: {key} group(s) {leaked} on both sides")
    return split


def leave_one_group_out(ds: WindowDataset, by: str = "person") -> Iterator[Split]:
    """One split per group of ``by`` (sorted by name): that group validates, the rest train.

    For labelled captures ``by="person"`` is leave-one-participant-out (HAART: 7 folds).
    """
    _check_group_key(by)
    ids = ds.group_ids(by)
    present = np.unique(ids)
    if present.size < 2:
        raise DatasetError(f"leave-one-group-out needs at least 2 {by} groups, got {present.size}")
    names = ds.group_names[by]
    for gid in sorted(present.tolist(), key=lambda g: names[g]):
        is_val = ids == gid
        yield Split(
            f"{by}={names[gid]}",
            np.flatnonzero(~is_val),
            np.flatnonzero(is_val),
            {key: _names(ds, key, np.flatnonzero(is_val)) for key in GROUP_KEYS},
        )


def shared_groups(ds: WindowDataset, split: Split, key: str) -> list[str]:
    """Names of ``key`` groups that appear in both training and validation."""
    ids = ds.group_ids(key)
    both = np.intersect1d(ids[split.train], ids[split.val])
    return sorted(ds.group_names[key][g] for g in both.tolist())


def _components(ds: WindowDataset, keys: tuple[str, ...]) -> np.ndarray:
    """Per-window connected-component id of the graph linking windows that share a group."""
    combos, inverse = np.unique(
        np.stack([ds.group_ids(k).astype(np.int64) for k in keys], axis=1),
        axis=0,
        return_inverse=True,
    )
    n_combos = len(combos)
    rows, cols, offset = [], [], n_combos
    for j, key in enumerate(keys):
        rows.append(np.arange(n_combos))
        cols.append(offset + combos[:, j])
        offset += len(ds.group_names[key])
    rows_a, cols_a = np.concatenate(rows), np.concatenate(cols)
    graph = coo_matrix((np.ones(rows_a.size), (rows_a, cols_a)), shape=(offset, offset))
    _, labels = connected_components(graph, directed=False)
    _, component = np.unique(labels[:n_combos], return_inverse=True)
    return component[inverse.ravel()]


def _names(ds: WindowDataset, key: str, indices: np.ndarray) -> list[str]:
    names = ds.group_names[key]
    return sorted(names[g] for g in np.unique(ds.group_ids(key)[indices]).tolist())


def _val_count(n: int, val_fraction: float) -> int:
    if not (0.0 < val_fraction < 1.0):
        raise DatasetError(f"val_fraction must lie strictly between 0 and 1, got {val_fraction}")
    if n < 2:
        raise DatasetError(f"cannot split {n} window(s)")
    return int(np.clip(round(val_fraction * n), 1, n - 1))


def _check_group_key(key: str) -> None:
    if key not in GROUP_KEYS:
        raise DatasetError(f"unknown group key {key!r}; known: {', '.join(GROUP_KEYS)}")
