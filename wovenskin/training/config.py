"""One training configuration, :class:`TrainConfig`, with one set of defaults read top to bottom.

Both trainers take it: the window trainer (``wovenskin train --data``, ``compare``,
:func:`~wovenskin.training.compare.train_on_dataset`,
:func:`~wovenskin.training.train.train_model`) and the capture trainer (``wovenskin train
--captures``, ``eval --lopo``, :mod:`~wovenskin.training.capture_train`).  The field
defaults are the window trainer's; the capture trainer starts from
:data:`CAPTURE_DEFAULTS`, which changes four of them (tuned on HAART).  Settings read from
a dict (a file, the command line) go through :meth:`TrainConfig.from_dict`: an unknown key
or a bad value is one :class:`~wovenskin.errors.ConfigError`.  The module needs no torch.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Annotated, Any, Literal

from annotated_types import Ge, Gt, Le, Lt

from wovenskin.settings import from_dict, to_dict
from wovenskin.training.datasets.normalisation import CaptureNormalisation

Positive = Annotated[int, Gt(0)]
PositiveFloat = Annotated[float, Gt(0)]
NonNegative = Annotated[float, Ge(0)]
DeviceName = Literal["auto", "cpu", "cuda"]
AmpName = Literal["auto", "off", "bf16", "fp16"]
Factor = Annotated[float, Ge(1)]
"""A random factor's range: values in ``[1 / f, f]``, log-uniform; 1 is off."""

DEFAULT_EPOCHS = 3
"""Epochs of the default window run: three passes over the 140-recording set (166,600
training windows each) take 17-21 minutes on one thread of the project's busy 2-core
machine (the default model's recipe, see its model card)."""

CAPTURE_HPARAMS: dict[str, dict[str, Any]] = {
    "tcn": {"stem_channels": 8, "dim": 32, "window_norm": False},
}
"""Hyperparameters of registry models for captures; a model not listed uses its defaults.

The small TCN (8 stem channels, 32-d) trains a HAART fold in about a minute on one core;
wider stems, a 64-d TCN and a small transformer did no better across people.  Captures are
already normalised, so the models' per-window peak normalisation is off: it would blow
up the faint windows between two pats."""

OPTIMISATION_KEYS = (
    "epochs", "batch_size", "lr", "seed", "patience", "weight_decay", "label_smoothing",
    "augment", "warmup_epochs",
)  # fmt: skip
"""The settings every checkpoint records as ``training`` and a resumed run must repeat."""


@dataclass(frozen=True)
class CaptureConfig:
    """How labelled captures are fed to a model (capture trainer only; tuned on HAART, LOPO).

    ``frame_step`` raw frames are averaged into one model frame; ``window_frames`` and
    ``eval_stride`` count model frames.  ``windows_per_capture`` random windows of every
    training capture make one epoch.  ``symmetries``: flip (and on square grids transpose)
    training windows at random, and average the log-probabilities over the same symmetries
    when scoring.  ``gain`` to ``mix`` are the random window array's augmentations
    (:class:`~wovenskin.training.capture_prep.CaptureWindowArray`).
    ``self_training_epochs`` > 0: leave-one-participant-out adapts each fold's model to the
    held-out person's unlabelled captures, fine-tuning that many epochs on the training
    captures plus the ``self_training_fraction`` it is surest of, labelled with its own
    predictions (:mod:`~wovenskin.training.capture_selftrain`).
    """

    frame_step: Positive = 2
    window_frames: Positive = 54
    eval_stride: Positive = 14
    windows_per_capture: Positive = 8
    symmetries: bool = True
    normalisation: CaptureNormalisation = field(default_factory=CaptureNormalisation)
    gain: Factor = 1.25
    noise: NonNegative = 0.01
    time_stretch: Factor = 1.0
    shift: Annotated[int, Ge(0)] = 0
    taxel_gain: NonNegative = 0.0
    mix: Annotated[float, Ge(0), Le(1)] = 0.0
    self_training_epochs: Annotated[int, Ge(0)] = 0
    self_training_fraction: Annotated[float, Gt(0), Le(1)] = 0.5

    def window_seconds(self, sample_rate_hz: float) -> float:
        return self.window_frames * self.frame_step / sample_rate_hz


@dataclass(frozen=True)
class TrainConfig:
    """Everything one training run needs besides its data; the defaults are the window
    trainer's (``wovenskin train --data`` and ``compare``).  See :data:`CAPTURE_DEFAULTS`."""

    # -- what is trained
    model: str = "transformer"
    hparams: dict[str, Any] | None = None
    """None: the registry defaults (captures: :data:`CAPTURE_HPARAMS` where listed)."""

    # -- optimisation: AdamW, linear warm-up, cosine decay (OPTIMISATION_KEYS)
    epochs: Positive = DEFAULT_EPOCHS
    batch_size: Positive = 64
    lr: PositiveFloat = 3e-3
    seed: int = 0
    """Initialisation, batch order, augmentation and dropout derive from it."""
    patience: Positive = 5
    """Epochs without a better validation score before training stops."""
    weight_decay: NonNegative = 0.01
    label_smoothing: Annotated[float, Ge(0), Lt(1)] = 0.05
    augment: bool = True
    """Random gain and noise per training window (the capture trainer draws its own)."""
    warmup_epochs: NonNegative = 1.0

    # -- the run
    device: DeviceName = "auto"
    """auto: CUDA when torch sees a GPU, else the CPU; cpu; cuda (refused without one).
    Not part of what a resumed run must repeat (:mod:`~wovenskin.training.device`)."""
    amp: AmpName = "auto"
    """Mixed precision on CUDA: auto (bf16 where supported, else fp16), bf16, fp16, off.
    The CPU always trains in float32 (auto is off there; bf16/fp16 are refused)."""
    threads: Positive = 1
    resume: bool = False
    time_budget_s: NonNegative | None = None
    """No epoch starts that would likely overrun it (at least one always runs)."""
    init_from: str | None = None
    """A checkpoint directory whose weights (``model.pt``) start the run instead of a random
    initialisation (fine-tuning); its model, hyperparameters, classes and window shape
    must be this run's."""

    # -- the validation split of a window data set
    split_seed: int = 0
    val_fraction: Annotated[float, Gt(0), Lt(1)] = 0.15

    # -- labelled captures
    captures: CaptureConfig = field(default_factory=CaptureConfig)

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> TrainConfig:
        """Validated settings from ``data``; missing keys take the defaults above."""
        return from_dict(cls, data, "training settings")

    def checked(self) -> TrainConfig:
        """This configuration validated (a :class:`ConfigError` when a value is out of range)."""
        return TrainConfig.from_dict(to_dict(self))

    def with_model(self, model: str | None) -> TrainConfig:
        """This configuration for ``model``, its own tuned hyperparameters (``None``: as is)."""
        if model is None or model == self.model:
            return self
        return replace(self, model=model, hparams=None)

    def resolved_hparams(self, tuned: Mapping[str, Mapping[str, Any]] | None = None) -> dict:
        """``hparams``, or when ``None`` the ``tuned`` ones of the model (else ``{}``)."""
        if self.hparams is not None:
            return dict(self.hparams)
        return dict((tuned or {}).get(self.model, {}))

    def optimisation(self) -> dict[str, Any]:
        """The :data:`OPTIMISATION_KEYS` settings, in that order (the checkpoint's record)."""
        return {key: getattr(self, key) for key in OPTIMISATION_KEYS}

    def capture_record(self) -> dict[str, Any]:
        """The capture recipe as capture checkpoints record it (one flat mapping)."""
        captures = dataclasses.asdict(self.captures)
        return {
            "model": self.model,
            "hparams": self.resolved_hparams(CAPTURE_HPARAMS),
            **self.optimisation(),
            **captures,
        }


CAPTURE_DEFAULTS = TrainConfig(model="tcn", epochs=20, lr=2e-3, patience=8)
"""Where the capture trainer starts: the small TCN, 20 epochs at a peak learning rate of
2e-3 with patience 8 (a HAART fold is small: more epochs, a gentler rate).  Everything else
is :class:`TrainConfig`'s default; ``augment`` is ignored (the window array augments)."""
