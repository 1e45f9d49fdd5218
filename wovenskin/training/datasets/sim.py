"""The simulated data set: one new person on one new skin per recording, windowed.

Recording ``i`` draws everything from ``SeedSequence(seed, spawn_key=(i,))``, so it does
not depend on the worker that made it or on ``n_recordings`` (a small set is a prefix of a
larger one with the same seed), and results land at fixed offsets: the files are
byte-identical for a seed whatever ``workers`` is.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from wovenskin.signal.config import ConditioningConfig
from wovenskin.sim.person import Person
from wovenskin.sim.skin_physics import SkinPhysics
from wovenskin.sim.stream import simulate_stream
from wovenskin.skin.layout import SkinLayout
from wovenskin.training.datasets.store import DatasetError, ProgressCallback, WindowDataset
from wovenskin.training.datasets.streams import (
    WindowingJob,
    sim_person_name,
    sim_skin_name,
    window_stream,
    write_recordings,
)
from wovenskin.training.datasets.writer import (
    DTYPE,
    INVALID_WINDOWS_PER_RECORDING,
    WINDOWS_PER_RECORDING,
    WORKERS,
    RecordingWindows,
    check_counts,
    check_target,
)
from wovenskin.training.window_settings import WindowSettings

RECORDINGS = 140
"""Simulated recordings of the default data set, each a new person on a new skin (the
paper's 140)."""
SECONDS_PER_RECORDING = 120.0
"""Length of each simulated recording: about 3 rounds of the 14 gestures."""


@dataclass(frozen=True)
class _SimJob:
    index: int
    seed: int
    seconds: float
    layout: dict
    invalid_fraction: float
    windowing: WindowingJob


def _simulate_recording(job: _SimJob) -> RecordingWindows:
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
    return window_stream(stream, job.windowing, rng, names, info)


def generate_sim_dataset(
    out_dir: str | os.PathLike,
    n_recordings: int = RECORDINGS,
    windows_per_recording: int = WINDOWS_PER_RECORDING,
    invalid_windows_per_recording: int = INVALID_WINDOWS_PER_RECORDING,
    seconds_per_recording: float = SECONDS_PER_RECORDING,
    seed: int = 0,
    workers: int = WORKERS,
    progress: ProgressCallback | None = None,
    settings: WindowSettings | None = None,
    conditioning: ConditioningConfig | None = None,
    layout: SkinLayout | None = None,
    invalid_fraction: float = 0.25,
    dtype: str = DTYPE,
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
    check_target(out, overwrite)
    check_counts(windows_per_recording, invalid_windows_per_recording)
    if not (isinstance(n_recordings, int | np.integer) and n_recordings >= 1):
        raise DatasetError(f"n_recordings must be an integer >= 1, got {n_recordings!r}")
    if not (np.isfinite(seconds_per_recording) and seconds_per_recording > 0):
        raise DatasetError(f"seconds_per_recording must be positive, got {seconds_per_recording}")
    settings = settings or WindowSettings()
    conditioning = conditioning or ConditioningConfig()
    layout = layout or SkinLayout()
    windowing = WindowingJob.of(
        conditioning, settings, windows_per_recording, invalid_windows_per_recording, dtype
    )
    jobs = [
        _SimJob(i, int(seed), float(seconds_per_recording), layout.to_dict(),
                float(invalid_fraction), windowing)
        for i in range(n_recordings)
    ]  # fmt: skip
    generation = {
        "builder": "generate_sim_dataset",
        "n_recordings": int(n_recordings),
        "windows_per_recording": int(windows_per_recording),
        "invalid_windows_per_recording": int(invalid_windows_per_recording),
        "seconds_per_recording": float(seconds_per_recording),
        "invalid_fraction": float(invalid_fraction),
        "layout": layout.to_dict(),
        "recording_seed": "numpy SeedSequence(seed, spawn_key=(recording index,))",
    }
    return write_recordings(
        out, "sim", windowing, seed, generation, jobs, _simulate_recording,
        lambda job: f"simulated recording {job.index}", workers, progress, overwrite,
    )  # fmt: skip
