"""Leave-one-participant-out cross-validation on labelled captures: the cross-person figure.

:func:`leave_one_participant_out` trains one model per participant of the file on all the
others (:func:`~wovenskin.training.capture_train.train_captures_split`) and scores that
participant's captures (:func:`~wovenskin.training.capture_eval.score_captures`), after
adapting the model to them without their labels when the recipe self-trains
(:mod:`~wovenskin.training.capture_selftrain`).  Needs torch.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from wovenskin.errors import ConfigError, DataError
from wovenskin.io import write_json
from wovenskin.recognition.onnx_runtime import OnnxRecognizer
from wovenskin.training.capture_eval import CaptureEvaluation, per_class_dict, score_captures
from wovenskin.training.capture_prep import read_capture_file
from wovenskin.training.capture_selftrain import ADAPTED_DIR, self_train
from wovenskin.training.capture_train import internal_validation, train_captures_split
from wovenskin.training.config import CAPTURE_DEFAULTS, TrainConfig
from wovenskin.training.history import TrainEvent
from wovenskin.training.metrics import ClassificationMetrics, classification_metrics

LOPO_FILE = "lopo.json"


@dataclass
class FoldResult:
    """One leave-one-participant-out fold: trained on the others, scored on ``participant``."""

    index: int  # 1-based
    folds: int
    participant: str
    evaluation: CaptureEvaluation
    best_epoch: int
    epochs_run: int
    train_seconds: float
    checkpoint_dir: str
    accuracy_before_self_training: float | None = None
    """The fold model's capture accuracy before it adapted to the participant (when the
    recipe self-trains; ``evaluation`` is then the adapted model's)."""

    def to_dict(self) -> dict[str, Any]:
        e = self.evaluation
        return {
            "participant": self.participant,
            "capture_accuracy": e.capture_accuracy,
            "capture_accuracy_before_self_training": self.accuracy_before_self_training,
            "window_accuracy": e.window_accuracy,
            "macro_f1": e.captures.macro_f1,
            "n_captures": e.captures.n,
            "n_windows": e.windows.n,
            "confusion": e.captures.confusion,
            "best_epoch": self.best_epoch,
            "epochs_run": self.epochs_run,
            "train_seconds": self.train_seconds,
            "checkpoint_dir": self.checkpoint_dir,
        }


@dataclass
class LopoResult:
    """Leave-one-participant-out cross-validation of a capture recipe on one file."""

    source: str
    class_names: tuple[str, ...]
    config: TrainConfig
    folds: list[FoldResult]
    seconds: float

    def _pooled(self, kind: str) -> ClassificationMetrics:
        k = len(self.class_names)
        confusion = np.zeros((k, k), dtype=np.int64)
        for fold in self.folds:
            confusion += np.asarray(getattr(fold.evaluation, kind).confusion, dtype=np.int64)
        true = np.repeat(np.repeat(np.arange(k), k), confusion.ravel())
        pred = np.repeat(np.tile(np.arange(k), k), confusion.ravel())
        return classification_metrics(true, pred, self.class_names)

    @property
    def captures(self) -> ClassificationMetrics:
        """All held-out captures of all folds together."""
        return self._pooled("captures")

    @property
    def windows(self) -> ClassificationMetrics:
        return self._pooled("windows")

    @property
    def capture_accuracy(self) -> float:
        return self.captures.accuracy

    @property
    def window_accuracy(self) -> float:
        return self.windows.accuracy

    @property
    def mean_fold_capture_accuracy(self) -> float:
        return float(np.mean([f.evaluation.capture_accuracy for f in self.folds]))

    def to_dict(self) -> dict[str, Any]:
        captures, windows = self.captures, self.windows
        return {
            "source": self.source,
            "protocol": "leave one participant out; one label per capture",
            "capture_accuracy": captures.accuracy,
            "mean_fold_capture_accuracy": self.mean_fold_capture_accuracy,
            "window_accuracy": windows.accuracy,
            "macro_f1": captures.macro_f1,
            "n_captures": captures.n,
            "n_windows": windows.n,
            "class_names": list(self.class_names),
            "per_class": per_class_dict(captures),
            "confusion": captures.confusion,
            "folds": [f.to_dict() for f in self.folds],
            "recipe": self.config.capture_record(),
            "seed": self.config.seed,
            "seconds": self.seconds,
        }

    def summary(self) -> str:
        per_fold = ", ".join(
            f"{f.participant} {100 * f.evaluation.capture_accuracy:.1f}" for f in self.folds
        )
        return (
            f"LOPO over {len(self.folds)} participants: capture accuracy "
            f"{100 * self.capture_accuracy:.1f} % (per participant: {per_fold}), window "
            f"accuracy {100 * self.window_accuracy:.1f} %, macro-F1 {self.captures.macro_f1:.3f}"
        )


def leave_one_participant_out(
    path: str | Path,
    out_dir: str | Path,
    config: TrainConfig | None = None,
    *,
    progress: Callable[[TrainEvent], None] | None = None,
    participants: Sequence[str] | None = None,
    on_fold: Callable[[FoldResult], None] | None = None,
) -> LopoResult:
    """Leave-one-participant-out cross-validation, one label per capture.

    For every participant of the file's ``groups`` (or only ``participants``), a model is
    trained as :func:`~wovenskin.training.capture_train.train_on_captures` would (the same
    ``config``, default :data:`CAPTURE_DEFAULTS`; internal validation drawn from the other
    participants only; never resumed) into ``out_dir/fold-<participant>/`` and scores that
    participant's captures with ONNX Runtime (:func:`score_captures`, ``config.threads``).
    With ``config.captures.self_training_epochs`` the fold's model is then adapted to that
    participant's captures without their labels
    (:func:`~wovenskin.training.capture_selftrain.self_train`, into
    ``fold-<participant>/adapted/``), the adapted model is what is scored, and the fold
    keeps the score before adaptation too.
    ``progress`` gets every fold's training events, ``on_fold`` every finished
    :class:`FoldResult`; ``out_dir/lopo.json`` is rewritten after every fold.
    """
    started = time.perf_counter()
    config = replace((config or CAPTURE_DEFAULTS).checked(), resume=False)
    captures = read_capture_file(path)
    groups = captures.groups.astype(str)
    names = sorted(set(groups.tolist()))
    if participants:
        unknown = sorted(set(participants) - set(names))
        if unknown:
            raise ConfigError(f"participant(s) {', '.join(unknown)} not in {path}")
        names = [n for n in names if n in set(participants)]
    if len(set(groups.tolist())) < 2:
        raise DataError(f"{path}: leave-one-participant-out needs at least 2 participants")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    result = LopoResult(str(path), tuple(captures.class_names), config, [], 0.0)
    for index, name in enumerate(names, start=1):
        held_out = np.flatnonzero(groups == name)
        train_ids, val_ids = internal_validation(
            captures.labels, groups, np.flatnonzero(groups != name), config.seed
        )
        fold_dir = out / f"fold-{name}"
        fold_started = time.perf_counter()
        trained = train_captures_split(
            captures, str(path), train_ids, val_ids, fold_dir, config,
            "one capture per (group, class) of the training participants", progress,
        )  # fmt: skip
        train_seconds = time.perf_counter() - fold_started
        evaluation = score_captures(
            OnnxRecognizer(fold_dir, threads=config.threads), captures, held_out, source=str(path)
        )
        before: float | None = None
        if config.captures.self_training_epochs > 0:
            assert evaluation.log_probs is not None
            before = evaluation.capture_accuracy
            self_train(
                captures, str(path), train_ids, val_ids, held_out, evaluation.log_probs,
                fold_dir, config, progress,
            )  # fmt: skip
            train_seconds = time.perf_counter() - fold_started
            evaluation = score_captures(
                OnnxRecognizer(fold_dir / ADAPTED_DIR, threads=config.threads),
                captures, held_out, source=str(path),
            )  # fmt: skip
        fold = FoldResult(
            index, len(names), name, evaluation, trained.best_epoch, trained.epochs_run,
            train_seconds, str(fold_dir), before,
        )  # fmt: skip
        result.folds.append(fold)
        result.seconds = time.perf_counter() - started
        write_json(out / LOPO_FILE, result.to_dict())
        if on_fold is not None:
            on_fold(fold)
    return result
