"""The shipped default model: present, loadable without torch, consistent with its card."""

from __future__ import annotations

import json

import numpy as np
import pytest

from wovenskin.gestures import CLASS_NAMES
from wovenskin.recognition.pipeline import (
    arbiter_settings_for_model,
    conditioning_for_model,
    load_recognizer,
    pipeline_settings_for_model,
)
from wovenskin.recognition.shipped import (
    ModelNotFoundError,
    default_model_dir,
    resolve_model_dir,
)


def test_the_default_model_is_shipped_with_its_card() -> None:
    directory = default_model_dir()
    assert (directory / "model.onnx").stat().st_size < 5_000_000
    assert (directory / "MODEL_CARD.md").is_file()


def test_default_model_covers_the_gesture_vocabulary_and_its_conditioning() -> None:
    recognizer = load_recognizer(None)
    assert tuple(recognizer.class_names) == CLASS_NAMES
    assert recognizer.meta.window == 30 and recognizer.meta.sample_rate_hz == 200.0
    config = conditioning_for_model(recognizer)
    assert config is not None and config.sample_rate_hz == 200.0
    assert 0.0 < arbiter_settings_for_model(recognizer).min_probability < 1.0


def test_the_shipped_touch_reader_runs_the_network_on_every_fourth_window() -> None:
    """The touch reader averages the windows over the whole touch: every fourth window
    scored the same on the bench streams and halves the network's share of the live path
    (docs/benchmarks.md); the window reader keeps every window, and an option wins."""
    recognizer = load_recognizer(None)
    assert pipeline_settings_for_model(recognizer).reader == "touch"
    assert pipeline_settings_for_model(recognizer).every == 4
    assert pipeline_settings_for_model(recognizer, reader="window").every == 1
    assert pipeline_settings_for_model(recognizer, every=1).every == 1


def test_default_model_gives_probabilities_for_a_window() -> None:
    recognizer = load_recognizer(None)
    windows = np.zeros((2, 30, 10, 10), dtype=np.float32)
    windows[1, :, 3:5, 4:6] = 0.3
    proba = recognizer.predict_proba(windows)
    assert proba.shape == (2, len(CLASS_NAMES))
    np.testing.assert_allclose(proba.sum(axis=1), 1.0, atol=1e-4)


def test_model_card_quotes_the_checkpoints_own_validation_figure() -> None:
    directory = default_model_dir()
    meta = json.loads((directory / "meta.json").read_text())
    card = (directory / "MODEL_CARD.md").read_text()
    accuracy = 100 * meta["metrics"]["val_accuracy"]
    assert f"{accuracy:.1f} %" in card
    assert meta["training_data"]["split"]["name"] == "grouped"


def test_a_missing_model_directory_is_one_clear_error(tmp_path) -> None:
    with pytest.raises(ModelNotFoundError, match="no such model directory"):
        resolve_model_dir(tmp_path / "nope")
    with pytest.raises(ModelNotFoundError, match="no model.onnx"):
        resolve_model_dir(tmp_path)
