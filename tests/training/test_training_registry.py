"""A model added with one class and one registry entry trains and compares by its name."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from torch import nn

from wovenskin.training import models
from wovenskin.training.compare import compare_models
from wovenskin.training.config import TrainConfig
from wovenskin.training.datasets import generate_sim_dataset
from wovenskin.training.models import WindowClassifier

pytestmark = pytest.mark.slow  # builds a data set and trains: `make test-fast` leaves it out


class MeanFrame(WindowClassifier):
    """The smallest model: the mean frame of the window, one linear layer."""

    def __init__(self, rows, cols, window, n_classes, window_norm: bool = True) -> None:
        super().__init__(rows, cols, window, n_classes, window_norm)
        self.head = nn.Linear(rows * cols, n_classes)

    def forward(self, windows: torch.Tensor) -> torch.Tensor:
        x, _ = self._normalized(windows)
        return self.head(x.mean(dim=1).flatten(1))


def test_a_registered_model_is_trained_and_compared_by_name(tmp_path, monkeypatch):
    monkeypatch.setitem(models.MODEL_REGISTRY, "meanframe", MeanFrame)
    ds = generate_sim_dataset(tmp_path / "ds", 3, 20, 5, 15.0, seed=4, workers=1)
    config = TrainConfig(epochs=1, batch_size=32, val_fraction=0.34)
    comparison = compare_models(ds, tmp_path / "cmp", ["meanframe"], config=config,
                                latency_repeats=2)  # fmt: skip
    row = comparison.rows[0]
    assert row.model == "meanframe" and row.params == 100 * 15 + 15
    assert np.isfinite(row.latency_median_ms) and 0 <= row.scores["grouped"].accuracy <= 1
