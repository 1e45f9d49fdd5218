"""Scoring windows with a torch model or a recogniser: scores in batches, and metrics.

:func:`evaluate` scores a torch model or an
:class:`~wovenskin.recognition.onnx_runtime.OnnxRecognizer` on windows;
:func:`~wovenskin.training.metrics.classification_metrics` (torch-free) computes accuracy,
macro-F1, per-class precision, recall and F1 and the confusion matrix.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Protocol

import numpy as np
import torch
from torch import nn

from wovenskin.errors import DataError
from wovenskin.training.device import module_device
from wovenskin.training.metrics import ClassificationMetrics, classification_metrics

EVAL_BATCH = 512


class Recognizer(Protocol):
    """Anything with ``predict_proba`` over windows, e.g. an ``OnnxRecognizer``."""

    class_names: Sequence[str]

    def predict_proba(self, windows: np.ndarray) -> np.ndarray: ...


def float32_batch(windows: Any, idx: np.ndarray) -> np.ndarray:
    batch = np.asarray(windows[idx], dtype=np.float32)
    if not np.isfinite(batch).all():
        bad = idx[~np.isfinite(batch.reshape(batch.shape[0], -1)).all(axis=1)]
        raise DataError(f"window {int(bad[0])} contains NaN or inf values")
    return batch


def chunks(idx: np.ndarray, size: int) -> list[np.ndarray]:
    return [idx[i : i + size] for i in range(0, idx.size, size)]


def predict_scores(
    model_or_recognizer: nn.Module | Recognizer,
    windows: Any,
    indices: np.ndarray | None = None,
    batch_size: int = EVAL_BATCH,
) -> np.ndarray:
    """``(n, K)`` scores of ``windows[indices]`` (all windows by default), in batches.

    Scores are logits for a torch model and probabilities for a recogniser; both rank
    classes the same way.  A torch model is run on its own device (float32 scores back
    on the CPU).
    """
    idx = np.arange(len(windows)) if indices is None else np.asarray(indices, dtype=np.int64)
    parts: list[np.ndarray] = []
    if isinstance(model_or_recognizer, nn.Module):
        model = model_or_recognizer
        device = module_device(model)
        was_training = model.training
        model.eval()
        try:
            with torch.inference_mode():
                for chunk in chunks(idx, batch_size):
                    x = torch.from_numpy(float32_batch(windows, chunk)).to(device)
                    parts.append(model(x).float().cpu().numpy())
        finally:
            model.train(was_training)
        n_classes = int(model.n_classes)
    else:
        for chunk in chunks(idx, batch_size):
            parts.append(model_or_recognizer.predict_proba(float32_batch(windows, chunk)))
        n_classes = len(model_or_recognizer.class_names)
    if not parts:
        return np.zeros((0, n_classes), dtype=np.float32)
    return np.concatenate(parts, axis=0)


def evaluate(
    model_or_recognizer: nn.Module | Recognizer,
    windows: Any,
    labels: np.ndarray,
    class_names: Sequence[str] | None = None,
    indices: np.ndarray | None = None,
    batch_size: int = EVAL_BATCH,
) -> ClassificationMetrics:
    """Score a torch model or a recogniser on ``windows[indices]`` against ``labels[indices]``.

    ``class_names`` defaults to the recogniser's; a torch model needs them given, or gets
    ``class_0``, ``class_1``... names.
    """
    if class_names is None:
        class_names = getattr(model_or_recognizer, "class_names", None)
    if class_names is None:
        class_names = [f"class_{i}" for i in range(int(model_or_recognizer.n_classes))]
    labels = np.asarray(labels)
    if len(labels) != len(windows):
        raise ValueError(f"{len(windows)} windows but {len(labels)} labels")
    idx = np.arange(len(windows)) if indices is None else np.asarray(indices, dtype=np.int64)
    scores = predict_scores(model_or_recognizer, windows, idx, batch_size)
    if scores.shape[1] != len(class_names):
        raise ValueError(f"model gives {scores.shape[1]} classes, {len(class_names)} names given")
    return classification_metrics(labels[idx], scores.argmax(axis=1), class_names)
