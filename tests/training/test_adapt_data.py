"""The trial split of ``wovenskin adapt``: blocks, held-out halves, windows and scoring."""

from __future__ import annotations

import numpy as np
import pytest

from wovenskin.errors import DataError
from wovenskin.recognition.arbiter import CommandChange
from wovenskin.recording.formats import LabelledStream
from wovenskin.signal.config import ConditioningConfig
from wovenskin.training.adapt_data import TRAINED, TrialSplit, score_held_out, trial_windows
from wovenskin.training.stream_windows import sample_stream_windows
from wovenskin.training.window_settings import WindowSettings
from wovenskin.training.windows import FrameEvents


def _stream(labels: list[str], gap_s: float = 1.5, touch_s: float = 0.6) -> LabelledStream:
    """A contact-free lead, then one pressed patch per label, ``gap_s`` apart."""
    fs = 200.0
    starts = 1.0 + np.arange(len(labels)) * (touch_s + gap_s)
    ends = starts + touch_s
    n = int(round((ends[-1] + 1.0) * fs))
    t = np.arange(n) / fs
    rng = np.random.default_rng(0)
    frames = 30000.0 + rng.normal(0.0, 3.0, size=(n, 10, 10))
    for k, (a, b) in enumerate(zip(starts, ends, strict=True)):
        on = (t >= a) & (t < b)
        row = 2 + k % 6
        frames[on, row : row + 2, 3:5] -= 1500.0  # a fingertip lowers the counts
    return LabelledStream(
        frames=frames.astype(np.float32), t=t, sample_rate_hz=fs,
        event_start_s=starts, event_end_s=ends, event_labels=np.array(labels),
    )  # fmt: skip


LABELS = ["swipe_up", "push", "invalid"] * 4


def test_split_holds_out_a_share_of_every_class_and_keeps_one_trained():
    split = TrialSplit.of(_stream(LABELS), 0.25, seed=3)
    labels = np.array(LABELS)
    assert split.held_out.sum() == 3
    for name in set(LABELS):
        members = split.fold[labels == name]
        assert (members == TRAINED).sum() >= 1
        assert (members != TRAINED).sum() <= 1
    assert set(split.fold[split.held_out].tolist()) <= {0, 1}


def test_blocks_partition_the_stream():
    stream = _stream(LABELS)
    split = TrialSplit.of(stream, 0.25, seed=1)
    blocks = sorted(split.block(k) for k in range(len(LABELS)))
    assert blocks[0][0] == 0.0
    assert blocks[-1][1] == pytest.approx(len(stream.t) / stream.sample_rate_hz)
    for (_, b0), (a1, _) in zip(blocks, blocks[1:], strict=False):
        assert b0 == pytest.approx(a1)
    for k in range(len(LABELS)):  # every trial lies inside its own block
        a, b = split.block(k)
        assert a <= stream.event_start_s[k] and stream.event_end_s[k] <= b
    held = sum(b - a for a, b in split.intervals((0, 1)))
    trained = sum(b - a for a, b in split.intervals((TRAINED,)))
    assert held + trained == pytest.approx(split.duration_s)


def test_same_seed_same_split_and_a_share_outside_range_is_refused():
    stream = _stream(LABELS)
    assert np.array_equal(TrialSplit.of(stream, 0.3, 5).fold, TrialSplit.of(stream, 0.3, 5).fold)
    with pytest.raises(DataError):
        TrialSplit.of(stream, 1.0)


def test_windows_are_cut_from_trained_trials():
    stream = _stream(LABELS)
    split = TrialSplit.of(stream, 0.25, seed=2)
    config = ConditioningConfig(sample_rate_hz=stream.sample_rate_hz)
    names = ["swipe_up", "push", "invalid"]
    batch = trial_windows(
        stream, split, names, config, WindowSettings(), 60, 30, np.random.default_rng(0)
    )
    assert len(batch) == 90 and np.isfinite(batch.windows).all()
    trained = split.trained_frames(stream.t)
    for k in np.flatnonzero(split.held_out):
        a, b = split.block(k)
        assert not trained[(stream.t >= a) & (stream.t < b)].any()


def test_only_allowed_window_ends_are_drawn():
    """The frame index is written into the signal, so each window's last value is its end."""
    n, w = 2000, 30
    signal = np.broadcast_to(np.arange(n, dtype=np.float32)[:, None, None], (n, 2, 2)).copy()
    touched = np.zeros(n, dtype=bool)
    touched[300:700] = touched[1300:1700] = True
    events = FrameEvents(np.array([0, 0]), np.array([300, 1300]), np.array([700, 1700]),
                         np.array([700, 1700]))  # fmt: skip
    allowed = np.zeros(n, dtype=bool)
    allowed[:1000] = True
    settings = WindowSettings(window_frames=w, min_segment_frames=10, max_partial_frames=8)
    batch = sample_stream_windows(
        signal, touched, events, events.start + 8, events.stop, 200, 100, 1, settings,
        np.random.default_rng(0), allowed,
    )  # fmt: skip
    ends = batch.windows[:, -1, 0, 0].astype(int)
    assert len(ends) == 300 and ends.max() < 1000


def test_an_unknown_label_is_refused():
    stream = _stream(LABELS)
    split = TrialSplit.of(stream, 0.25)
    config = ConditioningConfig(sample_rate_hz=stream.sample_rate_hz)
    with pytest.raises(DataError, match="swipe_up"):
        trial_windows(stream, split, ["push", "invalid"], config, WindowSettings(), 10, 5,
                      np.random.default_rng(0))  # fmt: skip


def test_scores_count_only_held_out_trials():
    stream = _stream(LABELS)
    split = TrialSplit.of(stream, 0.25, seed=4)
    commands = []
    for k, label in enumerate(LABELS):  # a perfect recogniser, plus one wrong command
        if label == "invalid":
            continue
        t = float(stream.event_start_s[k]) + 0.2
        commands += [CommandChange(t, label, "test"), CommandChange(t + 0.3, None, "lift")]
    scores = score_held_out(commands, stream, split)
    held = [label for label, h in zip(LABELS, split.held_out, strict=True) if h]
    assert scores.n_events == sum(1 for x in held if x != "invalid")
    assert scores.f1 == 1.0 and scores.n_false == 0
    k = int(np.flatnonzero(split.held_out)[0])
    a, _ = split.block(k)
    wrong = [CommandChange(a + 0.01, "circle_cw_2f", "test"), CommandChange(a + 0.02, None, "x")]
    assert score_held_out(_sorted(commands + wrong), stream, split).n_false == 1
    trained = int(np.flatnonzero(~split.held_out)[0])
    a, _ = split.block(trained)
    elsewhere = [CommandChange(a + 0.01, "circle_cw_2f", "t"), CommandChange(a + 0.02, None, "x")]
    assert score_held_out(_sorted(commands + elsewhere), stream, split).n_false == 0


def _sorted(commands: list[CommandChange]) -> list[CommandChange]:
    return sorted(commands, key=lambda c: c.t)
