"""Transductive self-training: a capture model adapted to one new person's unlabelled captures.

People touch differently, and a model trained on others errs on a new person in ways that
person's own captures could correct, even without their labels.  :func:`self_train`
scores the person's captures with the trained model, keeps the most confident share of
every predicted class (:func:`pseudo_labels`), and fine-tunes the model for a few epochs
on the training captures plus those, labelled with the model's own predictions.  The
person's true labels are never read: the copy of the captures that training sees carries
the predictions in their place.  Leave-one-participant-out runs it on the held-out
person (``CaptureConfig.self_training_epochs``); what it needs from that person, all their
captures at once, is what a user gives when recording a session to adapt to.  Needs torch.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import numpy as np

from wovenskin.recording.formats import LabelledCaptures
from wovenskin.training.capture_train import subset, train_captures_split
from wovenskin.training.config import TrainConfig
from wovenskin.training.history import TrainEvent
from wovenskin.training.train import TrainResult

ADAPTED_DIR = "adapted"
"""Subdirectory of a fold's checkpoint that holds the self-trained model."""


def pseudo_labels(log_probs: np.ndarray, fraction: float) -> tuple[np.ndarray, np.ndarray]:
    """``(positions, labels)``: the most confident ``fraction`` of every predicted class.

    ``log_probs`` ``(n, K)`` are per-capture scores (mean log-probabilities); a capture's
    confidence is the softmax probability of its top class.  Each predicted class keeps
    ``ceil(fraction * count)`` of its captures, so a class the model favours cannot crowd
    out the others.  Positions index the rows of ``log_probs``, sorted.
    """
    scores = np.asarray(log_probs, dtype=np.float64)
    if scores.ndim != 2 or scores.shape[0] == 0:
        raise ValueError(f"need per-capture scores (n, K), got shape {scores.shape}")
    if not 0.0 < fraction <= 1.0:
        raise ValueError(f"fraction must be in (0, 1], got {fraction}")
    z = scores - scores.max(axis=1, keepdims=True)
    probs = np.exp(z) / np.exp(z).sum(axis=1, keepdims=True)
    predicted = probs.argmax(axis=1)
    confidence = probs.max(axis=1)
    chosen: list[int] = []
    for label in np.unique(predicted).tolist():
        members = np.flatnonzero(predicted == label)
        keep = math.ceil(fraction * members.size)
        chosen.extend(members[np.argsort(-confidence[members], kind="stable")[:keep]].tolist())
    positions = np.array(sorted(chosen), dtype=np.int64)
    return positions, predicted[positions].astype(np.int64)


def self_train(
    captures: LabelledCaptures,
    source: str,
    train_ids: np.ndarray,
    val_ids: np.ndarray,
    target_ids: np.ndarray,
    target_log_probs: np.ndarray,
    model_dir: str | Path,
    config: TrainConfig,
    progress: Callable[[TrainEvent], None] | None = None,
) -> TrainResult:
    """Fine-tune the model in ``model_dir`` on ``train_ids`` plus pseudo-labelled targets.

    ``target_log_probs`` are the model's scores of ``target_ids`` (in that order).  The
    confident share (``config.captures.self_training_fraction``) of the targets joins the
    training captures with the predicted labels, and training restarts from the model's
    weights for ``config.captures.self_training_epochs`` epochs at half the peak learning
    rate, validated on ``val_ids`` as before.  The adapted checkpoint goes to
    ``model_dir/adapted``.
    """
    feed = config.captures
    target_ids = np.asarray(target_ids, dtype=np.int64)
    positions, guessed = pseudo_labels(target_log_probs, feed.self_training_fraction)
    labels = captures.labels.copy()
    # The targets' true labels never reach training: every one is replaced by a guess.
    labels[target_ids] = np.asarray(target_log_probs).argmax(axis=1)
    labels[target_ids[positions]] = guessed
    relabelled = replace(captures, labels=labels)
    # Keep the model's normalisation: its reference scale came from the training captures.
    norm = feed.normalisation.resolved(subset(captures, np.asarray(train_ids)))
    tuned = replace(
        config,
        captures=replace(feed, normalisation=norm),
        init_from=str(model_dir),
        epochs=feed.self_training_epochs,
        patience=feed.self_training_epochs,
        lr=config.lr / 2,
        warmup_epochs=0.0,
        resume=False,
    )
    return train_captures_split(
        relabelled,
        source,
        np.union1d(train_ids, target_ids[positions]),
        val_ids,
        Path(model_dir) / ADAPTED_DIR,
        tuned,
        f"as the model it adapts; plus {positions.size} pseudo-labelled target captures",
        progress,
    )
