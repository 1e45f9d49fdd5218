"""A run's progress: its epoch records and events, and ``history.json`` and
``learning_curve.png`` written after every epoch."""

from __future__ import annotations

import io
import json
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from wovenskin.io import atomic_write_bytes, dumps

HISTORY_FILE = "history.json"
CURVE_FILE = "learning_curve.png"


@dataclass(frozen=True)
class EpochRecord:
    epoch: int
    train_loss: float
    train_accuracy: float
    val_loss: float
    val_accuracy: float
    val_macro_f1: float
    lr: float
    seconds: float


@dataclass(frozen=True)
class TrainEvent:
    """Progress report: ``kind`` is ``"batch"`` (after each step) or ``"epoch"`` (after each
    epoch's validation, with ``record``)."""

    kind: str
    epoch: int
    epochs: int
    batch: int
    batches: int
    loss: float
    record: EpochRecord | None = None


def write_history(
    out_dir: str | Path, history: Sequence[EpochRecord], title: str, extra: Mapping | None = None
) -> None:
    """``history.json`` and ``learning_curve.png`` (loss and accuracy per epoch) in ``out_dir``.

    ``extra`` (JSON-friendly) is stored beside the epochs, e.g. stream figures of the model.
    """
    out_dir = Path(out_dir)
    path = out_dir / HISTORY_FILE
    previous: dict = {}
    if path.is_file():
        try:
            previous = json.loads(path.read_text()).get("extra", {}) or {}
        except (OSError, ValueError, AttributeError):
            previous = {}
    document = {
        "model": title,
        "epochs": [asdict(r) for r in history],
        "extra": {**previous, **dict(extra or {})},
    }
    atomic_write_bytes(path, (dumps(document, indent=1, allow_nan=True) + "\n").encode())
    if history:
        atomic_write_bytes(out_dir / CURVE_FILE, _learning_curve_png(history, title))


def _learning_curve_png(history: Sequence[EpochRecord], title: str) -> bytes:
    """Loss and accuracy per epoch, as PNG bytes (matplotlib's Agg canvas, no pyplot state)."""
    epochs = [r.epoch for r in history]
    fig = Figure(figsize=(9, 3.4))
    ax_loss, ax_acc = fig.subplots(1, 2)
    ax_loss.plot(epochs, [r.train_loss for r in history], "o-", label="train")
    ax_loss.plot(epochs, [r.val_loss for r in history], "s-", label="validation")
    ax_loss.set_xlabel("epoch")
    ax_loss.set_ylabel("cross-entropy")
    ax_loss.legend()
    ax_acc.plot(epochs, [r.train_accuracy for r in history], "o-", label="train")
    ax_acc.plot(epochs, [r.val_accuracy for r in history], "s-", label="validation")
    ax_acc.plot(epochs, [r.val_macro_f1 for r in history], "^--", label="validation macro-F1")
    ax_acc.set_xlabel("epoch")
    ax_acc.set_ylabel("window accuracy")
    ax_acc.legend()
    for axis in (ax_loss, ax_acc):
        axis.xaxis.set_major_locator(MaxNLocator(integer=True))
    fig.suptitle(f"{title}: learning curve")
    fig.tight_layout()
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=100)
    return buffer.getvalue()
