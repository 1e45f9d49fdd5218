"""Training and evaluation of the gesture classifiers (PyTorch, CPU-friendly, resumable).

:func:`train_model` trains a registry model (:mod:`~wovenskin.training.models`) on a
window data set given as plain arrays -- ``windows`` ``(N, W, R, C)`` (float16 or float32,
memory-mapped is fine: batches are read and converted one at a time), ``labels`` ``(N,)``
int, class names, and index arrays of the training and validation windows -- plus the data
set's meta mapping (sample rate, conditioning settings, grid; everything else is kept as
the description of the training data). It uses

- AdamW with a linear warm-up and a cosine decay of the learning rate, optional label
  smoothing, gradient clipping;
- light augmentation of training windows: a random gain per window (skins and people
  differ in strength) and a little Gaussian noise;
- an input scale fitted on the training windows (the median window peak), stored in the
  model so the network sees values of order one;
- early stopping on validation accuracy (ties broken by validation loss) with patience;
- deterministic seeds: the model's initialisation, the batch order and augmentation of
  every epoch and its dropout all derive from ``(seed, epoch)``, with
  ``torch.use_deterministic_algorithms(True)`` and a fixed thread count;
- after every epoch, ``history.json`` (per-epoch loss, accuracy, macro-F1, learning rate
  and time, plus any extra figures a caller adds, e.g. stream F1) and
  ``learning_curve.png`` in the output directory, and ``training_state.pt`` (model, optimiser,
  schedule, best weights, history), so ``resume=True`` continues an interrupted run and
  ends with the same weights as an uninterrupted one;
- the best model saved as a checkpoint (:mod:`~wovenskin.training.checkpoint`) whenever
  it improves, and exported to ONNX, with its validation metrics, at the end;
- the hardware at hand: the CPU or a CUDA GPU with mixed precision
  (:mod:`~wovenskin.training.device`; checkpoints are always saved as CPU weights), and
  several processes under torchrun with DistributedDataParallel
  (:mod:`~wovenskin.training.distributed`: the training windows sharded per rank, rank 0
  writing every file).

Its settings are one :class:`~wovenskin.training.config.TrainConfig`.  Scoring lives in
:mod:`~.scoring`, the checkpoint description in :mod:`~.run_meta`, the history files in
:mod:`~.history`, the resume state in :mod:`~.train_state`.
"""

from __future__ import annotations

import hashlib
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import nn

from wovenskin.errors import ConfigError, DataError
from wovenskin.io import to_jsonable
from wovenskin.recognition.checkpoint_meta import CheckpointMeta
from wovenskin.training import distributed
from wovenskin.training.checkpoint import load_checkpoint, save_checkpoint
from wovenskin.training.config import TrainConfig
from wovenskin.training.device import Precision, cpu_copy, resolve_device
from wovenskin.training.distributed import Ranks
from wovenskin.training.history import EpochRecord, TrainEvent, write_history
from wovenskin.training.metrics import ClassificationMetrics, classification_metrics
from wovenskin.training.models import build_model, resolve_hparams
from wovenskin.training.run_meta import checkpoint_meta_for
from wovenskin.training.scoring import EVAL_BATCH, chunks, float32_batch, predict_scores
from wovenskin.training.train_state import STATE_FILE, RunProgress, resume_state, save_state

GAIN_RANGE = (0.25, 4.0)
"""Range of the random per-window gain of augmentation (log-uniform).  The models divide
each window by its peak, so the gain only matters near the peak floor and against the
added noise: a 16x range teaches both a faint touch on a dull skin and a strong one."""
NOISE_FRACTION = 0.01
"""Standard deviation of augmentation noise, as a fraction of the input scale."""
SCALE_SAMPLE = 4096
"""Training windows sampled to fit the input scale."""
MIN_LR_FRACTION = 0.02
"""The cosine schedule decays the learning rate to this fraction of its peak."""
RANK_SEED_STRIDE = 7919
"""Dropout seeds of ranks differ by this (rank 0 keeps the one-process seed)."""


@dataclass
class TrainResult:
    checkpoint_dir: Path
    model_name: str
    best_epoch: int
    best_val_accuracy: float
    best_val_loss: float
    validation: ClassificationMetrics
    history: list[EpochRecord]
    epochs_run: int
    stop_reason: str  # "completed", "early_stopping" or "time_budget"
    resumed_from_epoch: int | None = None
    meta: CheckpointMeta | None = field(default=None, repr=False)


def fit_input_scale(windows: Any, train_idx: np.ndarray, seed: int) -> float:
    """Median over (up to :data:`SCALE_SAMPLE`) training windows of each window's peak |value|."""
    rng = np.random.default_rng([seed, 7919])
    sample = train_idx
    if sample.size > SCALE_SAMPLE:
        sample = rng.choice(train_idx, SCALE_SAMPLE, replace=False)
    peaks = [
        np.abs(float32_batch(windows, np.sort(chunk))).reshape(chunk.size, -1).max(axis=1)
        for chunk in chunks(sample, EVAL_BATCH)
    ]
    scale = float(np.median(np.concatenate(peaks)))
    return scale if math.isfinite(scale) and scale > 0 else 1.0


def _digest(idx: np.ndarray) -> str:
    return hashlib.sha1(np.ascontiguousarray(idx, dtype=np.int64).tobytes()).hexdigest()[:16]


def _check_inputs(
    windows: Any,
    labels: np.ndarray,
    class_names: Sequence[str],
    train_idx: np.ndarray,
    val_idx: np.ndarray,
) -> None:
    shape = getattr(windows, "shape", None)
    if shape is None or len(shape) != 4:
        raise DataError(f"windows must be an (N, W, R, C) array, got shape {shape}")
    if labels.shape != (shape[0],):
        raise DataError(f"{shape[0]} windows but labels of shape {labels.shape}")
    if labels.dtype.kind not in "iu":
        raise DataError(f"labels must be integers, got dtype {labels.dtype}")
    k = len(class_names)
    if k < 2:
        raise DataError(f"need at least 2 classes, got {k}")
    if labels.size and (labels.min() < 0 or labels.max() >= k):
        raise DataError(f"labels must lie in [0, {k}) for {k} class names")
    for name, idx in (("train_idx", train_idx), ("val_idx", val_idx)):
        if idx.size == 0:
            raise DataError(f"{name} is empty")
        if idx.min() < 0 or idx.max() >= shape[0]:
            raise DataError(f"{name} holds indices outside [0, {shape[0]})")
    overlap = np.intersect1d(train_idx, val_idx)
    if overlap.size:
        raise DataError(f"{overlap.size} windows are in both train_idx and val_idx")


def _lr_factor(step: int, warmup_steps: int, total_steps: int) -> float:
    """Linear warm-up to 1, then cosine decay to :data:`MIN_LR_FRACTION`."""
    if step < warmup_steps:
        return (step + 1) / warmup_steps
    progress = min(1.0, (step - warmup_steps) / max(1, total_steps - warmup_steps))
    return MIN_LR_FRACTION + (1 - MIN_LR_FRACTION) * 0.5 * (1 + math.cos(math.pi * progress))


class _TorchGlobals:
    """Sets torch's thread count and deterministic mode; restores both on exit."""

    def __init__(self, threads: int) -> None:
        self.threads = threads

    def __enter__(self) -> None:
        self._threads = torch.get_num_threads()
        self._deterministic = torch.are_deterministic_algorithms_enabled()
        self._warn_only = torch.is_deterministic_algorithms_warn_only_enabled()
        torch.set_num_threads(self.threads)
        torch.use_deterministic_algorithms(True, warn_only=True)

    def __exit__(self, *exc: object) -> None:
        torch.set_num_threads(self._threads)
        torch.use_deterministic_algorithms(self._deterministic, warn_only=self._warn_only)


def train_model(
    windows: Any,
    labels: np.ndarray,
    class_names: Sequence[str],
    train_idx: np.ndarray,
    val_idx: np.ndarray,
    out_dir: str | Path,
    meta: Mapping[str, Any] | Any,
    config: TrainConfig | None = None,
    progress: Callable[[TrainEvent], None] | None = None,
) -> TrainResult:
    """Train ``config.model`` on ``windows[train_idx]``, select on ``windows[val_idx]``.

    ``config`` (default :class:`TrainConfig`) gives the model, its hyperparameters
    (``None``: the registry's defaults), the optimisation and the run settings; it is
    validated first (:class:`~wovenskin.errors.ConfigError`).  ``out_dir`` receives the
    best checkpoint (``model.pt``, ``meta.json``, at the end ``model.onnx``) and
    ``training_state.pt``. ``config.resume`` continues from that state when it exists and
    was made with the same settings (else ``ConfigError``); a finished run is only
    re-exported. ``config.time_budget_s`` stops before an epoch that would likely overrun
    it (at least one epoch always runs); such a run can be resumed. ``progress`` gets a
    :class:`TrainEvent` after every batch and every epoch; an exception it raises stops
    training with the last completed epoch saved.

    ``config.device`` and ``config.amp`` choose where and in what precision it computes
    (:mod:`~.device`).  Called in every process of an initialised process group (torchrun,
    :func:`~.distributed.session`) it trains one DistributedDataParallel model on shards of
    the training windows (:mod:`~.distributed`); only rank 0 writes files and gets
    ``progress`` events, and every rank returns the same result.
    """
    started = time.monotonic()
    settings = (config or TrainConfig()).checked()
    model_name = settings.model
    labels = np.asarray(labels)
    train_idx = np.asarray(train_idx, dtype=np.int64).ravel()
    val_idx = np.asarray(val_idx, dtype=np.int64).ravel()
    class_names = [str(c) for c in class_names]
    _check_inputs(windows, labels, class_names, train_idx, val_idx)
    _, window, rows, cols = (int(s) for s in windows.shape)
    full_hparams = resolve_hparams(model_name, settings.hparams)
    fingerprint = {
        "model_name": model_name,
        "hparams": to_jsonable(full_hparams),
        "class_names": class_names,
        "input_shape": [window, rows, cols],
        "n_windows": int(windows.shape[0]),
        "train_idx": _digest(train_idx),
        "val_idx": _digest(val_idx),
        **settings.optimisation(),
        "init_from": settings.init_from,
    }
    ranks = distributed.current()
    precision = Precision.of(resolve_device(settings.device, ranks.local_rank), settings.amp)
    progress = progress if ranks.is_main else None
    training = {
        **settings.optimisation(),
        "n_train": int(train_idx.size),
        "n_val": int(val_idx.size),
        **({} if settings.init_from is None else {"init_from": str(settings.init_from)}),
        **_hardware_record(precision, ranks),
    }
    checkpoint_meta = checkpoint_meta_for(
        model_name, full_hparams, class_names, (window, rows, cols), meta, training
    )
    out_dir = Path(out_dir)
    if ranks.is_main:
        out_dir.mkdir(parents=True, exist_ok=True)
    state_path = out_dir / STATE_FILE
    steps_per_epoch = distributed.steps_per_epoch(train_idx.size, settings.batch_size, ranks)
    total_steps = settings.epochs * steps_per_epoch
    warmup_steps = max(1, min(total_steps // 2, round(settings.warmup_epochs * steps_per_epoch)))

    with _TorchGlobals(settings.threads):
        torch.manual_seed(settings.seed)
        net = build_model(model_name, rows, cols, window, len(class_names), **full_hparams)
        net.to(precision.device)
        optimizer = torch.optim.AdamW(
            net.parameters(), lr=settings.lr, weight_decay=settings.weight_decay
        )
        scheduler = torch.optim.lr_scheduler.LambdaLR(
            optimizer, lambda step: _lr_factor(step, warmup_steps, total_steps)
        )
        run, resumed_from = RunProgress(), None
        state = resume_state(settings, state_path, fingerprint, ranks)
        if state is not None:
            net.load_state_dict(state["model"])
            optimizer.load_state_dict(state["optimizer"])
            scheduler.load_state_dict(state["scheduler"])
            if precision.scaler is not None and "scaler" in state:
                precision.scaler.load_state_dict(state["scaler"])
            run = RunProgress.from_state(state["progress"])
            resumed_from = run.epoch + 1
        elif settings.init_from is not None:
            start = settings.init_from
            net.load_state_dict(
                distributed.from_main(
                    ranks,
                    lambda: _initial_weights(start, model_name, full_hparams, class_names, windows),
                )
            )
        else:
            net.set_input_scale(fit_input_scale(windows, train_idx, settings.seed))
        model = distributed.wrap(net, ranks)

        loss_fn = nn.CrossEntropyLoss(label_smoothing=settings.label_smoothing)
        last_epoch_s = 0.0
        while run.stop_reason is None:
            elapsed = time.monotonic() - started
            over_budget = bool(
                settings.time_budget_s is not None
                and last_epoch_s
                and elapsed + last_epoch_s > settings.time_budget_s
            )
            if distributed.main_value(ranks, over_budget):
                break
            epoch = run.epoch + 1
            epoch_started = time.monotonic()
            train_loss, train_acc = _train_epoch(
                model, optimizer, scheduler, loss_fn, windows, labels, train_idx, settings,
                epoch, progress, precision, ranks,
            )  # fmt: skip
            val_loss, val_metrics = _validate(net, windows, labels, val_idx, class_names, ranks)
            last_epoch_s = time.monotonic() - epoch_started
            record = EpochRecord(
                epoch, train_loss, train_acc, val_loss, val_metrics.accuracy,
                val_metrics.macro_f1, float(optimizer.param_groups[0]["lr"]), last_epoch_s,
            )  # fmt: skip
            record = distributed.main_value(ranks, record)  # one record, one stop decision
            if run.add(record, net, settings) and ranks.is_main:
                save_checkpoint(out_dir, cpu_copy(net), checkpoint_meta, export_onnx=False)
            if ranks.is_main:
                save_state(
                    state_path,
                    {
                        "fingerprint": fingerprint,
                        "model": net.state_dict(),
                        "optimizer": optimizer.state_dict(),
                        "scheduler": scheduler.state_dict(),
                        "progress": run.to_state(),
                        **(
                            {}
                            if precision.scaler is None
                            else {"scaler": precision.scaler.state_dict()}
                        ),
                    },
                )
                write_history(out_dir, run.history, model_name)
            if progress is not None:
                batches = steps_per_epoch
                progress(
                    TrainEvent(
                        "epoch", epoch, settings.epochs, batches, batches, train_loss, record
                    )
                )

        if run.best_state is None:
            raise ConfigError(f"{state_path} holds no trained epoch")
        net.load_state_dict(run.best_state)
        stop_reason = run.stop_reason or "time_budget"
        final_logits = _val_logits(net, windows, val_idx, ranks)
        validation = classification_metrics(
            labels[val_idx], final_logits.argmax(axis=1), class_names
        )
        final_meta = checkpoint_meta.with_updates(
            metrics={
                "best_epoch": run.best_epoch,
                "epochs_run": run.epoch,
                "stop_reason": stop_reason,
                "val_accuracy": validation.accuracy,
                "val_macro_f1": validation.macro_f1,
                "val_loss": run.best_val_loss,
                "validation": validation.to_dict(),
            }
        )
        if ranks.is_main:
            final_meta = save_checkpoint(out_dir, cpu_copy(net), final_meta, export_onnx=True)
        distributed.barrier(ranks)  # returned anywhere: the checkpoint is written

    return TrainResult(
        checkpoint_dir=out_dir,
        model_name=model_name,
        best_epoch=run.best_epoch,
        best_val_accuracy=run.best_val_accuracy,
        best_val_loss=run.best_val_loss,
        validation=validation,
        history=run.history,
        epochs_run=run.epoch,
        stop_reason=stop_reason,
        resumed_from_epoch=resumed_from,
        meta=final_meta,
    )


def _hardware_record(precision: Precision, ranks: Ranks) -> dict[str, Any]:
    """What the checkpoint records of the hardware: nothing for one CPU process."""
    if precision.device.type == "cpu" and not ranks.active:
        return {}
    return {
        "hardware": {
            "device": precision.device.type,
            "amp": precision.name,
            "processes": ranks.world_size,
        }
    }


def _initial_weights(
    directory: str | Path,
    model_name: str,
    hparams: Mapping[str, Any],
    class_names: Sequence[str],
    windows: Any,
) -> dict[str, torch.Tensor]:
    """The state dict of the checkpoint in ``directory`` (fine-tuning's start, input scale
    included), refused with a :class:`ConfigError` unless it is the model this run trains."""
    try:
        start, meta = load_checkpoint(directory)
    except (OSError, ValueError) as exc:
        raise ConfigError(f"cannot start from {directory}: {exc}") from exc
    _, window, rows, cols = (int(s) for s in windows.shape)
    theirs = {
        "model": meta.model_name,
        "hyperparameters": to_jsonable(resolve_hparams(meta.model_name, meta.hparams)),
        "classes": list(meta.class_names),
        "window shape": [meta.window, meta.rows, meta.cols],
    }
    ours = {
        "model": model_name,
        "hyperparameters": to_jsonable(dict(hparams)),
        "classes": list(class_names),
        "window shape": [window, rows, cols],
    }
    for what, value in ours.items():
        if theirs[what] != value:
            raise ConfigError(
                f"cannot start from {directory}: its {what} ({theirs[what]}) differ from this "
                f"run's ({value})"
            )
    return start.state_dict()


def _augmented(batch: np.ndarray, rng: np.random.Generator, scale: float) -> np.ndarray:
    """Random gain per window (log-uniform in :data:`GAIN_RANGE`) plus a little noise."""
    low, high = np.log(GAIN_RANGE[0]), np.log(GAIN_RANGE[1])
    gain = np.exp(rng.uniform(low, high, size=batch.shape[0])).astype(np.float32)
    noise = rng.standard_normal(batch.shape, dtype=np.float32) * np.float32(NOISE_FRACTION * scale)
    return batch * gain[:, None, None, None] + noise


def _train_epoch(
    model: nn.Module,
    optimizer: torch.optim.Optimizer,
    scheduler: torch.optim.lr_scheduler.LRScheduler,
    loss_fn: nn.Module,
    windows: Any,
    labels: np.ndarray,
    train_idx: np.ndarray,
    settings: TrainConfig,
    epoch: int,
    progress: Callable[[TrainEvent], None] | None,
    precision: Precision,
    ranks: Ranks,
) -> tuple[float, float]:
    """One pass over the training windows (this rank's share); returns the mean loss and
    accuracy over all ranks.

    Batch order, augmentation and dropout derive from ``(seed, epoch, rank)`` alone, so an
    epoch replays identically after a resume.
    """
    rng = np.random.default_rng([settings.seed, epoch])
    torch.manual_seed(settings.seed * 1_000_003 + epoch + RANK_SEED_STRIDE * ranks.rank)
    order = distributed.shard(rng.permutation(train_idx), ranks)
    if ranks.rank:  # rank 0 goes on with the one-process stream
        rng = np.random.default_rng([settings.seed, epoch, ranks.rank])
    batches = chunks(order, distributed.rank_batch_size(settings.batch_size, ranks))
    scale = float(distributed.unwrap(model).input_scale)
    device = precision.device
    model.train()
    total_loss, correct = 0.0, 0
    for b, chunk in enumerate(batches, start=1):
        idx = np.sort(chunk)  # sequential reads from a memory map
        x = float32_batch(windows, idx)
        if settings.augment:
            x = _augmented(x, rng, scale)
        y = torch.from_numpy(labels[idx].astype(np.int64)).to(device)
        with precision.autocast():
            logits = model(torch.from_numpy(x).to(device))
            loss = loss_fn(logits, y)
        optimizer.zero_grad(set_to_none=True)
        precision.step(loss, optimizer, model.parameters())
        scheduler.step()
        batch_loss = float(loss.detach())
        total_loss += batch_loss * idx.size
        correct += int((logits.detach().argmax(dim=1) == y).sum())
        if progress is not None:
            progress(TrainEvent("batch", epoch, settings.epochs, b, len(batches), batch_loss))
    total_loss, correct, count = distributed.all_sum([total_loss, correct, order.size], ranks)
    return total_loss / count, correct / count


def _validate(
    net: nn.Module,
    windows: Any,
    labels: np.ndarray,
    val_idx: np.ndarray,
    class_names: Sequence[str],
    ranks: Ranks,
) -> tuple[float, ClassificationMetrics]:
    """Mean cross-entropy (no smoothing) and metrics on the validation windows (each rank
    scores its share; every rank gets the metrics of all)."""
    logits = _val_logits(net, windows, val_idx, ranks)
    y = labels[val_idx].astype(np.int64)
    loss = float(nn.functional.cross_entropy(torch.from_numpy(logits), torch.from_numpy(y)))
    return loss, classification_metrics(y, logits.argmax(axis=1), class_names)


def _val_logits(net: nn.Module, windows: Any, val_idx: np.ndarray, ranks: Ranks) -> np.ndarray:
    """Logits of every validation window, each rank scoring its share."""
    scores = predict_scores(net, windows, distributed.share_of(val_idx, ranks))
    return distributed.gather_scores(scores, val_idx.size, ranks)
