"""Tests of wovenskin.recognition.streaming: the sliding window, its schedule and its checks."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from tiny_models import save_tiny_model

from wovenskin.recognition.onnx_runtime import OnnxRecognizer
from wovenskin.recognition.streaming import StreamingRecognizer, model_window
from wovenskin.signal import ConditioningConfig

ROWS, COLS, W = 4, 5, 6
CLASSES = ("swipe_up", "push", "invalid")


class FakeRecognizer:
    """Probabilities from each window's sum (deterministic), recording every call."""

    class_names = CLASSES

    def __init__(self, window: int | None = W) -> None:
        if window is not None:
            self.meta = type("Meta", (), {"window": window})()
        self.batches: list[np.ndarray] = []
        self.checked: tuple | None = None

    def check_input(self, rows, cols, window, rate, conditioning) -> None:
        self.checked = (rows, cols, window, rate, conditioning)
        if (rows, cols) != (ROWS, COLS):
            raise ValueError(f"model expects {ROWS}x{COLS} frames at 200 Hz, got {rows}x{cols}")

    def predict_proba(self, windows: np.ndarray) -> np.ndarray:
        self.batches.append(windows.copy())
        s = windows.sum(axis=(1, 2, 3))
        logits = np.stack([np.sin(s), np.cos(s), np.zeros_like(s)], axis=1)
        e = np.exp(logits)
        return (e / e.sum(axis=1, keepdims=True)).astype(np.float32)


def frames(n: int, seed: int = 0, contact_every: int = 1):
    rng = np.random.default_rng(seed)
    signal = rng.normal(0, 0.01, (n, ROWS, COLS)).astype(np.float32)
    active = np.zeros((n, ROWS, COLS), dtype=bool)
    touched = np.zeros(n, dtype=bool)
    for i in range(0, n, contact_every):
        active[i, i % ROWS, i % COLS] = True
    return signal, active, touched


def test_windows_are_the_last_frames_on_schedule() -> None:
    fake = FakeRecognizer()
    stream = StreamingRecognizer(fake, ROWS, COLS, 200.0, {"a": 1}, every=2)
    assert fake.checked == (ROWS, COLS, W, 200.0, {"a": 1})
    signal, active, touched = frames(20)
    out = stream.push(signal, active, touched)
    due = np.flatnonzero(out.predicted)
    assert due.tolist() == [5, 7, 9, 11, 13, 15, 17, 19]  # first full window, then every 2
    assert out.inferred.tolist() == out.predicted.tolist()  # every window had contact
    (batch,) = fake.batches
    for k, end in enumerate(due):
        np.testing.assert_array_equal(batch[k], signal[end - W + 1 : end + 1])
    # Probabilities are held between predictions, invalid before the first.
    expected = fake.predict_proba(batch)
    np.testing.assert_array_equal(out.probabilities[:5], np.tile([0, 0, 1], (5, 1)))
    np.testing.assert_array_equal(out.probabilities[5], expected[0])
    np.testing.assert_array_equal(out.probabilities[6], expected[0])
    np.testing.assert_array_equal(stream.latest_probabilities, expected[-1])
    assert stream.windows_predicted == 8 and stream.windows_inferred == 8


def test_contact_free_windows_are_not_classified() -> None:
    fake = FakeRecognizer()
    stream = StreamingRecognizer(fake, ROWS, COLS, 200.0)
    signal, active, touched = frames(40, contact_every=1000)  # contact only at frame 0
    touched[30] = True  # a debounced touch flag counts as contact too
    out = stream.push(signal, active, touched)
    inferred = np.flatnonzero(out.inferred)
    assert inferred.tolist() == [5] + list(range(30, 36))  # windows holding frame 0 or 30
    assert sum(len(b) for b in fake.batches) == 7
    idle = out.predicted & ~out.inferred
    np.testing.assert_array_equal(out.probabilities[idle], np.tile([0, 0, 1], (idle.sum(), 1)))
    assert stream.windows_predicted == 35 and stream.windows_inferred == 7


@settings(max_examples=40, deadline=None)
@given(cuts=st.lists(st.integers(1, 15), min_size=1, max_size=10), every=st.integers(1, 4))
def test_results_do_not_depend_on_how_frames_are_grouped(cuts: list[int], every: int) -> None:
    signal, active, touched = frames(60, seed=3, contact_every=4)
    whole = StreamingRecognizer(FakeRecognizer(), ROWS, COLS, 200.0, every=every)
    expected = whole.push(signal, active, touched)
    split = StreamingRecognizer(FakeRecognizer(), ROWS, COLS, 200.0, every=every)
    parts, start = [], 0
    for size in [*cuts, 60]:
        stop = min(start + size, 60)
        if stop > start:
            parts.append(split.push(signal[start:stop], active[start:stop], touched[start:stop]))
        start = stop
    for name in ("predicted", "inferred"):
        got = np.concatenate([getattr(p, name) for p in parts])
        np.testing.assert_array_equal(got, getattr(expected, name))
    got = np.concatenate([p.probabilities for p in parts])
    np.testing.assert_allclose(got, expected.probabilities, rtol=0, atol=1e-6)


def test_single_frames_and_blocks() -> None:
    fake = FakeRecognizer()
    stream = StreamingRecognizer(fake, ROWS, COLS, 200.0)
    signal, active, touched = frames(8)
    for i in range(8):
        out = stream.push(signal[i], active[i], touched[i])
        assert len(out) == 1 and out.predicted[0] == (i >= W - 1)
    block = type("Block", (), {"signal": signal, "active": active, "touched": touched})()
    assert len(stream.push_block(block)) == 8
    stream.reset()
    assert stream.frames_seen == 0 and stream.windows_predicted == 0


def test_bad_input_and_bad_models_give_one_line_errors() -> None:
    fake = FakeRecognizer()
    stream = StreamingRecognizer(fake, ROWS, COLS, 200.0)
    signal, active, touched = frames(10)
    with pytest.raises(ValueError, match=r"shaped \(N, 4, 5\) or \(4, 5\), got \(10, 5, 4\)"):
        stream.push(signal.transpose(0, 2, 1), active, touched)
    with pytest.raises(ValueError, match="active flags"):
        stream.push(signal, active[:, :2], touched)
    with pytest.raises(ValueError, match="expected 10 touched flags, got 9"):
        stream.push(signal, active, touched[:9])
    bad = signal.copy()
    bad[3, 1, 1] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        stream.push(bad, active, touched)
    assert stream.frames_seen == 0  # refused input leaves the state untouched
    with pytest.raises(ValueError, match="model expects 4x5 frames"):
        StreamingRecognizer(fake, 10, 10, 200.0)
    with pytest.raises(ValueError, match="every must be an integer >= 1"):
        StreamingRecognizer(fake, ROWS, COLS, 200.0, every=0)
    with pytest.raises(ValueError, match="pass window="):
        StreamingRecognizer(FakeRecognizer(window=None), ROWS, COLS, 200.0)
    assert model_window(FakeRecognizer(window=None), 7) == 7

    class NoInvalid(FakeRecognizer):
        class_names = ("a", "b", "c")

    with pytest.raises(ValueError, match="no 'invalid' class"):
        StreamingRecognizer(NoInvalid(), ROWS, COLS, 200.0)

    class WrongOutput(FakeRecognizer):
        def predict_proba(self, windows):
            return np.ones((len(windows), 2))

    with pytest.raises(ValueError, match=r"shaped \(5, 2\), expected \(5, 3\)"):
        StreamingRecognizer(WrongOutput(), ROWS, COLS, 200.0).push(signal, active, touched)


@pytest.fixture(scope="module")
def onnx_model(tmp_path_factory) -> Path:
    return save_tiny_model(tmp_path_factory.mktemp("model"), seed=0)


def test_onnx_recognizer_is_checked_against_the_stream(onnx_model: Path) -> None:
    recognizer = OnnxRecognizer(onnx_model)
    config = ConditioningConfig()
    stream = StreamingRecognizer(recognizer, 10, 10, 200.0, config)
    assert stream.window == 30
    rng = np.random.default_rng(0)
    signal = rng.normal(0, 0.05, (40, 10, 10)).astype(np.float32)
    active = signal > 0.1
    out = stream.push(signal, active, np.ones(40, dtype=bool))
    assert out.predicted.sum() == 11 and out.inferred.sum() == 11
    np.testing.assert_allclose(
        out.probabilities[-1], recognizer.predict_proba(signal[10:40])[0], atol=1e-5
    )
    with pytest.raises(ValueError, match="trained with other conditioning settings: smoothing_s"):
        StreamingRecognizer(recognizer, 10, 10, 200.0, ConditioningConfig(smoothing_s=0.05))
    with pytest.raises(ValueError, match="model expects 10x10 frames at 200 Hz, got 8x10"):
        StreamingRecognizer(recognizer, 8, 10, 200.0, config)
    with pytest.raises(ValueError, match="got 10x10 at 100 Hz"):
        StreamingRecognizer(recognizer, 10, 10, 100.0, config)
