"""Training on window data sets, and side-by-side comparison of the classifiers.

- :func:`train_on_dataset` splits a data set (:func:`~.report.dataset_split`), trains one
  model on it and stores the data set's fingerprint and the split in the checkpoint
  (:func:`~.report.split_record`), so ``wovenskin eval`` rebuilds exactly the validation
  windows and flags windows the model was trained on.
- :func:`compare_models` trains every requested model on the same data set and the same
  split(s) in one run, scores each checkpoint with ONNX Runtime on the validation windows
  (writing its evaluation report into ``<checkpoint>/eval-<split>/``), times them at batch
  1 on one thread in interleaved rounds (:func:`~.timing.measure_latency`),
  and returns a :class:`Comparison`: the paper's side-by-side table, plus macro-F1 and
  parameter counts, written as ``compare.json``.  Any model of the registry
  (:data:`~.models.MODEL_REGISTRY`) can be named.

Both take one :class:`~wovenskin.training.config.TrainConfig`.  Needs torch.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from rich.table import Table

from wovenskin.errors import ConfigError
from wovenskin.io import dumps
from wovenskin.recognition.event_scoring import aggregate, score_stream
from wovenskin.recognition.onnx_runtime import OnnxRecognizer
from wovenskin.recognition.pipeline import (
    load_stream,
    pipeline_settings_for_model,
    run_pipeline,
)
from wovenskin.settings import to_dict
from wovenskin.training.checkpoint import load_checkpoint
from wovenskin.training.config import TrainConfig
from wovenskin.training.datasets import DatasetError, WindowDataset
from wovenskin.training.history import TrainEvent
from wovenskin.training.models import MODEL_REGISTRY, count_parameters
from wovenskin.training.report import (
    EvalReport,
    dataset_split,
    evaluate_on_dataset,
    split_record,
    write_report,
)
from wovenskin.training.runs import COMPARE_FILE
from wovenskin.training.timing import measure_latency, one_core
from wovenskin.training.train import TrainResult, train_model

TRAIN_SPLITS = ("grouped", "random")
LATENCY_REPEATS = 300


def train_on_dataset(
    ds: WindowDataset,
    out_dir: str | Path,
    split: str = "grouped",
    config: TrainConfig | None = None,
    progress: Callable[[TrainEvent], None] | None = None,
) -> TrainResult:
    """Train ``config.model`` on the training side of ``split`` (``grouped`` or ``random``).

    The checkpoint (``out_dir``) records the data set's fingerprint and the split next to
    the data set's own description.
    """
    config = config or TrainConfig()
    if split not in TRAIN_SPLITS:
        raise DatasetError(f"cannot train on split {split!r}; choose {' or '.join(TRAIN_SPLITS)}")
    chosen = dataset_split(ds, split, seed=config.split_seed, val_fraction=config.val_fraction)
    meta = {**ds.meta, **split_record(ds, split, chosen, config.split_seed, config.val_fraction)}
    return train_model(
        ds.windows, ds.labels, ds.class_names, chosen.train, chosen.val, out_dir, meta, config,
        progress,
    )  # fmt: skip


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

    recognizer = OnnxRecognizer(checkpoint_dir, threads=1)
    settings = pipeline_settings_for_model(recognizer)
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
        median_latency_ms=None if total.median_latency_s is None else 1e3 * total.median_latency_s,
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
    config: TrainConfig | None = None,
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
    models = list(models or MODEL_REGISTRY)
    unknown = [m for m in models if m not in MODEL_REGISTRY]
    if unknown or not models:
        raise ConfigError(
            f"unknown model(s) {', '.join(unknown) or '(none given)'}; known: "
            f"{', '.join(MODEL_REGISTRY)}"
        )
    splits = list(dict.fromkeys(splits))
    bad = [s for s in splits if s not in TRAIN_SPLITS]
    if bad or not splits:
        raise DatasetError(f"unknown split(s) {', '.join(bad) or '(none)'}; use grouped, random")
    config = config or TrainConfig()
    extra = sorted(set(hparams or {}) - set(models))
    if extra:
        raise ConfigError(f"hyperparameters given for model(s) not compared: {', '.join(extra)}")
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
                split,
                replace(config, model=model, hparams=hparams[model]),
                None if progress is None else _labelled(progress, f"{model} / {split}"),
            )
            train_s = time.monotonic() - started
            report = evaluate_on_dataset(checkpoint, ds, split, seed=config.split_seed)
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
    val = dataset_split(ds, first, seed=config.split_seed, val_fraction=config.val_fraction).val
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
        options={k: v for k, v in to_dict(config).items() if k != "captures"},
        hparams=hparams,
        latency_repeats=latency_repeats,
        recipe=_recipe_of(ds),
    )
    out.mkdir(parents=True, exist_ok=True)
    (out / COMPARE_FILE).write_text(dumps(comparison.to_dict(), indent=1, allow_nan=True) + "\n")
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
