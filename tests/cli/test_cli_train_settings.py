"""``train`` and ``compare`` options left unset fall through to ``TrainConfig`` (issue 25).

The trainers are replaced by stand-ins that keep the configuration they are given, so
nothing is trained: the test reads which settings each command would have trained with.
"""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import pytest
from typer.testing import CliRunner

pytest.importorskip("torch")

import wovenskin.cli.training as cli_training  # noqa: E402
import wovenskin.training.capture_train as capture_train  # noqa: E402
import wovenskin.training.compare as compare  # noqa: E402
from wovenskin.cli import app  # noqa: E402
from wovenskin.errors import ConfigError  # noqa: E402
from wovenskin.training.config import CAPTURE_DEFAULTS, TrainConfig  # noqa: E402

OPTIONS = ["--batch-size", "16", "--lr", "0.001", "--patience", "2", "--epochs", "4"]
GIVEN = {"batch_size": 16, "lr": 0.001, "patience": 2, "epochs": 4}


class Kept(ConfigError):
    """Raised by the stand-in trainers once they hold the configuration."""


@pytest.fixture
def configs(monkeypatch):
    kept: list[TrainConfig] = []

    def keep(config):
        kept.append(config)
        raise Kept("configuration kept")

    monkeypatch.setattr(
        cli_training, "_open_or_build_dataset", lambda data, ui: SimpleNamespace(path="ds")
    )
    monkeypatch.setattr(
        compare, "train_on_dataset", lambda ds, out, split, config, show: keep(config)
    )
    monkeypatch.setattr(
        compare, "compare_models", lambda ds, out, n, s, config, *a, **k: keep(config)
    )
    monkeypatch.setattr(capture_train, "train_on_captures", lambda p, o, config, **k: keep(config))
    return kept


def config_of(configs, *args) -> TrainConfig:
    result = CliRunner().invoke(app, [str(a) for a in args])
    assert result.exit_code == 2 and "configuration kept" in result.output, result.output
    return configs.pop()


def test_train_without_options_trains_with_the_train_configs_defaults(configs, tmp_path) -> None:
    config = config_of(configs, "train", "--data", tmp_path, "--out", tmp_path / "m")
    assert config == TrainConfig(hparams={})


def test_train_options_given_replace_only_their_settings(configs, tmp_path) -> None:
    config = config_of(configs, "train", "--data", tmp_path, "--out", tmp_path / "m", *OPTIONS)
    assert config == replace(TrainConfig(hparams={}), **GIVEN)


def test_compare_falls_through_the_same_way(configs, tmp_path) -> None:
    assert config_of(configs, "compare", "--out", tmp_path / "c") == TrainConfig()
    config = config_of(configs, "compare", "--out", tmp_path / "c", *OPTIONS)
    assert config == replace(TrainConfig(), **GIVEN)


def test_captures_start_from_their_own_recipe_and_take_the_options_given(configs, tmp_path):
    base = ["train", "--captures", tmp_path / "h.npz", "--out", tmp_path / "m"]
    assert config_of(configs, *base) == CAPTURE_DEFAULTS
    assert config_of(configs, *base, *OPTIONS) == replace(CAPTURE_DEFAULTS, **GIVEN)
