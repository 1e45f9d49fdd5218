"""Window data sets: stored on disk, built from simulation, streams or captures, and split.

- :mod:`~.store`: the directory format, :class:`WindowDataset`, :func:`open_dataset`;
- :mod:`~.writer` and :mod:`~.jobs`: how builders write (a partial directory renamed into
  place) and run one job per recording on worker processes;
- builders: :func:`generate_sim_dataset` (:mod:`~.sim`: one new simulated person on one
  new skin per recording), :func:`build_dataset_from_streams` (:mod:`~.streams`:
  labelled streams and native recordings) and :func:`build_dataset_from_captures`
  (:mod:`~.captures`: labelled captures such as HAART, scaled by
  :class:`CaptureNormalisation`, :mod:`~.normalisation`);
- :mod:`~.splits`: :func:`random_split` (the paper's 85/15), :func:`grouped_split`
  (validation recordings, people and skins never appear in training) and
  :func:`leave_one_group_out`.

The builders' defaults are written once: counts, workers and dtype in :mod:`~.writer`,
the simulated recordings and their length in :mod:`~.sim`.  Everything a caller needs is
importable from this package.
"""

from wovenskin.training.datasets.captures import build_dataset_from_captures
from wovenskin.training.datasets.normalisation import CaptureNormalisation
from wovenskin.training.datasets.sim import RECORDINGS, SECONDS_PER_RECORDING, generate_sim_dataset
from wovenskin.training.datasets.splits import (
    Split,
    grouped_split,
    leave_one_group_out,
    random_split,
    shared_groups,
)
from wovenskin.training.datasets.store import (
    FORMAT,
    FORMAT_VERSION,
    GROUP_KEYS,
    WINDOW_DTYPES,
    DatasetError,
    ProgressCallback,
    WindowDataset,
    open_dataset,
)
from wovenskin.training.datasets.streams import (
    build_dataset_from_streams,
    load_stream,
    sim_person_name,
    sim_skin_name,
    stream_identity,
)
from wovenskin.training.datasets.writer import (
    DTYPE,
    INVALID_WINDOWS_PER_RECORDING,
    WINDOWS_PER_RECORDING,
    WORKERS,
)

__all__ = [
    "DTYPE",
    "FORMAT",
    "FORMAT_VERSION",
    "GROUP_KEYS",
    "INVALID_WINDOWS_PER_RECORDING",
    "RECORDINGS",
    "SECONDS_PER_RECORDING",
    "WINDOWS_PER_RECORDING",
    "WINDOW_DTYPES",
    "WORKERS",
    "CaptureNormalisation",
    "DatasetError",
    "ProgressCallback",
    "Split",
    "WindowDataset",
    "build_dataset_from_captures",
    "build_dataset_from_streams",
    "generate_sim_dataset",
    "grouped_split",
    "leave_one_group_out",
    "load_stream",
    "open_dataset",
    "random_split",
    "shared_groups",
    "sim_person_name",
    "sim_skin_name",
    "stream_identity",
]
