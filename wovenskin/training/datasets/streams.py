"""Windows from labelled streams and native recordings: conditioning, windowing, identity.

:func:`build_dataset_from_streams` windows labelled-stream ``.npz`` files or native
``.wsrec`` recordings; :func:`window_stream` (conditioning one stream and cutting its
windows, :mod:`~wovenskin.training.windows` or :mod:`~wovenskin.training.stream_windows`
by the recipe) and :func:`write_recordings` (one worker per recording into a new data
set) are shared with the simulated builder.  File ``i`` draws its windows from
``SeedSequence(seed, spawn_key=(i,))``.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from wovenskin.errors import DataError
from wovenskin.gestures import CLASS_NAMES, INVALID
from wovenskin.io import to_jsonable
from wovenskin.recording.files import read_stream
from wovenskin.recording.formats import LabelledStream
from wovenskin.signal.conditioner import condition_recording
from wovenskin.signal.config import ConditioningConfig
from wovenskin.sim.person import Person
from wovenskin.sim.skin_physics import SkinPhysics
from wovenskin.training.datasets.jobs import one_line, run_jobs
from wovenskin.training.datasets.store import DatasetError, ProgressCallback, WindowDataset
from wovenskin.training.datasets.writer import (
    DTYPE,
    INVALID_WINDOWS_PER_RECORDING,
    WINDOWS_PER_RECORDING,
    WORKERS,
    DatasetWriter,
    RecordingCollector,
    RecordingWindows,
    base_meta,
    check_counts,
    check_dtype,
    check_target,
)
from wovenskin.training.stream_windows import characteristic_spans, sample_stream_windows
from wovenskin.training.window_settings import WindowSettings
from wovenskin.training.windows import (
    FrameEvents,
    align_to_contact,
    events_to_frames,
    sample_windows,
)


@dataclass(frozen=True)
class WindowingJob:
    """What every worker needs to window a recording (plain data, cheap to send)."""

    conditioning: dict
    settings: dict
    class_names: tuple[str, ...]
    n_gesture: int
    n_invalid: int
    dtype: str

    @classmethod
    def of(
        cls,
        conditioning: ConditioningConfig,
        settings: WindowSettings | None,
        n_gesture: int,
        n_invalid: int,
        dtype: str,
    ) -> WindowingJob:
        """The job of a data set of the 14 gestures (``settings`` None: the defaults)."""
        settings = settings or WindowSettings()
        return cls(
            conditioning.to_dict(), settings.to_dict(), CLASS_NAMES, int(n_gesture),
            int(n_invalid), check_dtype(dtype),
        )  # fmt: skip


def window_stream(
    stream: LabelledStream,
    job: WindowingJob,
    rng: np.random.Generator,
    names: tuple[str, str, str],
    info: dict,
) -> RecordingWindows:
    """Condition one labelled stream and cut its windows."""
    config = ConditioningConfig.from_dict(job.conditioning)
    settings = WindowSettings.from_dict(job.settings)
    if not np.isclose(stream.sample_rate_hz, config.sample_rate_hz, rtol=1e-6):
        raise DataError(
            f"the stream runs at {stream.sample_rate_hz:g} Hz but the data set's conditioning "
            f"is set for {config.sample_rate_hz:g} Hz"
        )
    index = {name: i for i, name in enumerate(job.class_names)}
    unknown = sorted({str(label) for label in stream.event_labels} - index.keys())
    if unknown:
        raise DataError(f"event label(s) {', '.join(map(repr, unknown))} are not known classes")
    if INVALID not in index:
        raise DataError(f"the class list has no {INVALID!r} class")
    _, conditioned = condition_recording(stream.frames, config)
    events = events_to_frames(
        stream.t,
        stream.event_start_s,
        stream.event_end_s,
        [index[str(label)] for label in stream.event_labels],
        motion_end_s(stream),
        settings.rest_context_frames,
    )
    # A gesture the conditioning never saw touch the skin (a missed trial) teaches nothing.
    events, keep = align_to_contact(events, conditioned.touched, index[INVALID])
    dropped = [str(stream.event_labels[i]) for i in np.flatnonzero(~keep)]
    kept = FrameEvents(
        events.labels[keep], events.start[keep], events.stop[keep], events.informative_stop[keep]
    )
    if settings.recipe == "stream":
        motion_start, motion_stop = motion_frames(stream)
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
    return RecordingWindows(
        windows=batch.windows.astype(job.dtype, copy=False),
        labels=batch.labels,
        sources=batch.sources,
        recording=names[0],
        person=names[1],
        skin=names[2],
        info=info,
    )


def motion_end_s(stream: LabelledStream) -> np.ndarray | None:
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


def motion_frames(stream: LabelledStream) -> tuple[np.ndarray | None, np.ndarray | None]:
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
    text = json.dumps(to_jsonable(document), sort_keys=True)
    return hashlib.sha1(text.encode()).hexdigest()[:10]


def sim_person_name(person: Person) -> str:
    """Group name of a simulated person: a digest of all its traits."""
    return f"sim-person-{_digest(person.to_dict())}"


def sim_skin_name(physics: SkinPhysics) -> str:
    """Group name of a simulated skin: a digest of all its physics parameters."""
    return f"sim-skin-{_digest(physics.to_dict())}"


@dataclass(frozen=True)
class _StreamJob:
    index: int
    path: str
    seed: int
    person: str | None
    skin: str | None
    windowing: WindowingJob


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


def _window_stream_file(job: _StreamJob) -> RecordingWindows:
    """Worker: read one recording, condition it and cut its windows."""
    stream = load_stream(job.path)
    person, skin = stream_identity(stream)
    rng = np.random.default_rng(np.random.SeedSequence(job.seed, spawn_key=(job.index,)))
    names = (_recording_name(job.index, job.path), job.person or person, job.skin or skin)
    return window_stream(stream, job.windowing, rng, names, {"path": job.path})


def _recording_name(index: int, path: str) -> str:
    return f"{index:05d}-{Path(path).name}"


def build_dataset_from_streams(
    out_dir: str | os.PathLike,
    paths: Sequence[str | os.PathLike],
    windows_per_recording: int = WINDOWS_PER_RECORDING,
    invalid_windows_per_recording: int = INVALID_WINDOWS_PER_RECORDING,
    seed: int = 0,
    workers: int = WORKERS,
    progress: ProgressCallback | None = None,
    settings: WindowSettings | None = None,
    conditioning: ConditioningConfig | None = None,
    persons: Sequence[str] | None = None,
    skins: Sequence[str] | None = None,
    dtype: str = DTYPE,
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
    check_target(out, overwrite)
    check_counts(windows_per_recording, invalid_windows_per_recording)
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
            raise DatasetError(one_line(exc)) from exc
        conditioning = ConditioningConfig(sample_rate_hz=rate)
    settings = settings or WindowSettings()
    windowing = WindowingJob.of(
        conditioning, settings, windows_per_recording, invalid_windows_per_recording, dtype
    )
    jobs = [
        _StreamJob(i, p, int(seed), persons[i] if persons else None,
                   skins[i] if skins else None, windowing)
        for i, p in enumerate(paths)
    ]  # fmt: skip
    generation = {
        "builder": "build_dataset_from_streams",
        "paths": paths,
        "windows_per_recording": int(windows_per_recording),
        "invalid_windows_per_recording": int(invalid_windows_per_recording),
        "recording_seed": "numpy SeedSequence(seed, spawn_key=(file index,))",
    }
    return write_recordings(
        out, "streams", windowing, seed, generation, jobs, _window_stream_file,
        lambda job: job.path, workers, progress, overwrite,
    )  # fmt: skip


def write_recordings(
    out: Path,
    kind: str,
    windowing: WindowingJob,
    seed,
    generation: dict,
    jobs: Sequence,
    worker: Callable[[Any], RecordingWindows],
    describe: Callable[[Any], str],
    workers: int,
    progress: ProgressCallback | None,
    overwrite: bool,
) -> WindowDataset:
    """Run ``worker`` on every job (one recording each) into a new data set at ``out``.

    Each recording's windows land at its fixed offset; the data set's meta is ``kind``'s
    (grid read from the windows, rate, window settings and conditioning from
    ``windowing``, ``seed``) with ``generation`` describing the builder.  On any failure
    the partial directory is removed.
    """
    per_recording = windowing.n_gesture + windowing.n_invalid
    writer = DatasetWriter(out, len(jobs) * per_recording, windowing.dtype)
    try:
        collector = RecordingCollector(writer, len(jobs), per_recording)
        run_jobs(jobs, worker, workers, collector, progress, describe)
        assert writer.windows is not None
        _, rows, cols = writer.windows.shape[1:]
        meta = base_meta(
            kind,
            windowing.class_names,
            rows,
            cols,
            windowing.conditioning["sample_rate_hz"],
            windowing.settings,
            seed,
        )
        meta["conditioning"] = windowing.conditioning
        meta["generation"] = generation
        return collector.finish(meta, overwrite)
    except BaseException:
        writer.abort()
        raise
