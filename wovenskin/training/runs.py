"""Where training runs live, and the checks before one starts (no torch needed).

``wovenskin train`` and ``compare`` keep their outputs under :data:`RUNS_DIR`: the
default simulated data set (:func:`ensure_dataset` builds it once, only at its default
place, so a mistyped path is an error and not a 2-minute surprise), models and
comparisons.  :func:`check_checkpoint_dir` and :func:`check_comparison_dir` refuse to train
over earlier results unless resuming or overwriting.
"""

from __future__ import annotations

from pathlib import Path

from wovenskin.errors import ConfigError
from wovenskin.outputs import OutputExistsError, check_writable
from wovenskin.recognition.checkpoint_meta import read_meta
from wovenskin.training.datasets import (
    WORKERS,
    ProgressCallback,
    WindowDataset,
    generate_sim_dataset,
    open_dataset,
)

RUNS_DIR = Path("runs")
DEFAULT_DATASET_DIR = RUNS_DIR / "datasets" / "sim-default"
"""Where ``wovenskin train`` / ``compare`` keep the default simulated data set."""
COMPARE_FILE = "compare.json"
CHECKPOINT_FILES = ("model.pt", "model.onnx", "meta.json", "training_state.pt")


def default_train_dir(model: str, split: str) -> Path:
    """Where ``wovenskin train`` puts a model by default: ``runs/models/<model>-<split>``."""
    return RUNS_DIR / "models" / f"{model}-{split}"


def default_captures_dir(path: str | Path) -> Path:
    """Where ``wovenskin train --captures FILE`` puts its model: ``runs/models/captures-FILE``."""
    return RUNS_DIR / "models" / f"captures-{Path(path).stem}"


def default_lopo_dir(path: str | Path) -> Path:
    """Where ``wovenskin eval --captures FILE --lopo`` puts its folds: ``runs/lopo/FILE``."""
    return RUNS_DIR / "lopo" / Path(path).stem


def default_dataset_exists() -> bool:
    return (DEFAULT_DATASET_DIR / "meta.json").is_file()


def ensure_dataset(
    data_dir: str | Path | None,
    progress: ProgressCallback | None = None,
    workers: int = WORKERS,
) -> tuple[WindowDataset, bool]:
    """The data set at ``data_dir``; with ``None``, the default one, generated if missing.

    Returns the data set and whether it was just built.
    """
    if data_dir is not None:
        return open_dataset(data_dir), False
    if default_dataset_exists():
        return open_dataset(DEFAULT_DATASET_DIR), False
    return generate_sim_dataset(DEFAULT_DATASET_DIR, workers=workers, progress=progress), True


def eval_dataset_dir(model_dir: str | Path) -> Path:
    """The data set to score ``model_dir`` on: the one it was trained on, when it is still
    there, else the default one; a :class:`ConfigError` when there is neither."""
    trained_on = read_meta(model_dir).training_data.get("dataset") or {}
    recorded = trained_on.get("path") if isinstance(trained_on, dict) else None
    if recorded and Path(recorded).is_dir():
        return Path(recorded)
    if default_dataset_exists():
        return DEFAULT_DATASET_DIR
    raise ConfigError("no data set to score on: pass --data DIR (see wovenskin dataset)")


def check_checkpoint_dir(out: Path, overwrite: bool, resume: bool) -> None:
    """Refuse to train over a model already in ``out`` unless resuming it or ``overwrite``,
    and into a folder that could not be written (:func:`~wovenskin.outputs.check_writable`)."""
    check_writable(out, folder=True)
    if resume or overwrite or not out.is_dir():
        return
    if any((out / name).exists() for name in CHECKPOINT_FILES):
        raise OutputExistsError(out, "a trained model (--resume continues it)")


def check_comparison_dir(out: Path, overwrite: bool, resume: bool) -> None:
    """Refuse to compare into ``out`` when it holds a comparison or a trained model (in
    ``out/<split>/<model>/``) unless resuming it or ``overwrite``, and a folder that could
    not be written."""
    check_writable(out, folder=True)
    if resume or overwrite or not out.is_dir():
        return
    found = (out / COMPARE_FILE).exists() or any(
        (checkpoint / name).exists() for checkpoint in out.glob("*/*") for name in CHECKPOINT_FILES
    )
    if found:
        raise OutputExistsError(out, "a comparison (--resume continues it)")
