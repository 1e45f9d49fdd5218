"""Tests of wovenskin.recognition.smoothing and the arbiter's ``smoothing_s`` rule."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wovenskin.errors import ConfigError
from wovenskin.recognition.arbiter import DWELL, LIFT_OFF, Arbiter, ArbiterSettings
from wovenskin.recognition.smoothing import ProbabilitySmoother

CLASSES = ("swipe_up", "swipe_right", "push", "invalid")
RATE = 200.0


def row(name: str, p: float) -> np.ndarray:
    out = np.full(len(CLASSES), (1 - p) / (len(CLASSES) - 1))
    out[CLASSES.index(name)] = p
    return out


def test_the_mean_of_the_touch_s_last_predictions() -> None:
    smoother = ProbabilitySmoother(3)
    rows = [row("swipe_up", p) for p in (0.3, 0.6, 0.9, 0.9)]
    assert np.allclose(smoother.step(True, rows[0]), rows[0])
    assert np.allclose(smoother.step(True, rows[1]), (rows[0] + rows[1]) / 2)
    assert np.allclose(smoother.step(True, rows[2]), (rows[0] + rows[1] + rows[2]) / 3)
    assert np.allclose(smoother.step(True, rows[3]), (rows[1] + rows[2] + rows[3]) / 3)


def test_the_window_is_time_and_a_lift_forgets_every_row() -> None:
    smoother = ProbabilitySmoother(3)
    a, b = row("swipe_up", 0.9), row("push", 0.9)
    smoother.step(True, a)
    assert smoother.step(True, None) is None  # no prediction on this frame
    assert np.allclose(smoother.step(True, b), (a + b) / 2)  # a is 2 frames old: kept
    assert smoother.step(True, None) is None
    assert np.allclose(smoother.step(True, b), b)  # a is 4 frames old, b 2: only b's
    assert np.allclose(smoother.step(False, a), a)  # no contact: the raw row, all forgotten
    assert np.allclose(smoother.step(True, b), b)


def test_bad_frames_are_refused() -> None:
    for frames in (0, -1, 1.5, True):
        with pytest.raises(ConfigError):
            ProbabilitySmoother(frames)  # type: ignore[arg-type]
    for value in (0.0, -0.01, float("nan"), float("inf")):
        with pytest.raises(ConfigError):
            ArbiterSettings(smoothing_s=value)
    assert ArbiterSettings(smoothing_s=0.04).smoothing_frames(RATE) == 8
    assert ArbiterSettings().smoothing_frames(RATE) is None


def flickering(n: int) -> np.ndarray:
    """A swipe_up whose probability alternates 0.95 / 0.8 around a 0.85 threshold."""
    return np.stack([row("swipe_up", 0.95 if i % 2 == 0 else 0.8) for i in range(n)])


def run(probabilities: np.ndarray, arbiter_settings: ArbiterSettings, touched=None):
    n = len(probabilities)
    touched = np.ones(n, bool) if touched is None else np.asarray(touched)
    arbiter = Arbiter(CLASSES, RATE, arbiter_settings)
    return arbiter.run(
        np.arange(n) / RATE, touched, np.ones(n, bool), np.ones(n, bool), probabilities
    )


def test_smoothing_carries_the_dwell_through_flickering_probabilities() -> None:
    probabilities = flickering(60)
    assert run(probabilities, ArbiterSettings(min_probability=0.85)) == []
    changes = run(probabilities, ArbiterSettings(min_probability=0.85, smoothing_s=0.04))
    assert [(c.gesture, c.reason) for c in changes] == [("swipe_up", DWELL)]


def test_a_single_stray_window_is_diluted() -> None:
    probabilities = np.stack([row("invalid", 0.9)] * 40)
    probabilities[20] = row("push", 0.99)
    # Alone it stays the candidate for no dwell either way; smoothed it is never recognised.
    smoothed = ArbiterSettings(min_probability=0.85, smoothing_s=0.04, flick_s=0.0)
    touched = np.ones(40, bool)
    touched[22:] = False  # lifted right after it: the raw window would be a flick
    raw = ArbiterSettings(min_probability=0.85, flick_s=0.0)
    assert [c.reason for c in run(probabilities, raw, touched)] == ["flick", LIFT_OFF]
    assert run(probabilities, smoothed, touched) == []


@settings(max_examples=30, deadline=None)
@given(
    seed=st.integers(0, 10_000),
    cuts=st.lists(st.integers(1, 299), max_size=6),
    every=st.integers(1, 3),
)
def test_any_split_into_calls_and_step_give_the_same_commands(seed, cuts, every) -> None:
    rng = np.random.default_rng(seed)
    n = 300
    labels = rng.choice(CLASSES, size=n // 20)
    probabilities = np.stack(
        [row(str(labels[i // 20]), float(rng.uniform(0.6, 1.0))) for i in range(n)]
    )
    touched = rng.random(n) > 0.03
    performing = rng.random(n) > 0.1
    predicted = np.arange(n) % every == 0
    t = np.arange(n) / RATE
    config = ArbiterSettings(min_probability=0.8, smoothing_s=0.04)
    whole = Arbiter(CLASSES, RATE, config).run(t, touched, performing, predicted, probabilities)
    split = Arbiter(CLASSES, RATE, config)
    pieces = []
    bounds = [0, *sorted(set(cuts)), n]
    for a, b in zip(bounds[:-1], bounds[1:], strict=True):
        sl = slice(a, b)
        pieces += split.run(t[sl], touched[sl], performing[sl], predicted[sl], probabilities[sl])
    stepped = Arbiter(CLASSES, RATE, config)
    steps = []
    for i in range(n):
        rows = probabilities[i] if predicted[i] else None
        steps += stepped.step(t[i], touched[i], performing[i], rows)
    assert pieces == whole
    assert steps == whole


def test_the_shipped_model_recommends_smoothing_and_overrides_win() -> None:
    """Read window by window, the shipped model's windows are smoothed; its touch reader's
    readings already stand for the whole touch and are not."""
    from wovenskin.recognition.pipeline import arbiter_settings_for_model, load_recognizer

    recognizer = load_recognizer(None)
    recommended = arbiter_settings_for_model(recognizer, "window")
    assert recommended.smoothing_s is not None and 0.0 < recommended.smoothing_s <= 0.1
    assert arbiter_settings_for_model(recognizer, "window", smoothing_s=0.02).smoothing_s == 0.02
    assert arbiter_settings_for_model(recognizer).smoothing_s is None  # the touch reader
