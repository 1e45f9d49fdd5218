"""Fine-tuning: ``TrainConfig.init_from`` starts a run from a checkpoint's weights."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch

from wovenskin.errors import ConfigError
from wovenskin.recognition.checkpoint_meta import WEIGHTS_FILE, read_meta
from wovenskin.training.config import TrainConfig
from wovenskin.training.train import train_model

pytestmark = pytest.mark.slow  # trains models

CLASSES = ("slide_right", "press")
ROWS, COLS, WINDOW = 5, 6, 12
META = {
    "sample_rate_hz": 200.0,
    "conditioning": {"smoothing_s": 0.1},
    "grid": {"rows": ROWS, "cols": COLS, "row_pitch_mm": 10.0, "col_pitch_mm": 10.0},
    "window": WINDOW,
    "source": "synthetic blobs",
}
SMALL = {"n_layers": 1, "ff_dim": 32, "d_model": 32}


def blobs(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """A blob sliding right (class 0) or pressing in place (class 1)."""
    rng = np.random.default_rng(seed)
    labels = rng.integers(0, 2, n)
    t = np.linspace(0.0, 1.0, WINDOW)[None, :]
    col = 1.5 + 3.0 * t * (labels[:, None] == 0)
    strength = np.where(labels[:, None] == 1, 0.2 + 0.8 * t, 1.0) * rng.uniform(0.1, 0.3, (n, 1))
    cc = np.arange(COLS)[None, None, None, :]
    rr = np.arange(ROWS)[None, None, :, None]
    d2 = (cc - col[:, :, None, None]) ** 2 + (rr - 2.0) ** 2
    windows = strength[:, :, None, None] * np.exp(-d2 / 1.5)
    return windows.astype(np.float32), labels.astype(np.int64)


def _train(out: Path, **settings) -> None:
    windows, labels = blobs(120, 0)
    config = TrainConfig(model="transformer", hparams=SMALL, batch_size=32, **settings)
    train_model(windows, labels, CLASSES, np.arange(90), np.arange(90, 120), out, META, config)


def test_a_run_starts_from_the_checkpoint_and_records_it(tmp_path: Path) -> None:
    _train(tmp_path / "first", epochs=1, seed=1)
    # A learning rate too small to move the weights: the run ends where it started.
    _train(tmp_path / "tuned", epochs=1, seed=2, lr=1e-12, init_from=str(tmp_path / "first"))
    first = torch.load(tmp_path / "first" / WEIGHTS_FILE, weights_only=True)
    tuned = torch.load(tmp_path / "tuned" / WEIGHTS_FILE, weights_only=True)
    for key, value in first.items():
        assert torch.allclose(value, tuned[key], atol=1e-6), key
    assert read_meta(tmp_path / "tuned").training_data["training"]["init_from"] == str(
        tmp_path / "first"
    )
    # Without it the same seed-2 run starts elsewhere.
    _train(tmp_path / "fresh", epochs=1, seed=2, lr=1e-12)
    fresh = torch.load(tmp_path / "fresh" / WEIGHTS_FILE, weights_only=True)
    assert any(not torch.allclose(value, fresh[key]) for key, value in first.items())


def test_a_checkpoint_of_another_shape_or_a_missing_one_is_refused(tmp_path: Path) -> None:
    _train(tmp_path / "first", epochs=1, seed=1)
    windows, labels = blobs(60, 1)
    other = TrainConfig(
        model="transformer", hparams={**SMALL, "n_layers": 2}, epochs=1,
        init_from=str(tmp_path / "first"),
    )  # fmt: skip
    with pytest.raises(ConfigError, match="its hyperparameters .* differ"):
        train_model(windows, labels, CLASSES, np.arange(40), np.arange(40, 60),
                    tmp_path / "x", META, other)  # fmt: skip
    missing = TrainConfig(model="transformer", hparams=SMALL, init_from=str(tmp_path / "none"))
    with pytest.raises(ConfigError, match="cannot start from"):
        train_model(windows, labels, CLASSES, np.arange(40), np.arange(40, 60),
                    tmp_path / "y", META, missing)  # fmt: skip
