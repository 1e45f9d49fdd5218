"""Tests of wovenskin.training.config: one validated configuration, its documented defaults."""

from __future__ import annotations

import json
from dataclasses import fields

import pytest
from paths import REPO

from wovenskin.errors import ConfigError
from wovenskin.training.config import (
    CAPTURE_DEFAULTS,
    OPTIMISATION_KEYS,
    TrainConfig,
)

MODELS = REPO / "wovenskin" / "models"


def test_unknown_key_and_bad_value_are_one_line_config_errors():
    with pytest.raises(ConfigError, match="unknown setting 'epoch'") as unknown:
        TrainConfig.from_dict({"epoch": 3})
    with pytest.raises(ConfigError, match="lr: Input should be greater than 0") as bad:
        TrainConfig.from_dict({"lr": -1})
    with pytest.raises(ConfigError, match="val_fraction"):
        TrainConfig.from_dict({"val_fraction": 1.0})
    for error in (unknown, bad):
        assert "\n" not in str(error.value)
        assert isinstance(error.value, ValueError)  # callers catching ValueError still do
    with pytest.raises(ConfigError, match="epochs"):
        TrainConfig(epochs=0).checked()


def test_defaults_are_the_window_trainers_and_captures_change_four():
    config = TrainConfig.from_dict({})
    assert config == TrainConfig()
    assert (config.model, config.epochs, config.batch_size, config.lr) == (
        "transformer",
        3,
        64,
        3e-3,
    )
    changed = {
        f.name
        for f in fields(TrainConfig)
        if getattr(CAPTURE_DEFAULTS, f.name) != getattr(config, f.name)
    }
    assert changed == {"model", "epochs", "lr", "patience"}
    assert "CAPTURE_DEFAULTS" in (TrainConfig.__doc__ or "")


@pytest.mark.parametrize("name", ["default", "overlay"])
def test_shipped_models_record_the_optimisation_settings(name):
    meta = json.loads((MODELS / name / "meta.json").read_text())
    training = meta["training_data"]["training"]
    run_keys = ("n_train", "n_val", "init_from")  # the run, not its optimisation
    assert tuple(k for k in training if k not in run_keys) == OPTIMISATION_KEYS
    recorded = TrainConfig.from_dict({k: training[k] for k in OPTIMISATION_KEYS})
    assert recorded.optimisation() == {k: training[k] for k in OPTIMISATION_KEYS}
