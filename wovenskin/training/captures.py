"""Gesture recognition on labelled captures (e.g. HAART): training, per-capture scoring, LOPO.

A labelled-captures file (``docs/formats.md``) holds separate recordings of raw sensor values,
one label each, typically several seconds of one gesture repeated (HAART: 10 s captures at
54 Hz, 10-15 repetitions of one social touch).  This module owns how such files are
turned into models and how those models are scored, one label per capture.

Preprocessing (:class:`CaptureRecipe`, recorded in every checkpoint and replayed by
evaluation):

1. each capture's valid frames are normalised on their own
   (:class:`~wovenskin.training.datasets.CaptureNormalisation`: minus an untouched
   reading, divided by the capture's strong readings), so people who press with very
   different force look alike;
2. every ``frame_step`` consecutive frames are averaged into one model frame (HAART:
   54 Hz to 27 Hz).  The rhythm that separates the classes (stroke ~1 Hz, pat and rub
   2-4 Hz, scratch and tickle up to ~10 Hz) stays below the new Nyquist rate, and the
   per-frame convolutional stem, most of the cost of a model, runs half as often;
3. windows of ``window_frames`` model frames (default 2 s) are classified.

Training (:func:`train_on_captures`) runs :func:`~wovenskin.training.train.train_model`
on a :class:`CaptureWindowArray`: every epoch draws fresh windows, each at a random
position of a training capture and under a random symmetry of the grid (flips, and
transposition on square grids: a person may touch from any side), so six or seven
people's captures go much further than fixed windows would.  Validation uses fixed
windows of held-out captures: given participants (``val_groups``), or by default one
capture of every (participant, class) cell, so early stopping and the choice of the best
epoch never see a training capture.

Evaluation (:func:`evaluate_captures`, :func:`score_captures`) needs ONNX Runtime only:
windows every ``eval_stride`` model frames cover each capture, each window is scored
under every grid symmetry the model was trained with, and the capture's label is the
class with the highest mean log-probability over all of them.  Window accuracy is
reported too (identity symmetry only).

:func:`leave_one_participant_out` trains one model per participant of the file on all the
others and scores that participant's captures: the honest cross-person figure.
"""

from __future__ import annotations

import hashlib
import json
import math
import time
import zlib
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from wovenskin.recording.formats import LabelledCaptures
from wovenskin.training.checkpoint import CheckpointMeta, atomic_write_bytes
from wovenskin.training.datasets import CaptureNormalisation
from wovenskin.training.metrics import ClassificationMetrics, classification_metrics
from wovenskin.training.windows import capture_window_ends, capture_windows

if TYPE_CHECKING:
    from wovenskin.recognition.onnx_runtime import OnnxRecognizer
    from wovenskin.training.train import TrainEvent, TrainResult

CAPTURE_HPARAMS: dict[str, dict[str, Any]] = {
    "tcn": {"stem_channels": 8, "dim": 32, "window_norm": False},
}
"""Hyperparameters of registry models for captures; a model not listed uses its defaults.

The small TCN (8 stem channels, 32-d) trains a HAART fold in about a minute on one core;
wider stems, a 64-d TCN and a small transformer did no better across people.  Captures are
already normalised, so the models' per-window peak normalisation is off: it would blow
up the faint windows between two pats."""
LOPO_FILE = "lopo.json"
SCORE_CHUNK = 64
"""Captures scored per ONNX Runtime batch in :func:`score_captures`."""


# ============================================================================ recipe


@dataclass(frozen=True)
class CaptureRecipe:
    """How a capture model is trained and fed; the defaults are tuned on HAART (LOPO).

    ``frame_step``, ``window_frames`` and ``eval_stride`` count model frames (``frame_step``
    raw frames each).  ``windows_per_capture`` random windows of every training capture make
    one epoch.  ``symmetries``: flip (and on square grids transpose) training windows at
    random, and average the log-probabilities over the same symmetries when scoring.
    """

    model: str = "tcn"
    hparams: Mapping[str, Any] | None = None  # None: CAPTURE_HPARAMS of the model, else {}
    epochs: int = 20
    batch_size: int = 64
    lr: float = 2e-3
    patience: int = 8
    frame_step: int = 2
    window_frames: int = 54
    eval_stride: int = 14
    windows_per_capture: int = 8
    symmetries: bool = True
    normalisation: CaptureNormalisation = field(default_factory=CaptureNormalisation)
    gain: float = 1.25
    noise: float = 0.01
    time_stretch: float = 1.0
    shift: int = 0
    taxel_gain: float = 0.0
    mix: float = 0.0
    label_smoothing: float = 0.05
    weight_decay: float = 0.01

    def __post_init__(self) -> None:
        for name in ("epochs", "batch_size", "patience", "frame_step", "window_frames",
                     "eval_stride", "windows_per_capture"):  # fmt: skip
            value = getattr(self, name)
            if not isinstance(value, int | np.integer) or isinstance(value, bool) or value < 1:
                raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
        if not (math.isfinite(self.lr) and self.lr > 0):
            raise ValueError(f"lr must be positive, got {self.lr}")
        for name in ("gain", "time_stretch"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 1):
                raise ValueError(f"{name} must be a factor >= 1, got {value}")
        if not 0 <= self.mix <= 1:
            raise ValueError(f"mix must lie in [0, 1], got {self.mix}")
        for name in ("noise", "taxel_gain"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ValueError(f"{name} must not be negative, got {value}")
        if not isinstance(self.shift, int | np.integer) or self.shift < 0:
            raise ValueError(f"shift must be an integer >= 0, got {self.shift!r}")
        if not 0 <= self.label_smoothing < 1:
            raise ValueError(f"label_smoothing must lie in [0, 1), got {self.label_smoothing}")
        if not (math.isfinite(self.weight_decay) and self.weight_decay >= 0):
            raise ValueError(f"weight_decay must not be negative, got {self.weight_decay}")

    def resolved_hparams(self) -> dict[str, Any]:
        if self.hparams is not None:
            return dict(self.hparams)
        return dict(CAPTURE_HPARAMS.get(self.model, {}))

    def window_seconds(self, sample_rate_hz: float) -> float:
        return self.window_frames * self.frame_step / sample_rate_hz

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["hparams"] = self.resolved_hparams()
        d["normalisation"] = self.normalisation.to_dict()
        return d


def prepare_capture(
    frames: np.ndarray, normalisation: CaptureNormalisation, frame_step: int
) -> np.ndarray:
    """One capture's valid frames ``(T, R, C)`` as model frames ``(T // frame_step, R, C)``.

    Normalised (``normalisation`` must be resolved), then every ``frame_step`` frames
    averaged; a capture shorter than ``frame_step`` becomes one frame, its mean.
    """
    x = normalisation.apply(frames)
    if frame_step == 1:
        return x
    if len(x) < frame_step:
        return x.mean(axis=0, keepdims=True)
    n = len(x) // frame_step
    return x[: n * frame_step].reshape(n, frame_step, *x.shape[1:]).mean(axis=1)


def prepare_captures(
    captures: LabelledCaptures,
    normalisation: CaptureNormalisation,
    frame_step: int,
    indices: Sequence[int] | np.ndarray | None = None,
) -> dict[int, np.ndarray]:
    """:func:`prepare_capture` of the captures at ``indices`` (all by default), by index."""
    chosen = range(len(captures.lengths)) if indices is None else indices
    return {
        int(i): prepare_capture(
            captures.frames[i, : captures.lengths[i]], normalisation, frame_step
        )
        for i in chosen
    }


def grid_symmetries(windows: np.ndarray, transpose: bool) -> Iterator[np.ndarray]:
    """``windows`` ``(B, W, R, C)`` under the identity, row flip, column flip, both flips,
    and (``transpose``, square grids only) the same four transposed: 4 or 8 views."""
    for t in (False, True) if transpose and windows.shape[2] == windows.shape[3] else (False,):
        base = windows.transpose(0, 1, 3, 2) if t else windows
        for flip_rows in (False, True):
            for flip_cols in (False, True):
                view = base[:, :, ::-1] if flip_rows else base
                yield view[:, :, :, ::-1] if flip_cols else view


def window_ending(frames: np.ndarray, end: int, window_frames: int) -> np.ndarray:
    """The ``window_frames`` frames of ``frames`` ending at ``end`` (inclusive), padded with
    zeros in front when ``end`` is earlier than a full window (as ``capture_windows`` does)."""
    start = end - window_frames + 1
    if start >= 0:
        return frames[start : end + 1]
    pad = np.zeros((-start, *frames.shape[1:]), dtype=frames.dtype)
    return np.concatenate([pad, frames[: end + 1]])


def _capture_digest(frames: np.ndarray) -> str:
    """A short content hash of one capture's valid frames (to spot reused captures)."""
    data = np.ascontiguousarray(frames)
    return hashlib.sha1(str(data.shape).encode() + data.tobytes()).hexdigest()[:12]


# ============================================================================ windows


class CaptureWindowArray:
    """A read-only ``(N, W, R, C)`` float32 window array over prepared captures.

    It is what :func:`~wovenskin.training.train.train_model` reads batches from.
    Indices ``[0, n_random)`` are random windows: slot ``i`` belongs to capture
    ``random_captures[i]``, and every read draws a fresh position in that capture and
    (``symmetries``) a random flip/transposition, from ``SeedSequence(seed, crc32 of
    the indices read)``.  The training loop reads each epoch's batches in an order fixed by
    ``(seed, epoch)``, so the windows are new every epoch yet deterministic for the run,
    and a resumed run reads the same ones.  Indices ``[n_random, N)`` are the ``fixed``
    windows ``(capture, last frame)``, read as they are (validation).  A capture shorter
    than the window is padded with zeros in front (``capture_windows``' convention).
    """

    def __init__(
        self,
        prepared: Mapping[int, np.ndarray],
        window_frames: int,
        random_captures: Sequence[int] | np.ndarray,
        fixed: Sequence[tuple[int, int]],
        seed: int = 0,
        symmetries: bool = True,
        *,
        gain: float = 1.0,
        noise: float = 0.0,
        time_stretch: float = 1.0,
        shift: int = 0,
        taxel_gain: float = 0.0,
        mix: float = 0.0,
        partners: Mapping[int, Sequence[int] | np.ndarray] | None = None,
    ) -> None:
        if not prepared:
            raise ValueError("no captures to cut windows from")
        self.prepared = prepared
        self.window_frames = int(window_frames)
        self.random_captures = np.asarray(random_captures, dtype=np.int64)
        self.fixed = [(int(c), int(e)) for c, e in fixed]
        self.seed = int(seed)
        self.symmetries = symmetries
        self.gain = float(gain)
        self.noise = float(noise)
        self.time_stretch = float(time_stretch)
        self.shift = int(shift)
        self.taxel_gain = float(taxel_gain)
        self.mix = float(mix)
        self.partners = {int(k): np.asarray(v, dtype=np.int64) for k, v in (partners or {}).items()}
        grid = next(iter(prepared.values())).shape[1:]
        self.shape = (self.random_captures.size + len(self.fixed), self.window_frames, *grid)
        self.dtype = np.dtype(np.float32)
        self.ndim = 4

    def __len__(self) -> int:
        return self.shape[0]

    def __getitem__(self, index: Any) -> np.ndarray:
        idx = np.asarray(index, dtype=np.int64)
        scalar = idx.ndim == 0
        idx = np.atleast_1d(idx)
        if idx.size and (idx.min() < -len(self) or idx.max() >= len(self)):
            raise IndexError(f"window index out of range [0, {len(self)})")
        idx = np.where(idx < 0, idx + len(self), idx)
        rng = np.random.default_rng([self.seed, zlib.crc32(idx.tobytes())])
        out = np.empty((idx.size, *self.shape[1:]), dtype=np.float32)
        n_random = self.random_captures.size
        for k, i in enumerate(idx.tolist()):
            if i < n_random:
                capture = int(self.random_captures[i])
                out[k] = self._random_window(self.prepared[capture], rng)
                partners = self.partners.get(capture, ())
                if self.mix > 0 and len(partners) and rng.random() < self.mix:
                    other = self.prepared[int(rng.choice(partners))]
                    share = np.float32(rng.uniform(0.0, 0.5))
                    out[k] = (1 - share) * out[k] + share * self._random_window(other, rng)
            else:
                capture, end = self.fixed[i - n_random]
                out[k] = window_ending(self.prepared[capture], end, self.window_frames)
        return out[0] if scalar else out

    def _random_window(self, x: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        w = self.window_frames
        span = w
        if self.time_stretch > 1:  # play a span of w * rate frames back in w frames
            rate = math.exp(rng.uniform(-1, 1) * math.log(self.time_stretch))
            span = max(2, round(w * rate))
        end = len(x) - 1 if len(x) <= span else int(rng.integers(span - 1, len(x)))
        window = window_ending(x, end, span)
        if span != w:
            window = resample_frames(window, w)
        if self.symmetries:
            if rng.random() < 0.5:
                window = window[:, ::-1]
            if rng.random() < 0.5:
                window = window[:, :, ::-1]
            if window.shape[1] == window.shape[2] and rng.random() < 0.5:
                window = window.transpose(0, 2, 1)
        if self.shift:
            window = shifted(window, *rng.integers(-self.shift, self.shift + 1, size=2))
        if self.taxel_gain > 0:
            window = window * np.exp(
                self.taxel_gain * rng.standard_normal(window.shape[1:], dtype=np.float32)
            )
        if self.gain > 1:
            window = window * np.float32(math.exp(rng.uniform(-1, 1) * math.log(self.gain)))
        if self.noise > 0:
            window = window + np.float32(self.noise) * rng.standard_normal(
                window.shape, dtype=np.float32
            )
        return window


def shifted(frames: np.ndarray, rows: int, cols: int) -> np.ndarray:
    """``frames`` ``(T, R, C)`` moved by ``rows`` and ``cols`` taxels, zeros shifted in."""
    out = np.zeros_like(frames)
    r, c = frames.shape[1:]
    out[:, max(rows, 0) : r + min(rows, 0), max(cols, 0) : c + min(cols, 0)] = frames[
        :, max(-rows, 0) : r + min(-rows, 0), max(-cols, 0) : c + min(-cols, 0)
    ]
    return out


def resample_frames(frames: np.ndarray, n: int) -> np.ndarray:
    """``frames`` ``(T, R, C)`` linearly interpolated to ``n`` frames spanning the same time
    (first and last frames kept)."""
    t = np.linspace(0.0, len(frames) - 1, n)
    lo = np.minimum(np.floor(t).astype(np.int64), len(frames) - 1)
    hi = np.minimum(lo + 1, len(frames) - 1)
    frac = (t - lo).astype(np.float32)[:, None, None]
    return frames[lo] * (1 - frac) + frames[hi] * frac


# ============================================================================ training


def _read(path: str | Path) -> LabelledCaptures:
    """Read a labelled-captures file; every problem is a one-line ``ValueError``."""
    from wovenskin.recording.files import read_captures

    if not Path(path).is_file():
        raise FileNotFoundError(f"{path}: no such captures file")
    return read_captures(path, "training or scoring on captures")


def internal_validation(
    labels: np.ndarray, groups: np.ndarray, candidates: np.ndarray, seed: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """``(train, val)`` capture indices from ``candidates``: one random capture of every
    (group, class) cell that has at least 3 captures goes to validation.

    Validation then holds every person and class in proportion (1 in 12 on HAART) and
    training keeps the rest.  Tiny files whose cells all have fewer than 3 captures give
    one capture of every class that has at least 2.  ``ValueError`` if none qualifies.
    """
    candidates = np.sort(np.asarray(candidates, dtype=np.int64))
    rng = np.random.default_rng([seed, 104729])
    val: list[int] = []
    cells = sorted({(str(groups[i]), int(labels[i])) for i in candidates})
    for group, label in cells:
        members = candidates[(groups[candidates] == group) & (labels[candidates] == label)]
        if members.size >= 3:
            val.append(int(rng.choice(members)))
    if not val:
        for label in np.unique(labels[candidates]).tolist():
            members = candidates[labels[candidates] == label]
            if members.size >= 2:
                val.append(int(rng.choice(members)))
    if not val:
        raise ValueError("too few captures to hold any out for validation (need 2 of a class)")
    val_ids = np.array(sorted(val), dtype=np.int64)
    return np.setdiff1d(candidates, val_ids), val_ids


def subset(captures: LabelledCaptures, ids: np.ndarray) -> LabelledCaptures:
    """The captures at ``ids`` (their frames copied), with the file's class names and rate."""
    return replace(
        captures,
        frames=captures.frames[ids],
        lengths=captures.lengths[ids],
        labels=captures.labels[ids],
        groups=captures.groups[ids],
        metadata={},
    )


def _split_by_groups(
    captures: LabelledCaptures, candidates: np.ndarray, val_groups: Sequence[str]
) -> tuple[np.ndarray, np.ndarray]:
    names = sorted(set(str(g) for g in captures.groups[candidates]))
    unknown = sorted(set(val_groups) - set(names))
    if unknown:
        raise ValueError(
            f"validation group(s) {', '.join(unknown)} not in the file (groups: {', '.join(names)})"
        )
    is_val = np.isin(captures.groups[candidates].astype(str), list(val_groups))
    if is_val.all():
        raise ValueError("every capture would be validation; leave some groups for training")
    return candidates[~is_val], candidates[is_val]


def _fixed_windows(
    prepared: Mapping[int, np.ndarray], ids: np.ndarray, recipe: CaptureRecipe
) -> list[tuple[int, int]]:
    return [
        (int(i), int(end))
        for i in ids.tolist()
        for end in capture_window_ends(
            len(prepared[int(i)]), recipe.window_frames, recipe.eval_stride
        ).tolist()
    ]


def _mix_partners(captures: LabelledCaptures, ids: np.ndarray) -> dict[int, np.ndarray]:
    """For every capture of ``ids``: the captures of ``ids`` with its label by other people
    (all others with its label when one person gave them all)."""
    labels, groups = captures.labels[ids], captures.groups[ids].astype(str)
    out = {}
    for i, label, group in zip(ids.tolist(), labels.tolist(), groups.tolist(), strict=True):
        same = ids[(labels == label) & (ids != i)]
        others = same[groups[(labels == label) & (ids != i)] != group]
        out[int(i)] = others if others.size else same
    return out


def _train_captures(
    captures: LabelledCaptures,
    source: str,
    train_ids: np.ndarray,
    val_ids: np.ndarray,
    out_dir: str | Path,
    recipe: CaptureRecipe,
    *,
    seed: int,
    threads: int,
    progress: Callable[[TrainEvent], None] | None,
    resume: bool,
    validation: str,
) -> TrainResult:
    """Train ``recipe`` on captures ``train_ids``, validating on ``val_ids``; the core of
    :func:`train_on_captures` and every LOPO fold.  The normalisation's reference scale
    comes from the training captures alone."""
    from wovenskin.training.train import train_model

    norm = recipe.normalisation.resolved(subset(captures, train_ids))
    prepared = prepare_captures(captures, norm, recipe.frame_step, np.union1d(train_ids, val_ids))
    fixed = _fixed_windows(prepared, val_ids, recipe)
    random_captures = np.repeat(train_ids, recipe.windows_per_capture)
    windows = CaptureWindowArray(
        prepared, recipe.window_frames, random_captures, fixed, seed, recipe.symmetries,
        gain=recipe.gain, noise=recipe.noise, time_stretch=recipe.time_stretch,
        shift=recipe.shift, taxel_gain=recipe.taxel_gain, mix=recipe.mix,
        partners=_mix_partners(captures, train_ids) if recipe.mix > 0 else None,
    )  # fmt: skip
    labels = np.concatenate(
        [captures.labels[random_captures], captures.labels[[c for c, _ in fixed]]]
    ).astype(np.int64)
    n_random = random_captures.size
    _, rows, cols = captures.frames.shape[1:]
    groups = captures.groups.astype(str)
    data_meta = {
        "kind": "captures",
        "class_names": list(captures.class_names),
        "rows": int(rows),
        "cols": int(cols),
        "sample_rate_hz": float(captures.sample_rate_hz),
        "window_frames": recipe.window_frames,
        "conditioning": {"capture_normalisation": norm.to_dict(), "frame_step": recipe.frame_step},
        "captures": {
            "source": source,
            "recipe": recipe.to_dict(),
            "window_seconds": recipe.window_seconds(captures.sample_rate_hz),
            "validation": validation,
            "train_groups": sorted(set(groups[train_ids].tolist())),
            "val_groups": sorted(set(groups[val_ids].tolist())),
            "n_train_captures": int(train_ids.size),
            "n_val_captures": int(val_ids.size),
            "train_capture_digests": [
                _capture_digest(captures.frames[i, : captures.lengths[i]]) for i in train_ids
            ],
        },
    }
    return train_model(
        recipe.model,
        windows,
        labels,
        list(captures.class_names),
        np.arange(n_random),
        np.arange(n_random, len(windows)),
        out_dir,
        data_meta,
        epochs=recipe.epochs,
        batch_size=recipe.batch_size,
        lr=recipe.lr,
        seed=seed,
        patience=recipe.patience,
        progress=progress,
        resume=resume,
        hparams=recipe.resolved_hparams(),
        weight_decay=recipe.weight_decay,
        label_smoothing=recipe.label_smoothing,
        augment=False,  # the window array draws gain and noise itself (recipe.gain, .noise)
        threads=threads,
    )


def _recipe_for(recipe: CaptureRecipe | None, model: str | None, epochs: int | None):
    recipe = recipe or CaptureRecipe()
    if model is not None and model != recipe.model:
        recipe = replace(recipe, model=model, hparams=None)
    if epochs is not None:
        recipe = replace(recipe, epochs=epochs)
    return recipe


def train_on_captures(
    path: str | Path,
    out_dir: str | Path,
    *,
    model: str | None = None,
    epochs: int | None = None,
    seed: int = 0,
    threads: int = 1,
    progress: Callable[[TrainEvent], None] | None = None,
    resume: bool = False,
    val_groups: Sequence[str] | None = None,
    recipe: CaptureRecipe | None = None,
) -> TrainResult:
    """Train a recogniser on a labelled-captures file; the checkpoint goes to ``out_dir``.

    ``val_groups`` (participants of the file's ``groups``) are held out for validation;
    without them one capture of every (participant, class) cell is
    (:func:`internal_validation`).  Validation picks the best epoch and stops training early
    (``recipe.patience``).  ``model`` and ``epochs`` override ``recipe`` (default:
    :class:`CaptureRecipe`); a model other than the recipe's gets
    :data:`CAPTURE_HPARAMS` or its registry defaults.  The checkpoint's ``meta.json``
    records the class names, the capture rate, the window, the normalisation and frame
    step (its ``conditioning``) and the recipe, which is all :func:`evaluate_captures`
    needs.  ``progress`` gets the :class:`~wovenskin.training.train.TrainEvent` of
    every batch and epoch.  Needs torch.
    """
    recipe = _recipe_for(recipe, model, epochs)
    captures = _read(path)
    everything = np.arange(len(captures.labels))
    if val_groups:
        train_ids, val_ids = _split_by_groups(captures, everything, list(val_groups))
        validation = f"held-out groups {', '.join(sorted(val_groups))}"
    else:
        train_ids, val_ids = internal_validation(captures.labels, captures.groups, everything, seed)
        validation = "one capture per (group, class)"
    return _train_captures(
        captures, str(path), train_ids, val_ids, out_dir, recipe, seed=seed, threads=threads,
        progress=progress, resume=resume, validation=validation,
    )  # fmt: skip


# ============================================================================ evaluation


@dataclass(frozen=True)
class CaptureModelSpec:
    """What scoring captures with a checkpoint needs, read from its ``meta.json``."""

    normalisation: CaptureNormalisation
    frame_step: int
    window_frames: int
    eval_stride: int
    symmetries: bool
    train_digests: frozenset[str]

    @classmethod
    def from_meta(cls, meta: CheckpointMeta, where: str) -> CaptureModelSpec:
        conditioning = meta.conditioning
        stored = conditioning.get("capture_normalisation")
        if not isinstance(stored, Mapping):
            raise ValueError(
                f"model {where} was not trained on labelled captures "
                "(train one with `wovenskin train --captures FILE`)"
            )
        info = meta.training_data.get("captures")
        info = info if isinstance(info, Mapping) else {}
        recipe = info.get("recipe") if isinstance(info.get("recipe"), Mapping) else {}
        try:
            normalisation = CaptureNormalisation.from_dict(dict(stored))
            if normalisation.reference_scale is None:
                raise ValueError("its capture normalisation has no reference scale")
            return cls(
                normalisation=normalisation,
                frame_step=int(conditioning.get("frame_step", 1)),
                window_frames=meta.window,
                eval_stride=int(recipe.get("eval_stride", max(1, meta.window // 4))),
                symmetries=bool(recipe.get("symmetries", False)),
                train_digests=frozenset(str(d) for d in info.get("train_capture_digests", [])),
            )
        except (TypeError, ValueError) as exc:
            raise ValueError(f"model {where}: bad capture settings in meta.json ({exc})") from None


def per_class_dict(metrics: ClassificationMetrics) -> dict[str, dict[str, float]]:
    """``{class: {precision, recall, f1, support}}`` of ``metrics``."""
    return {
        s.name: {"precision": s.precision, "recall": s.recall, "f1": s.f1, "support": s.support}
        for s in metrics.per_class
    }


@dataclass
class CaptureEvaluation:
    """Captures scored one label each (and their windows), with what was scored."""

    source: str
    model_dir: str
    model_name: str
    class_names: tuple[str, ...]
    captures: ClassificationMetrics  # one prediction per capture
    windows: ClassificationMetrics  # one prediction per window (identity view)
    labels: np.ndarray  # (n,) true label of every scored capture
    predictions: np.ndarray  # (n,) predicted label of every scored capture
    groups: np.ndarray  # (n,) str, participant of every scored capture
    seen_in_training: int  # scored captures identical to a training capture of the model
    seconds: float
    views: int  # grid symmetries averaged per window
    log_probs: np.ndarray | None = None  # (n, K) mean log-probability of every capture

    @property
    def capture_accuracy(self) -> float:
        return self.captures.accuracy

    @property
    def window_accuracy(self) -> float:
        return self.windows.accuracy

    def per_group(self) -> dict[str, float]:
        """Capture accuracy of every participant."""
        return {
            g: float(np.mean(self.predictions[self.groups == g] == self.labels[self.groups == g]))
            for g in sorted(set(self.groups.tolist()))
        }

    def warnings(self) -> list[str]:
        if not self.seen_in_training:
            return []
        return [
            f"{self.seen_in_training} of the {self.captures.n} captures were used to train "
            "the model: their scores are not a test result"
        ]

    def to_dict(self) -> dict[str, Any]:
        return {
            "source": self.source,
            "model_dir": self.model_dir,
            "model_name": self.model_name,
            "capture_accuracy": self.captures.accuracy,
            "window_accuracy": self.windows.accuracy,
            "macro_f1": self.captures.macro_f1,
            "window_macro_f1": self.windows.macro_f1,
            "n_captures": self.captures.n,
            "n_windows": self.windows.n,
            "class_names": list(self.class_names),
            "per_class": per_class_dict(self.captures),
            "confusion": self.captures.confusion,
            "window_confusion": self.windows.confusion,
            "per_group": self.per_group(),
            "aggregation": f"mean log-probability over all windows and {self.views} grid views",
            "seen_in_training": self.seen_in_training,
            "warnings": self.warnings(),
            "seconds": self.seconds,
        }

    def summary(self) -> str:
        return (
            f"{self.captures.n} captures, {self.windows.n} windows: capture accuracy "
            f"{100 * self.capture_accuracy:.1f} %, window accuracy "
            f"{100 * self.window_accuracy:.1f} %, macro-F1 {self.captures.macro_f1:.3f}"
        )


def check_captures_fit(
    captures: LabelledCaptures, meta: CheckpointMeta, source: str, model_dir: str
) -> None:
    """One-line ``ValueError`` unless the file's classes, rate and grid are the model's."""
    if list(captures.class_names) != list(meta.class_names):
        raise ValueError(
            f"{source} has classes {', '.join(captures.class_names)}; model {model_dir} was "
            f"trained on {', '.join(meta.class_names)}"
        )
    rows, cols = captures.frames.shape[2:]
    if not math.isclose(captures.sample_rate_hz, meta.sample_rate_hz, rel_tol=1e-3):
        raise ValueError(
            f"{source} was sampled at {captures.sample_rate_hz:g} Hz; model {model_dir} "
            f"expects {meta.sample_rate_hz:g} Hz"
        )
    if (rows, cols) != (meta.rows, meta.cols):
        raise ValueError(
            f"{source} holds {rows}x{cols} frames; model {model_dir} expects "
            f"{meta.rows}x{meta.cols}"
        )


def _log_softmax(logits: np.ndarray) -> np.ndarray:
    z = np.asarray(logits, dtype=np.float64)
    z = z - z.max(axis=1, keepdims=True)
    return z - np.log(np.exp(z).sum(axis=1, keepdims=True))


def score_captures(
    recognizer: OnnxRecognizer,
    captures: LabelledCaptures,
    indices: Sequence[int] | np.ndarray | None = None,
    *,
    source: str = "",
) -> CaptureEvaluation:
    """Score the captures at ``indices`` (all by default) with a capture model.

    Every capture is prepared as in training, cut into windows every ``eval_stride`` model
    frames (the last one ending at its last frame), and every window scored under each grid
    symmetry the model was trained with; the capture's label is the class of highest mean
    log-probability.  Window accuracy counts each window's own (identity view) prediction.
    """
    started = time.perf_counter()
    meta = recognizer.meta
    model_dir = str(recognizer.checkpoint_dir)
    check_captures_fit(captures, meta, source or "the captures", model_dir)
    spec = CaptureModelSpec.from_meta(meta, model_dir)
    ids = np.arange(len(captures.labels)) if indices is None else np.asarray(indices, np.int64)
    if ids.size == 0:
        raise ValueError("no captures to score")
    capture_log_p = np.empty((ids.size, meta.n_classes))
    window_true: list[np.ndarray] = []
    window_pred: list[np.ndarray] = []
    views = 1
    for start in range(0, ids.size, SCORE_CHUNK):
        chunk = ids[start : start + SCORE_CHUNK]
        prepared = prepare_captures(captures, spec.normalisation, spec.frame_step, chunk)
        per_capture = [
            capture_windows(
                prepared[int(i)], len(prepared[int(i)]), spec.window_frames, spec.eval_stride
            )
            for i in chunk
        ]
        counts = np.array([len(w) for w in per_capture])
        batch = np.concatenate(per_capture)
        log_p = np.zeros((len(batch), meta.n_classes))
        views = 0
        for view in grid_symmetries(batch, spec.symmetries) if spec.symmetries else [batch]:
            view_log_p = _log_softmax(recognizer.predict_logits(np.ascontiguousarray(view)))
            if views == 0:
                window_pred.append(view_log_p.argmax(axis=1))
            log_p += view_log_p
            views += 1
        owner = np.repeat(np.arange(chunk.size), counts)
        sums = np.zeros((chunk.size, meta.n_classes))
        np.add.at(sums, owner, log_p)
        capture_log_p[start : start + chunk.size] = sums / (counts[:, None] * views)
        window_true.append(np.repeat(captures.labels[chunk], counts))
    capture_pred = capture_log_p.argmax(axis=1)
    labels = captures.labels[ids].astype(np.int64)
    seen = 0
    if spec.train_digests:
        seen = sum(
            _capture_digest(captures.frames[i, : captures.lengths[i]]) in spec.train_digests
            for i in ids.tolist()
        )
    class_names = tuple(meta.class_names)
    return CaptureEvaluation(
        source=source,
        model_dir=model_dir,
        model_name=meta.model_name,
        class_names=class_names,
        captures=classification_metrics(labels, capture_pred, class_names),
        windows=classification_metrics(
            np.concatenate(window_true), np.concatenate(window_pred), class_names
        ),
        labels=labels,
        predictions=capture_pred,
        groups=captures.groups[ids].astype(str),
        seen_in_training=int(seen),
        seconds=time.perf_counter() - started,
        views=views,
        log_probs=capture_log_p,
    )


def evaluate_captures(
    path: str | Path, model_dir: str | Path, *, threads: int = 1
) -> CaptureEvaluation:
    """Score a labelled-captures file with a capture model, on ONNX Runtime (no torch).

    One label per capture (:func:`score_captures`).  A file whose class names, sample rate
    or grid differ from the model's, or a model not trained on captures, is refused with a
    one-line ``ValueError``.
    """
    from wovenskin.recognition.onnx_runtime import OnnxRecognizer

    captures = _read(path)
    recognizer = OnnxRecognizer(model_dir, threads=threads)
    return score_captures(recognizer, captures, source=str(path))


# ============================================================================ LOPO


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

    def to_dict(self) -> dict[str, Any]:
        e = self.evaluation
        return {
            "participant": self.participant,
            "capture_accuracy": e.capture_accuracy,
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
    recipe: CaptureRecipe
    seed: int
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
            "recipe": self.recipe.to_dict(),
            "seed": self.seed,
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
    *,
    model: str | None = None,
    epochs: int | None = None,
    seed: int = 0,
    threads: int = 1,
    progress: Callable[[TrainEvent], None] | None = None,
    participants: Sequence[str] | None = None,
    on_fold: Callable[[FoldResult], None] | None = None,
    recipe: CaptureRecipe | None = None,
) -> LopoResult:
    """Leave-one-participant-out cross-validation, one label per capture.

    For every participant of the file's ``groups`` (or only ``participants``), a model is
    trained as :func:`train_on_captures` would (same recipe, internal validation drawn from
    the other participants only) into ``out_dir/fold-<participant>/`` and scores that
    participant's captures with ONNX Runtime (:func:`score_captures`).  ``progress`` gets
    every fold's training events, ``on_fold`` every finished :class:`FoldResult`;
    ``out_dir/lopo.json`` is rewritten after every fold.  Needs torch.
    """
    from wovenskin.recognition.onnx_runtime import OnnxRecognizer

    started = time.perf_counter()
    recipe = _recipe_for(recipe, model, epochs)
    captures = _read(path)
    groups = captures.groups.astype(str)
    names = sorted(set(groups.tolist()))
    if participants:
        unknown = sorted(set(participants) - set(names))
        if unknown:
            raise ValueError(f"participant(s) {', '.join(unknown)} not in {path}")
        names = [n for n in names if n in set(participants)]
    if len(set(groups.tolist())) < 2:
        raise ValueError(f"{path}: leave-one-participant-out needs at least 2 participants")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    result = LopoResult(str(path), tuple(captures.class_names), recipe, seed, [], 0.0)
    for index, name in enumerate(names, start=1):
        held_out = np.flatnonzero(groups == name)
        train_ids, val_ids = internal_validation(
            captures.labels, groups, np.flatnonzero(groups != name), seed
        )
        fold_dir = out / f"fold-{name}"
        fold_started = time.perf_counter()
        trained = _train_captures(
            captures, str(path), train_ids, val_ids, fold_dir, recipe, seed=seed,
            threads=threads, progress=progress, resume=False,
            validation="one capture per (group, class) of the training participants",
        )  # fmt: skip
        train_seconds = time.perf_counter() - fold_started
        evaluation = score_captures(
            OnnxRecognizer(fold_dir, threads=threads), captures, held_out, source=str(path)
        )
        fold = FoldResult(
            index, len(names), name, evaluation, trained.best_epoch, trained.epochs_run,
            train_seconds, str(fold_dir),
        )  # fmt: skip
        result.folds.append(fold)
        result.seconds = time.perf_counter() - started
        text = json.dumps(result.to_dict(), indent=2, allow_nan=False) + "\n"
        atomic_write_bytes(out / LOPO_FILE, text.encode("utf-8"))
        if on_fold is not None:
            on_fold(fold)
    return result
