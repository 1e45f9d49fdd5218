"""Training on window data sets, and side-by-side comparison of the classifiers.

This module is the layer between the ``wovenskin train`` / ``compare`` commands and
:func:`~wovenskin.training.train.train_model`:

- :func:`ensure_dataset` opens a data set directory, or builds the default simulated set
  there (the paper's size, :func:`~wovenskin.training.datasets.generate_sim_dataset`
  defaults) when it is missing -- only for the default location, so a mistyped path is an
  error, not a 2-minute surprise.
- :func:`train_on_dataset` splits a data set (:func:`~.report.dataset_split`), trains one
  model on it and stores the data set's fingerprint and the split in the checkpoint
  (:func:`~.report.split_record`), so ``wovenskin eval`` rebuilds exactly the validation
  windows and flags windows the model was trained on.
- :func:`compare_models` trains every requested model on the same data set and the same
  split(s) in one run, scores each checkpoint with ONNX Runtime on the validation windows
  (writing its evaluation report into ``<checkpoint>/eval-<split>/``), times them at batch
  1 on one thread in interleaved rounds (:func:`~.timing.measure_latency`),
  and returns a :class:`Comparison`: the paper's side-by-side table, plus macro-F1 and
  parameter counts, written as ``compare.json``.
- :class:`TrainProgressDisplay` shows training in the terminal (Rich): a bar per epoch with
  the running loss, and one line per finished epoch with validation accuracy;
  :func:`dataset_progress` is the bar over recordings while a data set is built.

Torch is imported only inside the functions that train.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from rich.console import Console
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)
from rich.table import Table

from wovenskin.training.datasets import (
    DatasetError,
    ProgressCallback,
    WindowDataset,
    generate_sim_dataset,
    open_dataset,
)
from wovenskin.training.report import (
    DEFAULT_VAL_FRACTION,
    EvalReport,
    dataset_split,
    evaluate_on_dataset,
    split_record,
    write_report,
)

if TYPE_CHECKING:
    from wovenskin.training.train import TrainEvent, TrainResult

RUNS_DIR = Path("runs")
DEFAULT_DATASET_DIR = RUNS_DIR / "datasets" / "sim-default"
"""Where ``wovenskin train`` / ``compare`` keep the default simulated data set."""
COMPARE_FILE = "compare.json"
TRAIN_SPLITS = ("grouped", "random")
LATENCY_REPEATS = 300


def default_train_dir(model: str, split: str) -> Path:
    """Where ``wovenskin train`` puts a model by default: ``runs/models/<model>-<split>``."""
    return RUNS_DIR / "models" / f"{model}-{split}"


def ensure_dataset(
    data_dir: str | Path | None,
    progress: ProgressCallback | None = None,
    workers: int = 2,
) -> tuple[WindowDataset, bool]:
    """The data set at ``data_dir``; with ``None``, the default one, generated if missing.

    Returns the data set and whether it was just built.
    """
    if data_dir is not None:
        return open_dataset(data_dir), False
    if (DEFAULT_DATASET_DIR / "meta.json").is_file():
        return open_dataset(DEFAULT_DATASET_DIR), False
    return generate_sim_dataset(DEFAULT_DATASET_DIR, workers=workers, progress=progress), True


DEFAULT_EPOCHS = 3
"""Epochs of the default run: three passes over the 140-recording set (166,600 training
windows each) take 17-21 minutes on one thread of the project's busy 2-core machine (the
default model's recipe, see its model card)."""


@dataclass(frozen=True)
class TrainOptions:
    """Settings of one training run on a data set (see ``train_model``)."""

    epochs: int = DEFAULT_EPOCHS
    batch_size: int = 64
    lr: float = 3e-3
    seed: int = 0
    patience: int = 5
    split_seed: int = 0
    val_fraction: float = DEFAULT_VAL_FRACTION
    resume: bool = False
    time_budget_s: float | None = None
    threads: int = 1


def train_on_dataset(
    ds: WindowDataset,
    out_dir: str | Path,
    model: str = "transformer",
    split: str = "grouped",
    options: TrainOptions | None = None,
    hparams: Mapping[str, Any] | None = None,
    progress: Callable[[TrainEvent], None] | None = None,
) -> TrainResult:
    """Train registry ``model`` on the training side of ``split`` (``grouped`` or ``random``).

    The checkpoint (``out_dir``) records the data set's fingerprint and the split next to
    the data set's own description.
    """
    from wovenskin.training.train import train_model

    options = options or TrainOptions()
    if split not in TRAIN_SPLITS:
        raise DatasetError(f"cannot train on split {split!r}; choose {' or '.join(TRAIN_SPLITS)}")
    chosen = dataset_split(ds, split, seed=options.split_seed, val_fraction=options.val_fraction)
    meta = {**ds.meta, **split_record(ds, split, chosen, options.split_seed, options.val_fraction)}
    return train_model(
        model,
        ds.windows,
        ds.labels,
        ds.class_names,
        chosen.train,
        chosen.val,
        out_dir,
        meta,
        epochs=options.epochs,
        batch_size=options.batch_size,
        lr=options.lr,
        seed=options.seed,
        patience=options.patience,
        progress=progress,
        resume=options.resume,
        time_budget_s=options.time_budget_s,
        hparams=hparams,
        threads=options.threads,
    )


# ============================================================================= comparison


@dataclass
class SplitScore:
    """One model trained and scored (ONNX Runtime, validation windows) on one split."""

    split: str
    accuracy: float
    macro_f1: float
    n_val: int
    best_epoch: int
    epochs_run: int
    stop_reason: str
    train_seconds: float
    checkpoint_dir: str
    report_dir: str


@dataclass
class StreamScore:
    """A model's whole pipeline on labelled streams (event scoring, pooled over streams)."""

    n_streams: int
    n_events: int
    precision: float
    recall: float
    f1: float
    false_per_min: float
    median_latency_ms: float | None
    median_motion_latency_ms: float | None


def score_on_streams(checkpoint_dir: str | Path, streams: Sequence[Any]) -> StreamScore:
    """Run the live pipeline of the checkpoint's ONNX model on ``streams`` and score events."""
    from wovenskin.recognition.event_scoring import aggregate, score_stream
    from wovenskin.recognition.onnx_runtime import OnnxRecognizer
    from wovenskin.recognition.pipeline import (
        PipelineSettings,
        arbiter_settings_for_model,
        load_stream,
        run_pipeline,
    )

    recognizer = OnnxRecognizer(checkpoint_dir, threads=1)
    settings = PipelineSettings(arbiter=arbiter_settings_for_model(recognizer))
    scores = []
    for stream in streams:
        labelled = load_stream(stream)
        result = run_pipeline(labelled, recognizer, settings)
        scores.append(score_stream(result.commands, labelled))
    total = aggregate(scores)
    motion = getattr(total, "median_motion_latency_s", None)
    return StreamScore(
        n_streams=len(scores),
        n_events=total.n_events,
        precision=total.precision,
        recall=total.recall,
        f1=total.f1,
        false_per_min=total.false_per_min,
        median_latency_ms=None
        if total.median_latency_s is None
        else 1e3 * total.median_latency_s,
        median_motion_latency_ms=None if motion is None else 1e3 * motion,
    )


@dataclass
class ComparisonRow:
    model: str
    params: int
    scores: dict[str, SplitScore] = field(default_factory=dict)
    latency_median_ms: float = float("nan")
    latency_p99_ms: float = float("nan")
    stream: StreamScore | None = None


@dataclass
class Comparison:
    data_dir: str
    splits: list[str]
    rows: list[ComparisonRow]
    options: dict[str, Any]
    hparams: dict[str, dict[str, Any]]
    latency_repeats: int
    recipe: str = ""

    def to_dict(self) -> dict[str, Any]:
        return {
            "data_dir": self.data_dir,
            "recipe": self.recipe,
            "splits": list(self.splits),
            "options": dict(self.options),
            "hparams": dict(self.hparams),
            "latency": "ONNX Runtime, batch 1, one thread, ms per window",
            "latency_repeats": self.latency_repeats,
            "models": {
                row.model: {
                    "params": row.params,
                    "latency_median_ms": row.latency_median_ms,
                    "latency_p99_ms": row.latency_p99_ms,
                    "streams": None if row.stream is None else asdict(row.stream),
                    **{split: asdict(score) for split, score in row.scores.items()},
                }
                for row in self.rows
            },
        }

    def table(self) -> Table:
        recipe = f" ({self.recipe} recipe)" if self.recipe else ""
        table = Table(title=f"wovenskin compare on {self.data_dir}{recipe}")
        with_streams = any(row.stream is not None for row in self.rows)
        table.add_column("model")
        table.add_column("params", justify="right")
        for split in self.splits:
            table.add_column(f"{split}\nacc %", justify="right")
            table.add_column(f"{split}\nmacro-F1", justify="right")
        table.add_column("ORT ms\nmedian", justify="right")
        table.add_column("ORT ms\np99", justify="right")
        table.add_column("epochs\n(best)", justify="right")
        table.add_column("train\nmin", justify="right")
        if with_streams:
            table.add_column("stream\nevent F1", justify="right")
            table.add_column("false\n/min", justify="right")
            table.add_column("latency ms\ncontact", justify="right")
        for row in self.rows:
            cells = [row.model, f"{row.params:,}"]
            for split in self.splits:
                score = row.scores[split]
                cells += [f"{100 * score.accuracy:.2f}", f"{score.macro_f1:.4f}"]
            first = row.scores[self.splits[0]]
            train_s = sum(s.train_seconds for s in row.scores.values())
            cells += [
                f"{row.latency_median_ms:.3f}",
                f"{row.latency_p99_ms:.3f}",
                f"{first.epochs_run} ({first.best_epoch})",
                f"{train_s / 60:.1f}",
            ]
            if with_streams:
                st = row.stream
                cells += (
                    ["-", "-", "-"]
                    if st is None
                    else [
                        f"{st.f1:.3f}",
                        f"{st.false_per_min:.2f}",
                        "-" if st.median_latency_ms is None else f"{st.median_latency_ms:.0f}",
                    ]
                )
            table.add_row(*cells)
        table.caption = (
            "accuracy and macro-F1 on validation windows (grouped: recordings, people and skins "
            "never seen in training; random: the paper's 85/15); latency: ONNX Runtime, batch "
            "1, one thread"
        )
        return table


def compare_models(
    ds: WindowDataset,
    out_dir: str | Path,
    models: Sequence[str] | None = None,
    splits: Sequence[str] = ("grouped",),
    options: TrainOptions | None = None,
    hparams: Mapping[str, Mapping[str, Any]] | None = None,
    latency_repeats: int = LATENCY_REPEATS,
    progress: Callable[[str, TrainEvent], None] | None = None,
    on_report: Callable[[str, str, EvalReport], None] | None = None,
    streams: Sequence[Any] = (),
) -> Comparison:
    """Train and score ``models`` on the same data set and split(s); write ``compare.json``.

    Checkpoints go to ``out_dir/<split>/<model>/`` with their evaluation reports in
    ``eval-<split>/``. ``progress(label, event)`` gets every training event, labelled
    ``"<model> / <split>"``; ``on_report(model, split, report)`` every evaluation.
    With ``streams`` (labelled streams or their paths), each model of the first split
    also runs the whole live pipeline on them (:func:`score_on_streams`): event F1, false
    activations per minute and latency, the figures that matter to a user.
    """
    from wovenskin.recognition.onnx_runtime import OnnxRecognizer
    from wovenskin.training.checkpoint import load_checkpoint
    from wovenskin.training.models import MODEL_REGISTRY, count_parameters
    from wovenskin.training.timing import measure_latency, one_core

    models = list(models or MODEL_REGISTRY)
    unknown = [m for m in models if m not in MODEL_REGISTRY]
    if unknown or not models:
        raise ValueError(
            f"unknown model(s) {', '.join(unknown) or '(none given)'}; known: "
            f"{', '.join(MODEL_REGISTRY)}"
        )
    splits = list(dict.fromkeys(splits))
    bad = [s for s in splits if s not in TRAIN_SPLITS]
    if bad or not splits:
        raise DatasetError(f"unknown split(s) {', '.join(bad) or '(none)'}; use grouped, random")
    options = options or TrainOptions()
    extra = sorted(set(hparams or {}) - set(models))
    if extra:
        raise ValueError(f"hyperparameters given for model(s) not compared: {', '.join(extra)}")
    hparams = {m: dict((hparams or {}).get(m, {})) for m in models}
    out = Path(out_dir)
    rows = []
    for model in models:
        row = None
        for split in splits:
            checkpoint = out / split / model
            started = time.monotonic()
            result = train_on_dataset(
                ds,
                checkpoint,
                model,
                split,
                options,
                hparams[model],
                None if progress is None else _labelled(progress, f"{model} / {split}"),
            )
            train_s = time.monotonic() - started
            report = evaluate_on_dataset(checkpoint, ds, split, seed=options.split_seed)
            report_dir = checkpoint / f"eval-{split}"
            write_report(report, report_dir)
            if on_report is not None:
                on_report(model, split, report)
            if row is None:
                torch_model, _ = load_checkpoint(checkpoint)
                row = ComparisonRow(model, count_parameters(torch_model))
            row.scores[split] = SplitScore(
                split=split,
                accuracy=report.accuracy,
                macro_f1=report.macro_f1,
                n_val=report.metrics.n,
                best_epoch=result.best_epoch,
                epochs_run=result.epochs_run,
                stop_reason=result.stop_reason,
                train_seconds=train_s,
                checkpoint_dir=str(checkpoint),
                report_dir=str(report_dir),
            )
        assert row is not None
        rows.append(row)

    first = splits[0]
    recognizers = {m: OnnxRecognizer(out / first / m, threads=1) for m in models}
    val = dataset_split(ds, first, seed=options.split_seed, val_fraction=options.val_fraction).val
    pick = np.random.default_rng(0).choice(val, size=min(32, val.size), replace=False)
    pool = np.asarray(ds.windows[np.sort(pick)], dtype=np.float32)[:, np.newaxis]
    with one_core():
        times = measure_latency(
            {m: r.predict_proba for m, r in recognizers.items()}, pool, latency_repeats
        )
    for row in rows:
        row.latency_median_ms = float(np.median(times[row.model]) * 1e3)
        row.latency_p99_ms = float(np.percentile(times[row.model], 99) * 1e3)
        if streams:
            row.stream = score_on_streams(out / first / row.model, streams)

    comparison = Comparison(
        data_dir=str(ds.path) if ds.path is not None else "",
        splits=splits,
        rows=rows,
        options=asdict(options),
        hparams=hparams,
        latency_repeats=latency_repeats,
        recipe=_recipe_of(ds),
    )
    out.mkdir(parents=True, exist_ok=True)
    (out / COMPARE_FILE).write_text(json.dumps(comparison.to_dict(), indent=1) + "\n", "utf-8")
    return comparison


def _recipe_of(ds: WindowDataset) -> str:
    """How the data set's windows were drawn (``overlay`` before recipes existed)."""
    settings = ds.meta.get("window_settings")
    if not isinstance(settings, dict) or ds.meta.get("kind") == "captures":
        return ""
    return str(settings.get("recipe", "overlay"))


def _labelled(
    progress: Callable[[str, TrainEvent], None], label: str
) -> Callable[[TrainEvent], None]:
    return lambda event: progress(label, event)


# ================================================================================ display


class TrainProgressDisplay:
    """Rich display of training: a bar per epoch (running loss), a line per finished epoch.

    Use as a context manager; call it with ``(event)`` or ``(label, event)`` (the label
    names the run, e.g. ``"bilstm / grouped"``, when several train one after another).
    """

    def __init__(self, console: Console) -> None:
        self.console = console
        self._progress = Progress(
            TextColumn("{task.description}"),
            BarColumn(),
            MofNCompleteColumn(),
            TextColumn("loss {task.fields[loss]:.4f}"),
            TimeElapsedColumn(),
            TimeRemainingColumn(),
            console=console,
            transient=True,
        )
        self._task: Any = None
        self._key: tuple[str, int] | None = None
        self._best: dict[str, tuple[float, float]] = {}

    def __enter__(self) -> TrainProgressDisplay:
        self._progress.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._progress.stop()

    def __call__(self, label_or_event: str | TrainEvent, event: TrainEvent | None = None) -> None:
        if event is None:
            label, event = "", label_or_event  # type: ignore[assignment]
        else:
            label = str(label_or_event)
        assert event is not None and not isinstance(event, str)
        key = (label, event.epoch)
        if key != self._key:
            if self._task is not None:
                self._progress.remove_task(self._task)
            prefix = f"{label}  " if label else ""
            self._task = self._progress.add_task(
                f"{prefix}epoch {event.epoch}/{event.epochs}", total=event.batches, loss=event.loss
            )
            self._key = key
        self._progress.update(self._task, completed=event.batch, loss=event.loss)
        if event.kind == "epoch" and event.record is not None:
            self._progress.console.print(self._epoch_line(label, event), highlight=False)

    def _epoch_line(self, label: str, event: TrainEvent) -> str:
        r = event.record
        assert r is not None
        best_acc, best_loss = self._best.get(label, (-1.0, float("inf")))
        improved = r.val_accuracy > best_acc or (
            r.val_accuracy == best_acc and r.val_loss < best_loss
        )
        if improved:
            self._best[label] = (r.val_accuracy, r.val_loss)
        prefix = f"{label}  " if label else ""
        return (
            f"{prefix}epoch {r.epoch:>3}/{event.epochs} loss {r.train_loss:.4f} "
            f"train {100 * r.train_accuracy:6.2f}% val {100 * r.val_accuracy:6.2f}% "
            f"F1 {r.val_macro_f1:.4f} val loss {r.val_loss:.4f} lr {r.lr:.1e} "
            f"{r.seconds:4.0f} s" + (" [green]best[/]" if improved else "")
        )


def dataset_progress(console: Console, description: str) -> tuple[Progress, ProgressCallback]:
    """A Rich progress bar over recordings, and the ``progress(done, total)`` that drives it."""
    bar = Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
        console=console,
    )
    task = bar.add_task(description, total=None)

    def update(done: int, total: int) -> None:
        bar.update(task, completed=done, total=total)

    return bar, update
