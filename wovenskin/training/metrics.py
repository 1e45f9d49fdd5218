"""Classification metrics of integer predictions, with numpy alone (no torch).

:func:`classification_metrics` gives accuracy, macro-F1, per-class precision, recall, F1
and support, and the confusion matrix (``confusion[true][predicted]``) as a
:class:`ClassificationMetrics`. Training (:mod:`~wovenskin.training.train`, which
re-exports these names) and torch-free evaluation with ONNX Runtime
(:mod:`~wovenskin.training.report`) share it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class ClassScore:
    name: str
    precision: float
    recall: float
    f1: float
    support: int


@dataclass(frozen=True)
class ClassificationMetrics:
    """Scores of predictions against true labels; ``confusion[true][predicted]`` counts."""

    class_names: tuple[str, ...]
    n: int
    accuracy: float
    macro_f1: float
    per_class: tuple[ClassScore, ...]
    confusion: list[list[int]]

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["class_names"] = list(self.class_names)
        d["per_class"] = [asdict(s) for s in self.per_class]
        return d


def classification_metrics(
    y_true: np.ndarray, y_pred: np.ndarray, class_names: Sequence[str]
) -> ClassificationMetrics:
    """Accuracy, macro-F1, per-class scores and confusion matrix of integer predictions.

    Precision, recall or F1 with a zero denominator count as 0. Macro-F1 averages the
    classes that occur in the labels or the predictions (as scikit-learn does).
    """
    k = len(class_names)
    y_true = np.asarray(y_true).astype(np.int64, copy=False).ravel()
    y_pred = np.asarray(y_pred).astype(np.int64, copy=False).ravel()
    if y_true.shape != y_pred.shape:
        raise ValueError(f"{y_true.size} labels but {y_pred.size} predictions")
    for name, y in (("labels", y_true), ("predictions", y_pred)):
        if y.size and (y.min() < 0 or y.max() >= k):
            raise ValueError(f"{name} must lie in [0, {k}) for {k} classes")
    confusion = np.bincount(y_true * k + y_pred, minlength=k * k).reshape(k, k)
    hits = np.diag(confusion).astype(np.float64)
    support = confusion.sum(axis=1)
    predicted = confusion.sum(axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        precision = np.where(predicted > 0, hits / predicted, 0.0)
        recall = np.where(support > 0, hits / support, 0.0)
        denominator = precision + recall
        f1 = np.where(denominator > 0, 2 * precision * recall / denominator, 0.0)
    present = (support > 0) | (predicted > 0)
    n = int(y_true.size)
    return ClassificationMetrics(
        class_names=tuple(class_names),
        n=n,
        accuracy=float(hits.sum() / n) if n else 0.0,
        macro_f1=float(f1[present].mean()) if present.any() else 0.0,
        per_class=tuple(
            ClassScore(str(name), float(p), float(r), float(f), int(s))
            for name, p, r, f, s in zip(class_names, precision, recall, f1, support, strict=True)
        ),
        confusion=confusion.tolist(),
    )
