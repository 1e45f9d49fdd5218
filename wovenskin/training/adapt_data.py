"""The data of ``wovenskin adapt``: a person's own trials, split into trained and held out.

A labelled stream (a guided recording or a labelled ``.npz``) is a run of *trials*: its
labelled events, gestures and ``invalid`` touches alike.  :class:`TrialSplit` gives every
trial a *block* of the stream's time, from the middle of the gap before it to the middle of
the gap after it (the first block starts at the stream's start, calibration included; the
last ends at its end), and holds out a share of the trials of every class, chosen at
random with a seed.  Every frame then belongs to exactly one trial:

- :func:`trial_windows` cuts training windows (the ``stream`` recipe,
  :mod:`~wovenskin.training.stream_windows`) only where the whole window lies in trained
  blocks, so no held-out frame reaches the model;
- :func:`score_held_out` scores a pipeline run over the whole stream (the conditioning
  and the recogniser see it as a live skin would) on the held-out blocks alone: their
  events, the activations inside them, false activations per minute of held-out time.

Labels may name classes the base model does not know (a user's own gesture); the caller
passes the class list to cut windows for.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from wovenskin.errors import DataError
from wovenskin.gestures import INVALID
from wovenskin.recognition.commandlog import CommandLike, changes_only
from wovenskin.recognition.event_scoring import EventScores, motion_starts, score_commands
from wovenskin.recording.formats import LabelledStream
from wovenskin.signal.conditioner import condition_recording
from wovenskin.signal.config import ConditioningConfig
from wovenskin.training.datasets.streams import motion_end_s, motion_frames
from wovenskin.training.stream_windows import characteristic_spans, sample_stream_windows
from wovenskin.training.window_settings import WindowSettings
from wovenskin.training.windows import (
    FrameEvents,
    WindowBatch,
    align_to_contact,
    canvas_starts,
    events_to_frames,
)

TRAINED = -1
"""The fold of a trained trial in :attr:`TrialSplit.fold`; held-out trials are in 0 or 1."""


@dataclass(frozen=True)
class TrialSplit:
    """The trials of one stream, their time blocks and which are held out.

    ``edges_s`` ``(K + 1,)`` are the block edges in time order and ``rank`` ``(K,)`` the
    time-order position of each event, so event ``k`` owns :meth:`block` ``(k)``.
    ``fold`` ``(K,)`` is :data:`TRAINED` for a trained trial and 0 or 1 for a held-out one:
    the held-out trials are dealt alternately into two halves of equal size (class after
    class), so that a choice made on one half can be scored on the other (cross-fitting,
    :mod:`~.adapt_arbiter`).
    """

    edges_s: np.ndarray
    rank: np.ndarray
    fold: np.ndarray
    duration_s: float

    @property
    def held_out(self) -> np.ndarray:
        """``(K,)`` bool: the held-out trials (either fold)."""
        return self.fold != TRAINED

    @classmethod
    def of(cls, stream: LabelledStream, held_out_fraction: float, seed: int = 0) -> TrialSplit:
        """Hold out about ``held_out_fraction`` of the trials, drawn at random with ``seed``
        from every class that keeps at least one trained trial, no class more than its
        share (rounded up)."""
        if not 0.0 <= held_out_fraction < 1.0:
            raise DataError(f"the held-out share must lie in [0, 1), got {held_out_fraction}")
        starts = np.asarray(stream.event_start_s, dtype=np.float64).reshape(-1)
        ends = np.asarray(stream.event_end_s, dtype=np.float64).reshape(-1)
        labels = np.asarray(stream.event_labels).astype(str).reshape(-1)
        duration = len(stream.t) / float(stream.sample_rate_hz)
        order = np.argsort(starts, kind="stable")
        rank = np.empty_like(order)
        rank[order] = np.arange(order.size)
        s, e = starts[order], ends[order]
        middle = [(a + b) / 2 if b >= a else b for a, b in zip(e[:-1], s[1:], strict=True)]
        edges = np.concatenate(([0.0], np.asarray(middle, dtype=np.float64), [duration]))
        edges = np.maximum.accumulate(np.clip(edges, 0.0, duration))
        fold = np.full(labels.size, TRAINED, dtype=np.int64)
        rng = np.random.default_rng([seed, 2311])
        names, counts = np.unique(labels, return_counts=True)
        size = dict(zip(names.tolist(), counts.tolist(), strict=True))
        cap = {n: min(c - 1, int(np.ceil(held_out_fraction * c))) for n, c in size.items()}
        taken = dict.fromkeys(size, 0)
        target = round(held_out_fraction * labels.size)
        for k in rng.permutation(labels.size):
            if sum(taken.values()) >= target:
                break
            name = str(labels[k])
            if taken[name] < cap[name]:
                fold[k] = 0
                taken[name] += 1
        # deal the held-out trials alternately into the halves, class after class (in time
        # order within a class), so the halves are as large as each other and as mixed
        dealt = [
            k for name in sorted(size) for k in np.argsort(starts, kind="stable")
            if labels[k] == name and fold[k] != TRAINED
        ]  # fmt: skip
        offset = int(rng.integers(2))
        for j, k in enumerate(dealt):
            fold[k] = (j + offset) % 2
        return cls(edges, rank, fold, duration)

    def block(self, k: int) -> tuple[float, float]:
        """The time block ``[start, end)`` of event ``k`` (stream order)."""
        i = int(self.rank[k])
        return float(self.edges_s[i]), float(self.edges_s[i + 1])

    def intervals(self, folds: Iterable[int]) -> list[tuple[float, float]]:
        """The blocks of the trials in ``folds`` (e.g. ``(0, 1)``: every held-out trial;
        ``(TRAINED,)``), adjacent ones merged, in time order.  A stream without events is
        one trained block."""
        folds = set(folds)
        if self.fold.size == 0:
            return [(0.0, self.duration_s)] if TRAINED in folds else []
        chosen = sorted(self.block(k) for k in range(self.fold.size) if int(self.fold[k]) in folds)
        merged: list[tuple[float, float]] = []
        for a, b in chosen:
            if merged and a <= merged[-1][1] + 1e-12:
                merged[-1] = (merged[-1][0], max(b, merged[-1][1]))
            elif b > a:
                merged.append((a, b))
        return merged

    def trained_frames(self, t: np.ndarray) -> np.ndarray:
        """``(T,)`` bool: the frames (times ``t``) inside a trained block."""
        t = np.asarray(t, dtype=np.float64)
        mask = np.zeros(t.size, dtype=bool)
        for a, b in self.intervals((TRAINED,)):
            mask |= (t >= a) & (t < b)
        return mask

    def summary(self) -> dict:
        held = sum(b - a for a, b in self.intervals((0, 1)))
        return {
            "trials": int(self.fold.size),
            "held_out_trials": int(self.held_out.sum()),
            "held_out_s": round(held, 3),
            "trained_s": round(self.duration_s - held, 3),
        }


def _inside(t: float, intervals: Sequence[tuple[float, float]]) -> bool:
    return any(a <= t < b for a, b in intervals)


HELD_OUT = (0, 1)


def score_held_out(
    commands: Iterable[CommandLike],
    stream: LabelledStream,
    split: TrialSplit,
    folds: Iterable[int] = HELD_OUT,
) -> EventScores:
    """Score a pipeline run over ``stream`` on the trials of ``folds`` only (default: every
    held-out trial; see the module doc).

    Activations count where they fall in those trials' blocks; command ends are kept
    wherever they fall, so a command held across a block edge is not mistaken for a new one.
    """
    folds = tuple(folds)
    intervals = split.intervals(folds)
    kept = [
        c for c in changes_only(commands) if c.gesture is None or _inside(float(c.t), intervals)
    ]
    k = np.flatnonzero(np.isin(split.fold, folds))
    motion = motion_starts(stream)
    labels = np.asarray(stream.event_labels).astype(str)
    return score_commands(
        kept,
        np.asarray(stream.event_start_s, dtype=np.float64)[k],
        np.asarray(stream.event_end_s, dtype=np.float64)[k],
        labels[k],
        sum(b - a for a, b in intervals),
        motion_start_s=None if motion is None else motion[k],
        known=set(labels.tolist()),  # a person's own gestures are classes here
    )


def trial_windows(
    stream: LabelledStream,
    split: TrialSplit,
    class_names: Sequence[str],
    conditioning: ConditioningConfig,
    settings: WindowSettings,
    n_gesture: int,
    n_invalid: int,
    rng: np.random.Generator,
) -> WindowBatch:
    """``n_gesture`` gesture and ``n_invalid`` invalid windows from the trained trials.

    Raises :class:`DataError` when the stream's rate is not the conditioning's or the
    trained trials hold no usable gesture.
    """
    if not np.isclose(stream.sample_rate_hz, conditioning.sample_rate_hz, rtol=1e-6):
        raise DataError(
            f"the stream runs at {stream.sample_rate_hz:g} Hz but the model's conditioning is "
            f"set for {conditioning.sample_rate_hz:g} Hz"
        )
    index = {name: i for i, name in enumerate(class_names)}
    if INVALID not in index:
        raise DataError(f"the class list has no {INVALID!r} class")
    labels = [str(label) for label in np.asarray(stream.event_labels).reshape(-1)]
    unknown = sorted(set(labels) - index.keys())
    if unknown:
        raise DataError(f"label(s) {', '.join(map(repr, unknown))} are not among the classes")
    _, conditioned = condition_recording(stream.frames, conditioning)
    events = events_to_frames(
        stream.t, stream.event_start_s, stream.event_end_s, [index[x] for x in labels],
        motion_end_s(stream), settings.rest_context_frames,
    )  # fmt: skip
    events, seen = align_to_contact(events, conditioned.touched, index[INVALID])
    keep = seen & ~split.held_out
    trained = FrameEvents(
        events.labels[keep], events.start[keep], events.stop[keep], events.informative_stop[keep]
    )
    motion_start, motion_stop = motion_frames(stream)
    if motion_start is not None and motion_stop is not None:
        motion_start, motion_stop = motion_start[keep], motion_stop[keep]
    span_start, span_stop = characteristic_spans(trained, motion_start, motion_stop, settings)
    # a window may end at frame i when all its frames lie in trained blocks
    w = settings.window_frames
    allowed = np.zeros(len(stream.t), dtype=bool)
    allowed[canvas_starts(split.trained_frames(stream.t), w) + w - 1] = True
    try:
        return sample_stream_windows(
            conditioned.signal, conditioned.touched, trained, span_start, span_stop,
            n_gesture, n_invalid, index[INVALID], settings, rng, allowed,
        )  # fmt: skip
    except ValueError as exc:
        raise DataError(f"cannot cut training windows: {exc}") from None
