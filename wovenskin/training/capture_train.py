"""The capture trainer: a model trained on labelled captures, validated on held-out captures.

:func:`train_on_captures` runs :func:`~wovenskin.training.train.train_model` on a
:class:`~wovenskin.training.capture_prep.CaptureWindowArray`: every epoch draws fresh
windows, each at a random position of a training capture and under a random symmetry of
the grid (flips, and transposition on square grids: a person may touch from any side), so
six or seven people's captures go much further than fixed windows would.  Validation uses
fixed windows of held-out captures: given participants (``val_groups``), or by default
one capture of every (participant, class) cell, so early stopping and the choice of the
best epoch never see a training capture.  Settings: a
:class:`~wovenskin.training.config.TrainConfig`, by default
:data:`~wovenskin.training.config.CAPTURE_DEFAULTS`.  Needs torch.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np

from wovenskin.errors import ConfigError, DataError
from wovenskin.recording.formats import LabelledCaptures
from wovenskin.training.capture_prep import (
    CaptureWindowArray,
    capture_digest,
    capture_window_ends,
    prepare_captures,
    read_capture_file,
)
from wovenskin.training.config import CAPTURE_DEFAULTS, CAPTURE_HPARAMS, TrainConfig
from wovenskin.training.history import TrainEvent
from wovenskin.training.train import TrainResult, train_model


def internal_validation(
    labels: np.ndarray, groups: np.ndarray, candidates: np.ndarray, seed: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """``(train, val)`` capture indices from ``candidates``: one random capture of every
    (group, class) cell that has at least 3 captures goes to validation.

    Validation then holds every person and class in proportion (1 in 12 on HAART) and
    training keeps the rest.  Tiny files whose cells all have fewer than 3 captures give
    one capture of every class that has at least 2.  A ``DataError`` if none qualifies.
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
        raise DataError("too few captures to hold any out for validation (need 2 of a class)")
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
        raise ConfigError(
            f"validation group(s) {', '.join(unknown)} not in the file (groups: {', '.join(names)})"
        )
    is_val = np.isin(captures.groups[candidates].astype(str), list(val_groups))
    if is_val.all():
        raise ConfigError("every capture would be validation; leave some groups for training")
    return candidates[~is_val], candidates[is_val]


def _fixed_windows(
    prepared: Mapping[int, np.ndarray], ids: np.ndarray, config: TrainConfig
) -> list[tuple[int, int]]:
    stride = config.captures.eval_stride
    return [
        (int(i), int(end))
        for i in ids.tolist()
        for end in capture_window_ends(
            len(prepared[int(i)]), config.captures.window_frames, stride
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


def train_captures_split(
    captures: LabelledCaptures,
    source: str,
    train_ids: np.ndarray,
    val_ids: np.ndarray,
    out_dir: str | Path,
    config: TrainConfig,
    validation: str,
    progress: Callable[[TrainEvent], None] | None = None,
) -> TrainResult:
    """Train ``config`` on captures ``train_ids``, validating on ``val_ids``; the core of
    :func:`train_on_captures` and every LOPO fold.  The normalisation's reference scale
    comes from the training captures alone."""
    # The window array draws gain and noise itself (config.captures.gain, .noise).
    config = replace(config, hparams=config.resolved_hparams(CAPTURE_HPARAMS), augment=False)
    feed = config.captures
    norm = feed.normalisation.resolved(subset(captures, train_ids))
    prepared = prepare_captures(captures, norm, feed.frame_step, np.union1d(train_ids, val_ids))
    fixed = _fixed_windows(prepared, val_ids, config)
    random_captures = np.repeat(train_ids, feed.windows_per_capture)
    windows = CaptureWindowArray(
        prepared, feed.window_frames, random_captures, fixed, config.seed, feed.symmetries,
        gain=feed.gain, noise=feed.noise, time_stretch=feed.time_stretch,
        shift=feed.shift, taxel_gain=feed.taxel_gain, mix=feed.mix,
        partners=_mix_partners(captures, train_ids) if feed.mix > 0 else None,
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
        "window_frames": feed.window_frames,
        "conditioning": {"capture_normalisation": norm.to_dict(), "frame_step": feed.frame_step},
        "captures": {
            "source": source,
            "recipe": config.capture_record(),
            "window_seconds": feed.window_seconds(captures.sample_rate_hz),
            "validation": validation,
            "train_groups": sorted(set(groups[train_ids].tolist())),
            "val_groups": sorted(set(groups[val_ids].tolist())),
            "n_train_captures": int(train_ids.size),
            "n_val_captures": int(val_ids.size),
            "train_capture_digests": [
                capture_digest(captures.frames[i, : captures.lengths[i]]) for i in train_ids
            ],
        },
    }
    return train_model(
        windows,
        labels,
        list(captures.class_names),
        np.arange(n_random),
        np.arange(n_random, len(windows)),
        out_dir,
        data_meta,
        config,
        progress,
    )


def train_on_captures(
    path: str | Path,
    out_dir: str | Path,
    config: TrainConfig | None = None,
    *,
    progress: Callable[[TrainEvent], None] | None = None,
    val_groups: Sequence[str] | None = None,
) -> TrainResult:
    """Train a recogniser on a labelled-captures file; the checkpoint goes to ``out_dir``.

    ``val_groups`` (participants of the file's ``groups``) are held out for validation;
    without them one capture of every (participant, class) cell is
    (:func:`internal_validation`).  Validation picks the best epoch and stops training early
    (``config.patience``).  ``config`` defaults to :data:`CAPTURE_DEFAULTS`; with
    ``hparams`` None the model gets :data:`CAPTURE_HPARAMS` or its registry defaults.  The
    checkpoint's ``meta.json`` records the class names, the capture rate, the window, the
    normalisation and frame step (its ``conditioning``) and the recipe, which is all
    :func:`~wovenskin.training.capture_eval.evaluate_captures` needs.  ``progress`` gets
    the :class:`~wovenskin.training.train.TrainEvent` of every batch and epoch.
    """
    config = (config or CAPTURE_DEFAULTS).checked()
    captures = read_capture_file(path)
    everything = np.arange(len(captures.labels))
    if val_groups:
        train_ids, val_ids = _split_by_groups(captures, everything, list(val_groups))
        validation = f"held-out groups {', '.join(sorted(val_groups))}"
    else:
        train_ids, val_ids = internal_validation(
            captures.labels, captures.groups, everything, config.seed
        )
        validation = "one capture per (group, class)"
    return train_captures_split(
        captures, str(path), train_ids, val_ids, out_dir, config, validation, progress
    )
