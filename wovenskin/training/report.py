"""Evaluation reports of trained recognisers on window data sets, with ONNX Runtime only.

This module owns what ``wovenskin dataset``, ``train``, ``eval`` and ``compare`` show and
write about data and models, and it never imports torch:

- :func:`dataset_split` picks the windows a model is scored on: the validation side of
  the honest grouped split or of the paper's random 85/15 split
  (:mod:`~wovenskin.training.datasets`), or every window (``"all"``, for a held-out
  data set). :func:`split_record` describes a split so training can store it in the
  checkpoint and evaluation can rebuild exactly the same one.
- :func:`evaluate_on_dataset` runs a checkpoint's ONNX graph
  (:class:`~wovenskin.recognition.onnx_runtime.OnnxRecognizer`) over those windows in
  batches, after checking that the data set matches the model's input contract (grid,
  window, rate, conditioning, classes). When the checkpoint was trained on the same data
  set, it counts the evaluated windows the model saw in training and warns about them (a
  model trained on the random split and scored on the grouped one is not an honest
  figure).
- :class:`EvalReport` holds the result; :func:`write_report` writes ``metrics.json``,
  ``confusion.json`` and ``confusion.png`` (matplotlib's Agg canvas, no pyplot state);
  :func:`per_class_table` is the Rich per-class table.
- :class:`DatasetSummary` describes a data set: windows per class, people, skins,
  recordings, size on disk.
"""

from __future__ import annotations

import hashlib
import json
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from rich.table import Table

from wovenskin.recognition.onnx_runtime import ONNX_THREADS, OnnxRecognizer
from wovenskin.training.datasets import (
    DatasetError,
    Split,
    WindowDataset,
    grouped_split,
    open_dataset,
    random_split,
)
from wovenskin.training.metrics import ClassificationMetrics, classification_metrics

SPLITS = ("grouped", "random", "all")
"""Window sets a model can be scored on (``all``: every window of the data set)."""
DEFAULT_VAL_FRACTION = 0.15
EVAL_CHUNK = 2048
"""Windows converted to float32 and sent to ONNX Runtime at a time (bounds memory)."""
METRICS_FILE = "metrics.json"
CONFUSION_JSON = "confusion.json"
CONFUSION_PNG = "confusion.png"

EvalProgress = Callable[[int, int], None]
"""Called as ``progress(windows_done, windows_total)``."""


# ================================================================================ splits


def dataset_split(
    ds: WindowDataset,
    name: str,
    seed: int = 0,
    val_fraction: float = DEFAULT_VAL_FRACTION,
) -> Split:
    """The ``grouped`` or ``random`` split of ``ds``, or ``all`` (every window validates).

    ``grouped`` keeps recordings, people and skins apart (the headline figure); ``random``
    is the paper's split. ``all`` has an empty training side: it scores a model on a data
    set it never saw.
    """
    if name == "grouped":
        return grouped_split(ds, val_fraction=val_fraction, seed=seed)
    if name == "random":
        return random_split(ds, val_fraction=val_fraction, seed=seed)
    if name == "all":
        return Split("all windows", np.zeros(0, dtype=np.int64), np.arange(len(ds), dtype=np.int64))
    raise DatasetError(f"unknown split {name!r}; choose one of {', '.join(SPLITS)}")


def dataset_fingerprint(ds: WindowDataset) -> str:
    """A short digest of a data set's meta, labels and recordings (same set, same digest)."""
    digest = hashlib.sha1(json.dumps(ds.meta, sort_keys=True, default=str).encode())
    digest.update(np.ascontiguousarray(ds.labels).tobytes())
    digest.update(np.ascontiguousarray(ds.recording).tobytes())
    return digest.hexdigest()[:16]


def _index_digest(indices: np.ndarray) -> str:
    data = np.ascontiguousarray(indices, dtype=np.int64).tobytes()
    return hashlib.sha1(data).hexdigest()[:16]


def split_record(
    ds: WindowDataset, name: str, split: Split, seed: int, val_fraction: float
) -> dict[str, Any]:
    """What training stores about its data and split, so evaluation can rebuild both."""
    return {
        "dataset": {
            "path": str(ds.path.resolve()) if ds.path is not None else None,
            "fingerprint": dataset_fingerprint(ds),
            "n_windows": len(ds),
        },
        "split": {
            "name": name,
            "description": split.name,
            "seed": int(seed),
            "val_fraction": float(val_fraction),
            "n_train": int(split.train.size),
            "n_val": int(split.val.size),
            "val_digest": _index_digest(split.val),
            "held_out": {k: len(v) for k, v in split.held_out.items()},
        },
    }


# ============================================================================ evaluation


@dataclass
class EvalReport:
    """A checkpoint scored on a window set of a data set."""

    model_dir: str
    model_name: str
    data_dir: str
    split: str  # "grouped", "random" or "all"
    split_description: str
    split_seed: int
    metrics: ClassificationMetrics
    seconds: float
    warnings: list[str] = field(default_factory=list)
    seen_in_training: int = 0  # evaluated windows that were training windows of the model

    @property
    def accuracy(self) -> float:
        return self.metrics.accuracy

    @property
    def macro_f1(self) -> float:
        return self.metrics.macro_f1

    def to_dict(self) -> dict[str, Any]:
        return {
            "model_dir": self.model_dir,
            "model_name": self.model_name,
            "data_dir": self.data_dir,
            "split": self.split,
            "split_description": self.split_description,
            "split_seed": self.split_seed,
            "n_windows": self.metrics.n,
            "accuracy": self.metrics.accuracy,
            "macro_f1": self.metrics.macro_f1,
            "seen_in_training": self.seen_in_training,
            "seconds": self.seconds,
            "windows_per_s": self.metrics.n / self.seconds if self.seconds > 0 else None,
            "warnings": list(self.warnings),
            "metrics": self.metrics.to_dict(),
        }

    def summary(self) -> str:
        return (
            f"{self.model_name} on {self.metrics.n} windows ({self.split_description}): "
            f"accuracy {100 * self.accuracy:.2f} %, macro-F1 {self.macro_f1:.4f}"
        )


def dataset_conditioning(ds: WindowDataset) -> dict[str, Any]:
    """The conditioning record a checkpoint trained on ``ds`` carries (see ``train``)."""
    conditioning = ds.meta.get("conditioning")
    if conditioning is not None:
        return dict(conditioning)
    if ds.meta.get("normalisation") is not None:
        return {"capture_normalisation": dict(ds.meta["normalisation"])}
    return {}


def _trained_split(meta_training: Mapping[str, Any]) -> dict[str, Any]:
    split = meta_training.get("split")
    return dict(split) if isinstance(split, Mapping) else {}


def _trained_dataset(meta_training: Mapping[str, Any]) -> dict[str, Any]:
    dataset = meta_training.get("dataset")
    return dict(dataset) if isinstance(dataset, Mapping) else {}


def evaluate_on_dataset(
    model_dir: str | Path,
    data_dir: str | Path | WindowDataset,
    split: str | None = None,
    seed: int | None = None,
    threads: int = ONNX_THREADS,
    progress: EvalProgress | None = None,
) -> EvalReport:
    """Score the checkpoint in ``model_dir`` with ONNX Runtime on a window set of a data set.

    ``split`` (``grouped``, ``random`` or ``all``) and ``seed`` default to the split the
    checkpoint was trained with (``grouped`` and 0 when it does not say). The data set must
    match the model's grid, window, sample rate, conditioning and class names, else
    ``ValueError``.
    """
    started = time.perf_counter()
    recognizer = OnnxRecognizer(model_dir, threads=threads)
    ds = data_dir if isinstance(data_dir, WindowDataset) else open_dataset(data_dir)
    meta = recognizer.meta
    where = str(ds.path) if ds.path is not None else "the data set"
    try:
        recognizer.check_input(
            ds.rows, ds.cols, ds.window_frames, ds.sample_rate_hz, dataset_conditioning(ds)
        )
    except ValueError as exc:
        raise ValueError(f"{where} does not fit model {model_dir}: {exc}") from None
    if list(meta.class_names) != ds.class_names:
        raise ValueError(
            f"{where} has classes {', '.join(ds.class_names)}; model {model_dir} was trained "
            f"on {', '.join(meta.class_names)}"
        )
    trained = _trained_split(meta.training_data)
    split = split or trained.get("name") or "grouped"
    seed = int(seed if seed is not None else trained.get("seed", 0))
    val_fraction = float(trained.get("val_fraction", DEFAULT_VAL_FRACTION))
    chosen = dataset_split(ds, split, seed=seed, val_fraction=val_fraction)
    warnings, seen = _leakage(ds, meta.training_data, chosen)

    indices = chosen.val
    predictions = np.empty(indices.size, dtype=np.int64)
    if progress is not None:
        progress(0, int(indices.size))
    for start in range(0, indices.size, EVAL_CHUNK):
        chunk = indices[start : start + EVAL_CHUNK]
        batch = np.asarray(ds.windows[chunk], dtype=np.float32)
        predictions[start : start + chunk.size] = recognizer.predict(batch)
        if progress is not None:
            progress(int(start + chunk.size), int(indices.size))
    metrics = classification_metrics(ds.labels[indices], predictions, ds.class_names)
    return EvalReport(
        model_dir=str(Path(model_dir)),
        model_name=meta.model_name,
        data_dir=str(ds.path) if ds.path is not None else "",
        split=split,
        split_description=chosen.name,
        split_seed=seed,
        metrics=metrics,
        seconds=time.perf_counter() - started,
        warnings=warnings,
        seen_in_training=seen,
    )


def _leakage(
    ds: WindowDataset, training: Mapping[str, Any], chosen: Split
) -> tuple[list[str], int]:
    """Warnings, and how many evaluated windows the model was trained on (when knowable)."""
    trained_data, trained_split = _trained_dataset(training), _trained_split(training)
    if not trained_data or not trained_split:
        return ["the checkpoint does not record its training data; cannot check for leakage"], 0
    if trained_data.get("fingerprint") != dataset_fingerprint(ds):
        return [], 0  # another data set: nothing of it was seen in training
    try:
        used = dataset_split(
            ds,
            str(trained_split["name"]),
            seed=int(trained_split["seed"]),
            val_fraction=float(trained_split["val_fraction"]),
        )
    except (KeyError, TypeError, ValueError):
        return ["the checkpoint's training split cannot be rebuilt; cannot check for leakage"], 0
    seen = int(np.intersect1d(used.train, chosen.val, assume_unique=True).size)
    if not seen:
        return [], 0
    return [
        f"{seen} of {chosen.val.size} evaluated windows were training windows of this model "
        f"(trained on the {trained_split['name']} split): the figure is not a held-out score"
    ], seen


# =============================================================================== writing


@dataclass(frozen=True)
class ReportFiles:
    metrics_json: Path
    confusion_json: Path
    confusion_png: Path


def _normalised_rows(confusion: np.ndarray) -> np.ndarray:
    totals = confusion.sum(axis=1, keepdims=True)
    return np.divide(confusion, totals, out=np.zeros(confusion.shape), where=totals > 0)


def confusion_document(metrics: ClassificationMetrics) -> dict[str, Any]:
    """The confusion matrix as JSON: counts and row-normalised rates (rows: true class)."""
    confusion = np.asarray(metrics.confusion, dtype=np.int64)
    return {
        "class_names": list(metrics.class_names),
        "axes": "confusion[true][predicted]",
        "counts": confusion.tolist(),
        "rates": np.round(_normalised_rows(confusion), 6).tolist(),
        "n": metrics.n,
        "accuracy": metrics.accuracy,
        "macro_f1": metrics.macro_f1,
    }


def plot_confusion(metrics: ClassificationMetrics, path: str | Path, title: str = "") -> Path:
    """Draw the row-normalised confusion matrix with counts as a PNG; return its path."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    confusion = np.asarray(metrics.confusion, dtype=np.int64)
    rates = _normalised_rows(confusion)
    names = list(metrics.class_names)
    k = len(names)
    size = max(4.0, 0.55 * k + 2.5)
    figure = Figure(figsize=(size + 1.2, size), layout="constrained")
    FigureCanvasAgg(figure)
    axes = figure.add_subplot()
    image = axes.imshow(rates, cmap="Blues", vmin=0.0, vmax=1.0)
    figure.colorbar(image, ax=axes, fraction=0.046, pad=0.04, label="share of true class")
    font = 8 if k <= 16 else 6
    for i, j in zip(*np.nonzero(confusion), strict=True):
        colour = "white" if rates[i, j] > 0.6 else "black"
        axes.text(j, i, str(confusion[i, j]), ha="center", va="center", fontsize=font, color=colour)
    axes.set_xticks(range(k), names, rotation=55, ha="right", fontsize=font + 1)
    axes.set_yticks(range(k), names, fontsize=font + 1)
    axes.set_xlabel("predicted")
    axes.set_ylabel("true")
    headline = (
        f"accuracy {100 * metrics.accuracy:.2f} %, macro-F1 {metrics.macro_f1:.4f}, "
        f"{metrics.n} windows"
    )
    axes.set_title(f"{title}\n{headline}" if title else headline, fontsize=10)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(path, dpi=110)
    return path


def write_report(report: EvalReport, out_dir: str | Path) -> ReportFiles:
    """Write ``metrics.json``, ``confusion.json`` and ``confusion.png`` into ``out_dir``."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    metrics_path = out / METRICS_FILE
    metrics_path.write_text(json.dumps(report.to_dict(), indent=1) + "\n", encoding="utf-8")
    confusion_path = out / CONFUSION_JSON
    confusion_path.write_text(
        json.dumps(confusion_document(report.metrics), indent=1) + "\n", encoding="utf-8"
    )
    title = f"{report.model_name}: {report.split_description}"
    png = plot_confusion(report.metrics, out / CONFUSION_PNG, title=title)
    return ReportFiles(metrics_path, confusion_path, png)


def per_class_table(metrics: ClassificationMetrics, title: str = "") -> Table:
    """Precision, recall, F1, support and the most frequent confusion of every class."""
    confusion = np.asarray(metrics.confusion, dtype=np.int64)
    table = Table(title=title or None)
    table.add_column("class")
    for name in ("precision", "recall", "F1", "support"):
        table.add_column(name, justify="right")
    table.add_column("most often mistaken for")
    for i, score in enumerate(metrics.per_class):
        off_diagonal = confusion[i].copy()
        off_diagonal[i] = 0
        worst = int(off_diagonal.argmax())
        mistaken = (
            f"{metrics.class_names[worst]} ({off_diagonal[worst]})" if off_diagonal[worst] else ""
        )
        table.add_row(
            score.name,
            f"{score.precision:.3f}",
            f"{score.recall:.3f}",
            f"{score.f1:.3f}",
            str(score.support),
            mistaken,
        )
    table.caption = (
        f"accuracy {100 * metrics.accuracy:.2f} % | macro-F1 {metrics.macro_f1:.4f} | "
        f"{metrics.n} windows"
    )
    return table


# ============================================================================== data sets


def _size_on_disk(path: Path | None) -> int:
    if path is None or not path.is_dir():
        return 0
    return sum(p.stat().st_size for p in path.iterdir() if p.is_file())


def _human_bytes(n: int) -> str:
    size = float(n)
    for unit in ("B", "KiB", "MiB", "GiB"):
        if size < 1024 or unit == "GiB":
            return f"{size:.0f} {unit}" if unit == "B" else f"{size:.1f} {unit}"
        size /= 1024
    raise AssertionError("unreachable")


@dataclass(frozen=True)
class DatasetSummary:
    """What a window data set holds."""

    path: str
    kind: str
    n_windows: int
    class_counts: dict[str, int]
    recordings: int
    people: int
    skins: int
    rows: int
    cols: int
    window_frames: int
    sample_rate_hz: float
    dtype: str
    bytes_on_disk: int

    @classmethod
    def of(cls, ds: WindowDataset) -> DatasetSummary:
        return cls(
            path=str(ds.path) if ds.path is not None else "",
            kind=str(ds.meta.get("kind", "")),
            n_windows=len(ds),
            class_counts=ds.class_counts(),
            recordings=len(np.unique(ds.recording)),
            people=len(np.unique(ds.person)),
            skins=len(np.unique(ds.skin)),
            rows=ds.rows,
            cols=ds.cols,
            window_frames=ds.window_frames,
            sample_rate_hz=ds.sample_rate_hz,
            dtype=str(ds.windows.dtype),
            bytes_on_disk=_size_on_disk(ds.path),
        )

    def to_dict(self) -> dict[str, Any]:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}

    def table(self, class_names: Sequence[str] | None = None) -> Table:
        names = list(class_names or self.class_counts)
        table = Table(title=f"window data set {self.path}".strip())
        table.add_column("class")
        table.add_column("windows", justify="right")
        table.add_column("share", justify="right")
        for name in names:
            count = self.class_counts.get(name, 0)
            share = count / self.n_windows if self.n_windows else 0.0
            table.add_row(name, f"{count:,}", f"{100 * share:.1f} %")
        return table

    def describe(self) -> str:
        """One line: windows, their shape, recordings, people, skins, size on disk."""
        return (
            f"{self.n_windows:,} windows of {self.window_frames} frames of {self.rows}x{self.cols} "
            f"at {self.sample_rate_hz:g} Hz ({self.dtype}); {self.recordings} recordings, "
            f"{self.people} people, {self.skins} skins; {_human_bytes(self.bytes_on_disk)} on disk"
        )
