"""A model's recommended execution rules are honoured the same way everywhere (issue 25).

A copy of the shipped model recommends a dwell of 250 ms and a ``min_probability`` of 0.6
in its ``meta.json``.  ``replay``, ``eval-stream``, ``bench recognition``, ``bench
gestures`` and the live chain behind ``run`` and the dashboard must all run it with
exactly :func:`~wovenskin.recognition.pipeline.pipeline_settings_for_model`'s settings:
an option given, else the model's recommendation, else the settings' default.  The
pipelines themselves are replaced by stand-ins that only keep the settings they get, so
no stream is classified.
"""

from __future__ import annotations

import json
import shutil
from types import SimpleNamespace

import numpy as np
import pytest
from typer.testing import CliRunner

import wovenskin.bench.gestures
import wovenskin.bench.recognition
import wovenskin.recognition.pipeline as pipeline
from wovenskin.cli import app
from wovenskin.errors import ConfigError
from wovenskin.recognition.arbiter import ArbiterSettings
from wovenskin.recognition.shipped import default_model_dir

RECOMMENDED = {"dwell_s": 0.25, "min_probability": 0.6}


@pytest.fixture(scope="module")
def model_dir(tmp_path_factory):
    """The shipped model with other recommended execution rules."""
    folder = tmp_path_factory.mktemp("model") / "recommending"
    folder.mkdir()
    shipped = default_model_dir()
    shutil.copy(shipped / "model.onnx", folder / "model.onnx")
    meta = json.loads((shipped / "meta.json").read_text())
    meta["arbiter"] = dict(RECOMMENDED)
    meta.setdefault("reader", {})["arbiter"] = dict(RECOMMENDED)  # the shipped reader's rules
    (folder / "meta.json").write_text(json.dumps(meta))
    return folder


class Captured(ConfigError):
    """Raised by the stand-ins once they hold the settings (the command ends in one line)."""


@pytest.fixture
def captured(monkeypatch):
    """The pipeline settings each stand-in was called with."""
    seen: list = []

    def keep(settings):
        seen.append(settings)
        raise Captured("settings captured")

    def stream(path):
        return SimpleNamespace(event_labels=np.array([]))

    monkeypatch.setattr(pipeline, "load_stream", stream)
    monkeypatch.setattr(pipeline, "run_pipeline", lambda stream, model, s, **kw: keep(s))
    for module, name in (
        (wovenskin.bench.recognition, "run_recognition_benchmark"),
        (wovenskin.bench.gestures, "run_gestures_benchmark"),
    ):
        monkeypatch.setattr(module, name, lambda model, s, *args, **kw: keep(s))
    return seen


COMMANDS = {
    "replay": ["replay", "stream.npz"],
    "eval-stream": ["eval-stream", "stream.npz"],
    "bench recognition": ["bench", "recognition"],
    "bench gestures": ["bench", "gestures"],
}


def settings_of(args: list[str], model_dir, captured) -> object:
    result = CliRunner().invoke(app, [*args, "--model", str(model_dir)])
    assert result.exit_code == 2 and "settings captured" in result.output, result.output
    return captured.pop()


def expected(model_dir, **overrides):
    recognizer = pipeline.load_recognizer(model_dir)
    return pipeline.pipeline_settings_for_model(recognizer, **overrides)


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_every_command_runs_the_models_recommendation(command, model_dir, captured) -> None:
    settings = settings_of(COMMANDS[command], model_dir, captured)
    assert settings == expected(model_dir)
    assert settings.arbiter.dwell_s == RECOMMENDED["dwell_s"]  # not the 100 ms default
    assert settings.arbiter.min_probability == RECOMMENDED["min_probability"]
    assert settings.every == 4  # the shipped touch reader's own recommendation (reader.every)


@pytest.mark.parametrize("command", ["replay", "eval-stream"])
def test_an_option_given_wins_over_the_recommendation(command, model_dir, captured) -> None:
    args = [*COMMANDS[command], "--dwell-ms", "150", "--min-probability", "0.7", "--every", "2"]
    settings = settings_of(args, model_dir, captured)
    assert settings == expected(model_dir, every=2, dwell_s=0.15, min_probability=0.7)


def test_the_live_chain_of_run_and_the_dashboard_runs_the_recommendation(model_dir) -> None:
    from wovenskin.runtime.pipeline import open_live_pipeline

    chain = open_live_pipeline("sim:seed=1", model=model_dir)
    try:
        assert chain.pipeline.settings == expected(model_dir)
        assert chain.pipeline.arbiter.settings.dwell_s == RECOMMENDED["dwell_s"]
    finally:
        chain.close()


def test_without_a_recommendation_the_settings_defaults_apply() -> None:
    bare = SimpleNamespace(meta=SimpleNamespace(arbiter={}))
    assert pipeline.pipeline_settings_for_model(bare).arbiter == ArbiterSettings()
    assert pipeline.pipeline_settings_for_model(bare, dwell_s=None).arbiter == ArbiterSettings()
