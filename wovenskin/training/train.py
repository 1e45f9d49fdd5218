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
  it improves, and exported to ONNX, with its validation metrics, at the end.

:func:`evaluate` scores a torch model or an
:class:`~wovenskin.recognition.onnx_runtime.OnnxRecognizer` on windows;
:func:`classification_metrics` (from :mod:`~wovenskin.training.metrics`, torch-free)
computes accuracy, macro-F1, per-class precision, recall and F1 and the confusion matrix.
"""

from __future__ import annotations

import hashlib
import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import torch
from torch import nn

from wovenskin.training.checkpoint import (
    CheckpointMeta,
    atomic_write_bytes,
    save_checkpoint,
)
from wovenskin.training.metrics import (  # ClassScore is re-exported for users of train
    ClassificationMetrics,
    ClassScore,  # noqa: F401
    classification_metrics,
)
from wovenskin.training.models import build_model, resolve_hparams

STATE_FILE = "training_state.pt"
EVAL_BATCH = 512
GAIN_RANGE = (0.25, 4.0)
"""Range of the random per-window gain of augmentation (log-uniform).  The models divide
each window by its peak, so the gain only matters near the peak floor and against the
added noise: a 16x range teaches both a faint touch on a dull skin and a strong one."""
HISTORY_FILE = "history.json"
CURVE_FILE = "learning_curve.png"
NOISE_FRACTION = 0.01
"""Standard deviation of augmentation noise, as a fraction of the input scale."""
SCALE_SAMPLE = 4096
"""Training windows sampled to fit the input scale."""
MIN_LR_FRACTION = 0.02
"""The cosine schedule decays the learning rate to this fraction of its peak."""


# ------------------------------------------------------------------------ evaluation


class Recognizer(Protocol):
    """Anything with ``predict_proba`` over windows, e.g. an ``OnnxRecognizer``."""

    class_names: Sequence[str]

    def predict_proba(self, windows: np.ndarray) -> np.ndarray: ...


def _float32_batch(windows: Any, idx: np.ndarray) -> np.ndarray:
    batch = np.asarray(windows[idx], dtype=np.float32)
    if not np.isfinite(batch).all():
        bad = idx[~np.isfinite(batch.reshape(batch.shape[0], -1)).all(axis=1)]
        raise ValueError(f"window {int(bad[0])} contains NaN or inf values")
    return batch


def _chunks(idx: np.ndarray, size: int) -> list[np.ndarray]:
    return [idx[i : i + size] for i in range(0, idx.size, size)]


def predict_scores(
    model_or_recognizer: nn.Module | Recognizer,
    windows: Any,
    indices: np.ndarray | None = None,
    batch_size: int = EVAL_BATCH,
) -> np.ndarray:
    """``(n, K)`` scores of ``windows[indices]`` (all windows by default), in batches.

    Scores are logits for a torch model and probabilities for a recogniser; both rank
    classes the same way.
    """
    idx = np.arange(len(windows)) if indices is None else np.asarray(indices, dtype=np.int64)
    parts: list[np.ndarray] = []
    if isinstance(model_or_recognizer, nn.Module):
        model = model_or_recognizer
        was_training = model.training
        model.eval()
        try:
            with torch.inference_mode():
                for chunk in _chunks(idx, batch_size):
                    parts.append(model(torch.from_numpy(_float32_batch(windows, chunk))).numpy())
        finally:
            model.train(was_training)
        n_classes = int(model.n_classes)
    else:
        for chunk in _chunks(idx, batch_size):
            parts.append(model_or_recognizer.predict_proba(_float32_batch(windows, chunk)))
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


# --------------------------------------------------------------------------- training


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


def _as_mapping(meta: Mapping[str, Any] | Any) -> dict[str, Any]:
    if isinstance(meta, Mapping):
        return dict(meta)
    to_dict = getattr(meta, "to_dict", None)
    if callable(to_dict):
        return dict(to_dict())
    raise TypeError(f"data set meta must be a mapping or have to_dict(), got {type(meta)}")


def _jsonable(value: Any) -> Any:
    """``value`` made JSON-serialisable (numpy scalars and arrays to Python, others to str)."""
    if isinstance(value, Mapping):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return _jsonable(value.tolist()) if value.size <= 1000 else f"array{value.shape}"
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, Path):
        return str(value)
    if value is None or isinstance(value, bool | int | str):
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else str(value)
    if hasattr(value, "to_dict"):
        return _jsonable(value.to_dict())
    return str(value)


def _first(mapping: Mapping[str, Any], *keys: str) -> Any:
    for key in keys:
        if mapping.get(key) is not None:
            return mapping[key]
    return None


def checkpoint_meta_for(
    model_name: str,
    hparams: Mapping[str, Any],
    class_names: Sequence[str],
    input_shape: tuple[int, int, int],
    data_meta: Mapping[str, Any] | Any,
    training: Mapping[str, Any] | None = None,
) -> CheckpointMeta:
    """The :class:`CheckpointMeta` of a model trained on a data set described by ``data_meta``.

    ``data_meta`` must give ``sample_rate_hz`` and ``conditioning`` (the settings the frames
    were conditioned with). Windows of labelled captures (``conditioning`` None) record
    ``{"capture_normalisation": data_meta["normalisation"]}`` instead, or ``{}`` when there
    is none: consumers pass the same dict to ``check_input``. Grid rows/cols, window length
    and class names are cross-checked against the arrays when present (top level or under ``grid`` /
    ``layout``), pitches are taken from there. Everything else becomes the training-data
    description, with ``training`` (the training settings) added.
    """
    window, rows, cols = input_shape
    meta = _as_mapping(data_meta)
    grid = _as_mapping(_first(meta, "grid", "layout") or meta)
    rate = _first(meta, "sample_rate_hz", "rate_hz")
    if rate is None:
        raise ValueError("data set meta lacks sample_rate_hz")
    if "conditioning" not in meta:
        raise ValueError("data set meta lacks conditioning (the settings its frames went through)")
    meta_rows, meta_cols = grid.get("rows"), grid.get("cols")
    grid_given = meta_rows is not None and meta_cols is not None
    if grid_given and (int(meta_rows), int(meta_cols)) != (rows, cols):
        raise ValueError(
            f"data set meta says {meta_rows}x{meta_cols} frames, windows are {rows}x{cols}"
        )
    meta_window = _first(meta, "window", "window_frames", "window_length")
    if meta_window is not None and int(meta_window) != window:
        raise ValueError(f"data set meta says {meta_window}-frame windows, windows hold {window}")
    meta_classes = meta.get("class_names")
    if meta_classes is not None and [str(c) for c in meta_classes] != list(class_names):
        raise ValueError("data set meta lists other class names than the ones given")
    conditioning = meta["conditioning"]
    if conditioning is not None:
        conditioning = _jsonable(_as_mapping(conditioning))
    elif meta.get("normalisation") is not None:  # labelled captures: normalised, not conditioned
        conditioning = {"capture_normalisation": _jsonable(_as_mapping(meta["normalisation"]))}
    else:
        conditioning = {}
    description = {k: v for k, v in meta.items() if k not in ("conditioning", "class_names")}
    if training is not None:
        description["training"] = dict(training)
    row_pitch = grid.get("row_pitch_mm")
    col_pitch = grid.get("col_pitch_mm")
    return CheckpointMeta(
        model_name=model_name,
        hparams=_jsonable(dict(hparams)),
        class_names=tuple(class_names),
        rows=rows,
        cols=cols,
        window=window,
        sample_rate_hz=float(rate),
        conditioning=conditioning,
        row_pitch_mm=None if row_pitch is None else float(row_pitch),
        col_pitch_mm=None if col_pitch is None else float(col_pitch),
        training_data=_jsonable(description),
    )


def fit_input_scale(windows: Any, train_idx: np.ndarray, seed: int) -> float:
    """Median over (up to :data:`SCALE_SAMPLE`) training windows of each window's peak |value|."""
    rng = np.random.default_rng([seed, 7919])
    sample = train_idx
    if sample.size > SCALE_SAMPLE:
        sample = rng.choice(train_idx, SCALE_SAMPLE, replace=False)
    peaks = [
        np.abs(_float32_batch(windows, np.sort(chunk))).reshape(chunk.size, -1).max(axis=1)
        for chunk in _chunks(sample, EVAL_BATCH)
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
        raise ValueError(f"windows must be an (N, W, R, C) array, got shape {shape}")
    if labels.shape != (shape[0],):
        raise ValueError(f"{shape[0]} windows but labels of shape {labels.shape}")
    if labels.dtype.kind not in "iu":
        raise ValueError(f"labels must be integers, got dtype {labels.dtype}")
    k = len(class_names)
    if k < 2:
        raise ValueError(f"need at least 2 classes, got {k}")
    if labels.size and (labels.min() < 0 or labels.max() >= k):
        raise ValueError(f"labels must lie in [0, {k}) for {k} class names")
    for name, idx in (("train_idx", train_idx), ("val_idx", val_idx)):
        if idx.size == 0:
            raise ValueError(f"{name} is empty")
        if idx.min() < 0 or idx.max() >= shape[0]:
            raise ValueError(f"{name} holds indices outside [0, {shape[0]})")
    overlap = np.intersect1d(train_idx, val_idx)
    if overlap.size:
        raise ValueError(f"{overlap.size} windows are in both train_idx and val_idx")


@dataclass(frozen=True)
class TrainSettings:
    """Optimisation settings of a run (recorded in the checkpoint, checked on resume)."""

    epochs: int = 30
    batch_size: int = 128
    lr: float = 2e-3
    seed: int = 0
    patience: int = 5
    weight_decay: float = 0.01
    label_smoothing: float = 0.05
    augment: bool = True
    warmup_epochs: float = 1.0

    def __post_init__(self) -> None:
        if self.epochs < 1 or self.batch_size < 1 or self.patience < 1:
            raise ValueError("epochs, batch_size and patience must be at least 1")
        if not (self.lr > 0 and self.weight_decay >= 0 and self.warmup_epochs >= 0):
            raise ValueError("lr must be positive, weight_decay and warmup_epochs not negative")
        if not 0 <= self.label_smoothing < 1:
            raise ValueError(f"label_smoothing must lie in [0, 1), got {self.label_smoothing}")


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


@dataclass
class _Progress:
    """Where a run stands: the epochs done, the best one so far and why it stopped."""

    epoch: int = 0
    history: list[EpochRecord] = field(default_factory=list)
    best_epoch: int = 0
    best_val_accuracy: float = -1.0
    best_val_loss: float = math.inf
    best_state: dict[str, torch.Tensor] | None = None
    epochs_since_best: int = 0
    stop_reason: str | None = None

    def add(self, record: EpochRecord, model: nn.Module, settings: TrainSettings) -> bool:
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
    def from_state(cls, d: Mapping[str, Any]) -> _Progress:
        values = {k: d[k] for k in cls.__dataclass_fields__ if k != "history"}
        return cls(history=[EpochRecord(**r) for r in d["history"]], **values)


def _save_state(path: Path, state: dict[str, Any]) -> None:
    import io

    buffer = io.BytesIO()
    torch.save(state, buffer)
    atomic_write_bytes(path, buffer.getvalue())


def _load_state(path: Path, fingerprint: dict[str, Any]) -> dict[str, Any]:
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
        saved = state["fingerprint"]
    except Exception as exc:
        raise ValueError(f"cannot resume: {path} is unreadable ({type(exc).__name__})") from None
    differing = [k for k in fingerprint if saved.get(k) != fingerprint[k]]
    if differing:
        key = differing[0]
        raise ValueError(
            f"cannot resume from {path}: it was trained with {key}={saved.get(key)!r}, "
            f"this run asks for {fingerprint[key]!r}"
        )
    return state


def train_model(
    model_name: str,
    windows: Any,
    labels: np.ndarray,
    class_names: Sequence[str],
    train_idx: np.ndarray,
    val_idx: np.ndarray,
    out_dir: str | Path,
    meta: Mapping[str, Any] | Any,
    epochs: int = 30,
    batch_size: int = 128,
    lr: float = 2e-3,
    seed: int = 0,
    patience: int = 5,
    progress: Callable[[TrainEvent], None] | None = None,
    resume: bool = False,
    time_budget_s: float | None = None,
    *,
    hparams: Mapping[str, Any] | None = None,
    weight_decay: float = 0.01,
    label_smoothing: float = 0.05,
    augment: bool = True,
    warmup_epochs: float = 1.0,
    threads: int = 1,
) -> TrainResult:
    """Train ``model_name`` on ``windows[train_idx]``, select on ``windows[val_idx]``.

    ``out_dir`` receives the best checkpoint (``model.pt``, ``meta.json``, at the end
    ``model.onnx``) and ``training_state.pt``. ``resume`` continues from that state when it
    exists and was made with the same settings (else ``ValueError``); a finished run is
    only re-exported. ``time_budget_s`` stops before an epoch that would likely overrun
    it (at least one epoch always runs); such a run can be resumed. ``progress`` gets a
    :class:`TrainEvent` after every batch and every epoch; an exception it raises stops
    training with the last completed epoch saved.
    """
    started = time.monotonic()
    settings = TrainSettings(
        epochs, batch_size, lr, seed, patience, weight_decay, label_smoothing, augment,
        warmup_epochs,
    )  # fmt: skip
    labels = np.asarray(labels)
    train_idx = np.asarray(train_idx, dtype=np.int64).ravel()
    val_idx = np.asarray(val_idx, dtype=np.int64).ravel()
    class_names = [str(c) for c in class_names]
    _check_inputs(windows, labels, class_names, train_idx, val_idx)
    _, window, rows, cols = (int(s) for s in windows.shape)
    full_hparams = resolve_hparams(model_name, hparams)
    fingerprint = {
        "model_name": model_name,
        "hparams": _jsonable(full_hparams),
        "class_names": class_names,
        "input_shape": [window, rows, cols],
        "n_windows": int(windows.shape[0]),
        "train_idx": _digest(train_idx),
        "val_idx": _digest(val_idx),
        **asdict(settings),
    }
    training = {**asdict(settings), "n_train": int(train_idx.size), "n_val": int(val_idx.size)}
    checkpoint_meta = checkpoint_meta_for(
        model_name, full_hparams, class_names, (window, rows, cols), meta, training
    )
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    state_path = out_dir / STATE_FILE
    steps_per_epoch = math.ceil(train_idx.size / batch_size)
    total_steps = epochs * steps_per_epoch
    warmup_steps = max(1, min(total_steps // 2, round(warmup_epochs * steps_per_epoch)))

    with _TorchGlobals(threads):
        torch.manual_seed(seed)
        model = build_model(model_name, rows, cols, window, len(class_names), **full_hparams)
        optimizer = torch.optim.AdamW(model.parameters(), lr=lr, weight_decay=weight_decay)
        scheduler = torch.optim.lr_scheduler.LambdaLR(
            optimizer, lambda step: _lr_factor(step, warmup_steps, total_steps)
        )
        run, resumed_from = _Progress(), None
        if resume and state_path.is_file():
            state = _load_state(state_path, fingerprint)
            model.load_state_dict(state["model"])
            optimizer.load_state_dict(state["optimizer"])
            scheduler.load_state_dict(state["scheduler"])
            run = _Progress.from_state(state["progress"])
            resumed_from = run.epoch + 1
        else:
            model.set_input_scale(fit_input_scale(windows, train_idx, seed))

        loss_fn = nn.CrossEntropyLoss(label_smoothing=label_smoothing)
        last_epoch_s = 0.0
        while run.stop_reason is None:
            elapsed = time.monotonic() - started
            if (
                time_budget_s is not None
                and last_epoch_s
                and elapsed + last_epoch_s > time_budget_s
            ):
                break
            epoch = run.epoch + 1
            epoch_started = time.monotonic()
            train_loss, train_acc = _train_epoch(
                model, optimizer, scheduler, loss_fn, windows, labels, train_idx, settings,
                epoch, progress,
            )  # fmt: skip
            val_loss, val_metrics = _validate(model, windows, labels, val_idx, class_names)
            last_epoch_s = time.monotonic() - epoch_started
            record = EpochRecord(
                epoch, train_loss, train_acc, val_loss, val_metrics.accuracy,
                val_metrics.macro_f1, float(optimizer.param_groups[0]["lr"]), last_epoch_s,
            )  # fmt: skip
            if run.add(record, model, settings):
                save_checkpoint(out_dir, model, checkpoint_meta, export_onnx=False)
            _save_state(
                state_path,
                {
                    "fingerprint": fingerprint,
                    "model": model.state_dict(),
                    "optimizer": optimizer.state_dict(),
                    "scheduler": scheduler.state_dict(),
                    "progress": run.to_state(),
                },
            )
            write_history(out_dir, run.history, model_name)
            if progress is not None:
                batches = steps_per_epoch
                progress(TrainEvent("epoch", epoch, epochs, batches, batches, train_loss, record))

        if run.best_state is None:
            raise ValueError(f"{state_path} holds no trained epoch")
        model.load_state_dict(run.best_state)
        stop_reason = run.stop_reason or "time_budget"
        validation = evaluate(model, windows, labels, class_names, indices=val_idx)
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
        final_meta = save_checkpoint(out_dir, model, final_meta, export_onnx=True)

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


def write_history(
    out_dir: str | Path, history: Sequence[EpochRecord], title: str, extra: Mapping | None = None
) -> None:
    """``history.json`` and ``learning_curve.png`` (loss and accuracy per epoch) in ``out_dir``.

    ``extra`` (JSON-friendly) is stored beside the epochs, e.g. stream figures of the model.
    """
    import json

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
    atomic_write_bytes(path, (json.dumps(document, indent=1) + "\n").encode())
    if not history:
        return
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib import pyplot as plt

    epochs = [r.epoch for r in history]
    fig, (ax_loss, ax_acc) = plt.subplots(1, 2, figsize=(9, 3.4))
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
    from matplotlib.ticker import MaxNLocator

    for axis in (ax_loss, ax_acc):
        axis.xaxis.set_major_locator(MaxNLocator(integer=True))
    fig.suptitle(f"{title}: learning curve")
    fig.tight_layout()
    import io

    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=100)
    plt.close(fig)
    atomic_write_bytes(out_dir / CURVE_FILE, buffer.getvalue())


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
    settings: TrainSettings,
    epoch: int,
    progress: Callable[[TrainEvent], None] | None,
) -> tuple[float, float]:
    """One pass over the training windows; returns mean loss and accuracy.

    Batch order, augmentation and dropout derive from ``(seed, epoch)`` alone, so an epoch
    replays identically after a resume.
    """
    rng = np.random.default_rng([settings.seed, epoch])
    torch.manual_seed(settings.seed * 1_000_003 + epoch)
    batches = _chunks(rng.permutation(train_idx), settings.batch_size)
    scale = float(model.input_scale)
    model.train()
    total_loss, correct = 0.0, 0
    for b, chunk in enumerate(batches, start=1):
        idx = np.sort(chunk)  # sequential reads from a memory map
        x = _float32_batch(windows, idx)
        if settings.augment:
            x = _augmented(x, rng, scale)
        y = torch.from_numpy(labels[idx].astype(np.int64))
        logits = model(torch.from_numpy(x))
        loss = loss_fn(logits, y)
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        nn.utils.clip_grad_norm_(model.parameters(), 1.0)
        optimizer.step()
        scheduler.step()
        batch_loss = float(loss.detach())
        total_loss += batch_loss * idx.size
        correct += int((logits.detach().argmax(dim=1) == y).sum())
        if progress is not None:
            progress(TrainEvent("batch", epoch, settings.epochs, b, len(batches), batch_loss))
    return total_loss / train_idx.size, correct / train_idx.size


def _validate(
    model: nn.Module,
    windows: Any,
    labels: np.ndarray,
    val_idx: np.ndarray,
    class_names: Sequence[str],
) -> tuple[float, ClassificationMetrics]:
    """Mean cross-entropy (no smoothing) and metrics on the validation windows."""
    logits = predict_scores(model, windows, val_idx)
    y = labels[val_idx].astype(np.int64)
    loss = float(nn.functional.cross_entropy(torch.from_numpy(logits), torch.from_numpy(y)))
    return loss, classification_metrics(y, logits.argmax(axis=1), class_names)
