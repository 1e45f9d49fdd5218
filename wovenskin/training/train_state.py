"""Where a training run stands, and the state file that lets an interrupted run resume.

:class:`RunProgress` books the epochs of a run: its history, the best epoch (validation
accuracy, ties to the lower loss) with its weights, and why it stopped (all epochs done,
or early stopping after ``patience`` epochs without a better one).  After every epoch the
trainer (:mod:`~wovenskin.training.train`) writes ``training_state.pt``
(:data:`STATE_FILE`): the run's fingerprint (model, hyperparameters, classes, data,
split and optimisation settings), the model, optimiser, schedule (and float16 gradient
scaler) states and the progress.  :func:`resume_state` reads it back for a resumed run,
refusing one made with other settings with a one-line :class:`ConfigError`; in a
distributed run rank 0 reads it and every rank gets it (:mod:`~.distributed`).
"""

from __future__ import annotations

import io
import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import torch
from torch import nn

from wovenskin.errors import ConfigError
from wovenskin.io import atomic_write_bytes
from wovenskin.training import distributed
from wovenskin.training.config import TrainConfig
from wovenskin.training.distributed import Ranks
from wovenskin.training.history import EpochRecord

STATE_FILE = "training_state.pt"


@dataclass
class RunProgress:
    """Where a run stands: the epochs done, the best one so far and why it stopped."""

    epoch: int = 0
    history: list[EpochRecord] = field(default_factory=list)
    best_epoch: int = 0
    best_val_accuracy: float = -1.0
    best_val_loss: float = math.inf
    best_state: dict[str, torch.Tensor] | None = None
    epochs_since_best: int = 0
    stop_reason: str | None = None

    def add(self, record: EpochRecord, model: nn.Module, settings: TrainConfig) -> bool:
        """Book an epoch; True when it is the best so far (ties go to the lower loss)."""
        self.epoch = record.epoch
        self.history.append(record)
        improved = record.val_accuracy > self.best_val_accuracy or (
            record.val_accuracy == self.best_val_accuracy and record.val_loss < self.best_val_loss
        )
        if improved:
            self.best_epoch = record.epoch
            self.best_val_accuracy = record.val_accuracy
            self.best_val_loss = record.val_loss
            self.best_state = {k: v.detach().clone() for k, v in model.state_dict().items()}
            self.epochs_since_best = 0
        else:
            self.epochs_since_best += 1
        if record.epoch >= settings.epochs:
            self.stop_reason = "completed"
        elif self.epochs_since_best >= settings.patience:
            self.stop_reason = "early_stopping"
        return improved

    def to_state(self) -> dict[str, Any]:
        d = {k: v for k, v in self.__dict__.items() if k != "history"}
        d["history"] = [asdict(r) for r in self.history]
        return d

    @classmethod
    def from_state(cls, d: Mapping[str, Any]) -> RunProgress:
        values = {k: d[k] for k in cls.__dataclass_fields__ if k != "history"}
        return cls(history=[EpochRecord(**r) for r in d["history"]], **values)


def save_state(path: Path, state: dict[str, Any]) -> None:
    """Write ``state`` to ``path`` atomically (a crash leaves the previous state)."""
    buffer = io.BytesIO()
    torch.save(state, buffer)
    atomic_write_bytes(path, buffer.getvalue())


def load_state(path: Path, fingerprint: dict[str, Any]) -> dict[str, Any]:
    """The state in ``path`` (CPU tensors), refused unless made with ``fingerprint``."""
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
        saved = state["fingerprint"]
    except Exception as exc:
        raise ConfigError(f"cannot resume: {path} is unreadable ({type(exc).__name__})") from None
    differing = [k for k in fingerprint if saved.get(k) != fingerprint[k]]
    if differing:
        key = differing[0]
        raise ConfigError(
            f"cannot resume from {path}: it was trained with {key}={saved.get(key)!r}, "
            f"this run asks for {fingerprint[key]!r}"
        )
    return state


def resume_state(
    settings: TrainConfig, state_path: Path, fingerprint: dict[str, Any], ranks: Ranks
) -> dict[str, Any] | None:
    """The saved state a resumed run continues (read by rank 0, sent to every rank), or None
    when not resuming or when there is none yet."""
    if not settings.resume:
        return None
    return distributed.from_main(
        ranks, lambda: load_state(state_path, fingerprint) if state_path.is_file() else None
    )
