"""Tests of ``wovenskin replay`` and ``wovenskin eval-stream``."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from tiny_models import save_tiny_model
from typer.testing import CliRunner

from wovenskin.cli import app
from wovenskin.recognition import shipped
from wovenskin.recognition.commandlog import format_command_log, parse_command_log
from wovenskin.recognition.pipeline import PipelineSettings, load_recognizer, run_pipeline
from wovenskin.recording.formats import write_labelled_stream
from wovenskin.sim.stream import simulate_stream

runner = CliRunner()


@pytest.fixture(scope="module")
def model_dir(tmp_path_factory) -> Path:
    return save_tiny_model(tmp_path_factory.mktemp("model"), seed=2, decisive=True)


@pytest.fixture(scope="module")
def streams(tmp_path_factory) -> list[Path]:
    directory = tmp_path_factory.mktemp("streams")
    paths = []
    for seed in (1, 2):
        path = directory / f"s{seed}.npz"
        write_labelled_stream(path, simulate_stream(10.0, seed=seed))
        paths.append(path)
    return paths


def test_replay_json_prints_only_the_command_log(model_dir, streams) -> None:
    result = runner.invoke(app, ["replay", str(streams[0]), "--json", "--model", str(model_dir)])
    assert result.exit_code == 0, result.output
    expected = run_pipeline(streams[0], load_recognizer(model_dir)).commands
    assert len(expected) >= 4
    assert result.stdout == format_command_log(expected)
    for line in result.stdout.splitlines():
        assert set(json.loads(line)) == {"t", "gesture"}
    assert "x real time" in result.stderr  # the summary goes to stderr


def test_replay_every_and_table(model_dir, streams) -> None:
    result = runner.invoke(
        app, ["replay", str(streams[0]), "--json", "--model", str(model_dir), "--every", "4"]
    )
    assert result.exit_code == 0, result.output
    expected = run_pipeline(
        streams[0], load_recognizer(model_dir), PipelineSettings(every=4)
    ).commands
    assert parse_command_log(result.stdout) == parse_command_log(format_command_log(expected))
    table = runner.invoke(app, ["replay", str(streams[0]), "--model", str(model_dir)])
    assert table.exit_code == 0
    assert "commands" in table.stdout and "lift-off" in table.stdout


def test_replay_uses_the_shipped_model_by_default(
    model_dir, streams, monkeypatch, tmp_path
) -> None:
    monkeypatch.setattr(shipped, "DEFAULT_MODEL_DIR", model_dir)
    result = runner.invoke(app, ["replay", str(streams[0]), "--json"])
    assert result.exit_code == 0, result.output
    assert parse_command_log(result.stdout)
    monkeypatch.setattr(shipped, "DEFAULT_MODEL_DIR", tmp_path / "no-model")
    result = runner.invoke(app, ["replay", str(streams[0]), "--json"])
    assert result.exit_code == 2
    assert result.stdout == ""
    assert "shipped default model is missing" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and "Traceback" not in result.output


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["missing.npz"], "no such file"),
        (["STREAM", "--model", "nowhere"], "no such model directory"),
        (["STREAM", "--every", "0"], "--every 0: Input should be greater than or equal to 1"),
        (["STREAM", "--min-probability", "2"], "--min-probability 2: Input should be less"),
        (["BAD"], "bad.npz"),
    ],
)
def test_errors_are_one_line(model_dir, streams, tmp_path, args, message) -> None:
    bad = tmp_path / "bad.npz"
    np.savez(bad, frames=np.zeros((5, 2)))
    args = [str(streams[0]) if a == "STREAM" else str(bad) if a == "BAD" else a for a in args]
    if "--model" not in args:
        args += ["--model", str(model_dir)]
    for command in ("replay", "eval-stream"):
        result = runner.invoke(app, [command, *args, "--json"])
        assert result.exit_code == 2, result.output
        assert message in result.stderr
        assert len(result.stderr.strip().splitlines()) == 1
        assert result.stdout == "" and "Traceback" not in result.output


def test_eval_stream_json_and_table(model_dir, streams) -> None:
    result = runner.invoke(
        app, ["eval-stream", *map(str, streams), "--model", str(model_dir), "--json"]
    )
    assert result.exit_code == 0, result.output
    document = json.loads(result.stdout)
    assert [Path(s["path"]).name for s in document["streams"]] == ["s1.npz", "s2.npz"]
    total = document["total"]
    assert total["streams"] == 2 and total["duration_s"] == pytest.approx(20.0)
    assert total["events"] == sum(s["events"] for s in document["streams"])
    for key in ("precision", "recall", "f1", "false_activations_per_min", "median_latency_s"):
        assert key in total
    assert document["settings"] == {
        "every": 1, "dwell_s": 0.1, "min_probability": 0.0, "keep_probability": None,
        "max_switches": 1, "start_within_s": 0.2, "flick_s": 0.075, "flick_gap_s": 0.05,
        "flick_probability": 0.9, "flick_after_s": 0.3, "smoothing_s": None,
    }  # fmt: skip
    table = runner.invoke(app, ["eval-stream", str(streams[0]), "--model", str(model_dir)])
    assert table.exit_code == 0
    assert "event scores" in table.stdout and "per class" in table.stdout
