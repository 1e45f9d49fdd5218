"""Tests of wovenskin.bench.control: IK, loop and latency figures, and the CLI command."""

from __future__ import annotations

import io
import json

import numpy as np
import pytest
from rich.console import Console
from stand_ins import ContactMeans
from typer.testing import CliRunner

from wovenskin.bench import control as bench_control
from wovenskin.bench.control import (
    LATENCY_TARGET_S,
    ControlBenchResult,
    GestureLatency,
    _summarise_latencies,
    bench_ik,
    run_control_benchmark,
)
from wovenskin.cli import app
from wovenskin.recognition import shipped


def test_ik_steps_are_timed() -> None:
    times, rate = bench_ik(steps=60)
    assert rate == 250.0 and times.shape == (60,)
    assert np.all(times > 0) and np.median(times) < 0.05


def test_all_figures_with_a_stand_in_recogniser() -> None:
    result = run_control_benchmark(
        loop_seconds=1.0, streams=1, stream_seconds=10.0, ik_steps=50,
        recognizer=ContactMeans("push"), gestures=["push"],
    )  # fmt: skip
    assert result.ik_steps == 50 and result.ik_step_p99_ms >= result.ik_step_median_ms > 0
    assert 150 < result.loop_rate_hz < 250  # the simulated skin paced at 200 Hz
    assert result.loop_ticks > 100 and result.loop_interval_p99_ms >= 0
    assert result.loop_compute_p99_ms >= result.loop_compute_median_ms > 0
    assert result.latency_gestures >= 4  # every event of the stream counts
    assert result.latency_moved >= 3  # every push, recognised, from rest
    # contact, conditioning, the 0.1 s dwell and a jerk-limited start: 0.1 s to 0.5 s
    assert 100 <= result.latency_median_ms <= 500
    assert result.latency_max_ms >= result.latency_p90_ms >= result.latency_median_ms
    assert result.command_median_ms <= result.latency_median_ms
    assert 0.0 <= result.latency_within_target <= 1.0
    document = json.loads(json.dumps(result.to_dict()))
    assert document["latency_per_gesture_ms"]
    console = Console(record=True, width=200, file=io.StringIO())
    console.print(result.table())
    text = console.export_text()
    assert "IK step" in text and "first contact -> first motion" in text


def test_latency_summary_counts_only_gestures_that_moved_from_rest() -> None:
    result = ControlBenchResult(ik_steps=1, ik_step_median_ms=1, ik_step_p99_ms=1, ik_rate_hz=250)
    latencies = [
        GestureLatency("push", 1.0, 1.12, 1.15, True, "push"),
        GestureLatency("push", 3.0, 3.13, 3.25, True, "push"),
        GestureLatency("swipe_up", 5.0, 5.11, None, False, "swipe_up"),  # the arm still moved
        GestureLatency("swipe_up", 7.0, None, None, True),  # never recognised
        GestureLatency("swipe_up", 9.0, 9.05, 9.06, True, "push"),  # the wrong command
    ]
    _summarise_latencies(result, latencies)
    assert (result.latency_gestures, result.latency_moved) == (5, 2)
    assert result.latency_median_ms == pytest.approx(200.0)
    assert result.latency_max_ms == pytest.approx(250.0)
    assert result.latency_within_target == pytest.approx(0.5)  # 150 ms yes, 250 ms no
    assert result.command_median_ms == pytest.approx(120.0)  # 120, 130, 110 ms
    assert result.latency_per_gesture_ms == {"push": pytest.approx(200.0)}
    assert LATENCY_TARGET_S == 0.2
    assert any("still moved" in note for note in result.notes)
    assert any("1 gesture(s) started another command" in note for note in result.notes)


def test_without_a_model_only_ik_is_measured(monkeypatch) -> None:
    def missing(path=None):
        raise shipped.ModelNotFoundError("the shipped default model is missing")

    monkeypatch.setattr(shipped, "resolve_model_dir", missing)
    result = run_control_benchmark(loop_seconds=1.0, ik_steps=20)
    assert result.ik_steps == 20 and result.loop_ticks == 0 and result.latency_gestures == 0
    assert "not measured: the shipped default model is missing" in result.notes[0]


def test_cli_prints_figures(monkeypatch) -> None:
    seen = {}

    def fake(model, loop_seconds, streams, stream_seconds, ik_steps):
        seen.update(loop_seconds=loop_seconds, streams=streams, ik_steps=ik_steps)
        return run_control_benchmark(
            loop_seconds=0, streams=1, stream_seconds=6.0, ik_steps=ik_steps,
            recognizer=ContactMeans("push"), gestures=["push"],
        )  # fmt: skip

    monkeypatch.setattr(bench_control, "run_control_benchmark", fake)
    runner = CliRunner()
    result = runner.invoke(app, ["bench", "control", "--ik-steps", "30", "--loop-seconds", "0"])
    assert result.exit_code == 0, result.output
    assert "IK step (30 steps at 250 Hz)" in result.stdout and "median" in result.stdout
    assert seen == {"loop_seconds": 0.0, "streams": 2, "ik_steps": 30}
    result = runner.invoke(app, ["bench", "control", "--json", "--ik-steps", "30"])
    document = json.loads(result.stdout)
    assert document["ik_steps"] == 30 and document["latency_gestures"] >= 1
