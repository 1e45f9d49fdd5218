"""Tests of ``wovenskin bench recognition``: the conditions, the seeds, the figures, the CLI."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from typer.testing import CliRunner

from wovenskin.bench import conditions as suite
from wovenskin.bench import recognition as bench
from wovenskin.bench.conditions import CONDITIONS, condition_names, make_stream, stream_seed
from wovenskin.bench.recognition import TARGETS, run_recognition_benchmark
from wovenskin.cli import app
from wovenskin.recognition.event_scoring import score_stream
from wovenskin.recognition.pipeline import (
    PipelineSettings,
    arbiter_settings_for_model,
    load_recognizer,
    run_pipeline,
)
from wovenskin.recording.formats import write_labelled_stream
from wovenskin.signal.conditioner import condition_recording
from wovenskin.signal.config import ConditioningConfig
from wovenskin.sim.person import Person
from wovenskin.sim.skin_physics import SkinPhysics

runner = CliRunner()
SECONDS = 8.0
SUBSET = ["response_x1", "person_fast"]
FIGURE_KEYS = {
    "streams",
    "events",
    "detected",
    "false_activations",
    "duplicates",
    "precision",
    "recall",
    "f1",
    "false_activations_per_min",
    "median_latency_s",
    "median_motion_latency_s",
    "p90_latency_s",
    "p90_motion_latency_s",
}

# What each condition must override: (physics, person, simulate_stream keyword arguments).
EXPECTED = {
    "response_x0.1": ({"gain_pf": 0.4, "c0_pf": 20.0}, {}, {}),
    "response_x0.3": ({"gain_pf": 1.2, "c0_pf": 20.0}, {}, {}),
    "response_x1": ({"gain_pf": 4.0, "c0_pf": 20.0}, {}, {}),
    "response_x3": ({"gain_pf": 12.0, "c0_pf": 20.0}, {}, {}),
    "response_x10": ({"gain_pf": 40.0, "c0_pf": 20.0}, {}, {}),
    "fingertip_small": ({"field_spread_mm": 0.0}, {"pad_mm": 8.0, "pad_growth_mm": 2.0}, {}),
    "fingertip_large": ({"field_spread_mm": 6.5}, {"pad_mm": 9.5, "pad_growth_mm": 4.0}, {}),
    "person_light": ({}, {"force_n": 0.25}, {}),
    "person_slow": ({}, {"pace": 0.0}, {}),
    "person_fast": ({}, {"pace": 1.0}, {}),
    "person_hesitant": ({}, {"settle_s": 0.2, "consistency": 1.5}, {}),
    "skin_noisy": (
        {"noise_pf": 0.03, "mains_pf": 0.04, "body_mains_pf": 0.1, "glitch_rate_hz": 0.3},
        {},
        {},
    ),
    "skin_drifting": (
        {"drift_common_per_min": 0.01, "drift_channel_per_min": 0.004, "drift_tau_s": 120.0},
        {},
        {},
    ),
    "invalid_heavy": ({}, {}, {"invalid_fraction": 0.6}),
    "long_rests": ({}, {"rest_probability": 0.9, "rest_mean_s": 1.0}, {}),
}


def test_conditions_are_the_documented_suite() -> None:
    assert list(CONDITIONS) == list(EXPECTED)
    for name, condition in CONDITIONS.items():
        assert f"``{name}``" in suite.__doc__, name
        assert condition.description
    assert condition_names(None) == list(CONDITIONS)
    # A subset keeps the suite's order; unknown names are refused in one line.
    assert condition_names("person_fast, response_x1") == SUBSET
    with pytest.raises(ValueError, match="unknown condition.*nope"):
        condition_names("response_x1,nope")
    with pytest.raises(ValueError, match="no conditions"):
        condition_names(" , ")


@pytest.mark.parametrize("name", list(EXPECTED))
def test_each_condition_overrides_only_what_it_says(name: str) -> None:
    rng = np.random.default_rng(11)
    physics, person = SkinPhysics.sample(rng), Person.sample(rng)
    new_physics, new_person, kwargs = CONDITIONS[name].apply(rng, physics, person)
    physics_changes, person_changes, stream_kwargs = EXPECTED[name]
    assert new_physics == replace(physics, **physics_changes)
    assert new_person == replace(person, **person_changes)
    assert kwargs == stream_kwargs


def test_stream_seeds_are_fixed_distinct_and_independent_of_the_subset() -> None:
    seeds = {stream_seed(9000, i, j) for i in range(len(CONDITIONS)) for j in range(5)}
    assert len(seeds) == 5 * len(CONDITIONS)
    assert stream_seed(9000, 3, 1) == stream_seed(9000, 3, 1) != stream_seed(9001, 3, 1)
    with pytest.raises(ValueError, match="stream index"):
        stream_seed(9000, 0, -1)


def test_make_stream_is_deterministic() -> None:
    a = make_stream("skin_noisy", 123, SECONDS)
    b = make_stream("skin_noisy", 123, SECONDS)
    np.testing.assert_array_equal(a.frames, b.frames)
    np.testing.assert_array_equal(a.event_start_s, b.event_start_s)
    assert a.metadata["events"] == b.metadata["events"]
    assert a.metadata["physics"]["glitch_rate_hz"] == 0.3
    assert len(a.event_labels) >= 1
    other = make_stream("skin_noisy", 124, SECONDS)
    assert not np.array_equal(a.frames, other.frames)
    heavy = make_stream("invalid_heavy", 123, SECONDS)
    assert heavy.metadata["invalid_fraction"] == 0.6


def conditioned(name: str, seed: int):
    stream = make_stream(name, seed, SECONDS)
    _, out = condition_recording(stream.frames.astype(np.float32), ConditioningConfig())
    return stream, out


def test_response_conditions_scale_the_conditioned_signal() -> None:
    dull, dull_out = conditioned("response_x0.1", 5)
    keen, keen_out = conditioned("response_x10", 5)
    # The same seed: the same person, skin and events, only the response differs.
    np.testing.assert_array_equal(dull.event_start_s, keen.event_start_s)
    assert dull.metadata["physics"]["gain_pf"] == pytest.approx(0.4)
    assert keen.metadata["physics"]["gain_pf"] == pytest.approx(40.0)
    ratio = np.abs(keen_out.signal).max() / np.abs(dull_out.signal).max()
    assert ratio > 30


def test_a_large_fingertip_touches_more_channels_than_a_small_one() -> None:
    def channels(name: str) -> float:
        _, out = conditioned(name, 2)
        counts = out.active.reshape(len(out), -1).sum(axis=1)
        return float(np.median(counts[out.touched]))

    assert channels("fingertip_large") >= 1.4 * channels("fingertip_small")


@pytest.fixture(scope="module")
def recognizer():
    return load_recognizer(None, threads=1)


@pytest.fixture(scope="module")
def result(recognizer):
    calls = []
    out = run_recognition_benchmark(
        recognizer,
        conditions=SUBSET,
        streams_per_condition=1,
        seconds=SECONDS,
        progress=lambda done, total, what: calls.append((done, total)),
    )
    assert calls[0] == (0, 2) and calls[-1] == (2, 2)
    return out


def test_the_json_has_per_condition_and_pooled_figures(result) -> None:
    document = json.loads(json.dumps(result.to_dict()))
    assert document["suite"] == {
        "base_seed": bench.DEFAULT_BASE_SEED,
        "streams_per_condition": 1,
        "seconds": SECONDS,
        "conditions": SUBSET,
    }
    assert list(document["conditions"]) == SUBSET
    for name in SUBSET:
        figures = document["conditions"][name]
        assert set(figures) >= FIGURE_KEYS
        index = list(CONDITIONS).index(name)
        assert figures["seeds"] == [stream_seed(bench.DEFAULT_BASE_SEED, index, 0)]
        assert figures["description"] == CONDITIONS[name].description
        assert [s["seed"] for s in figures["per_stream"]] == figures["seeds"]
        assert figures["streams"] == 1
    pooled = document["pooled"]
    assert set(pooled) >= FIGURE_KEYS
    assert pooled["streams"] == 2 and pooled["duration_s"] == pytest.approx(2 * SECONDS)
    assert pooled["events"] == sum(document["conditions"][n]["events"] for n in SUBSET)
    assert pooled["median_motion_latency_s"] is not None  # simulated streams know it
    worst = min(SUBSET, key=lambda n: document["conditions"][n]["f1"])
    assert document["worst_condition"] == {
        "name": worst,
        "f1": document["conditions"][worst]["f1"],
    }
    assert [t["name"] for t in document["targets"]] == [t.name for t in TARGETS]
    for check in document["targets"]:
        assert set(check) == {"name", "value", "target", "comparison", "passed"}
    assert document["passed"] == all(t["passed"] for t in document["targets"])
    assert document["settings"]["min_probability"] == pytest.approx(
        result.settings["min_probability"]
    )
    assert document["wall_s"] > 0 and document["pipeline_s"] > 0


def test_figures_agree_with_eval_stream(result, recognizer, tmp_path) -> None:
    """The bench runs a stream exactly as ``wovenskin eval-stream`` runs its file."""
    name = SUBSET[0]
    seed = result.conditions[0].streams[0].seed
    stream = make_stream(name, seed, SECONDS)
    path = tmp_path / "stream.npz"
    write_labelled_stream(path, stream)
    cli = runner.invoke(app, ["eval-stream", str(path), "--json"])
    assert cli.exit_code == 0, cli.output
    total = json.loads(cli.stdout)["total"]
    ours = result.conditions[0].to_dict()
    for key in ("events", "detected", "false_activations", "duplicates", "f1"):
        assert ours[key] == total[key], key
    assert ours["median_latency_s"] == pytest.approx(total["median_latency_s"])
    assert ours["median_motion_latency_s"] == pytest.approx(total["median_motion_latency_s"])
    # ... with the model's recommended execution rules (not the arbiter's bare defaults).
    settings = PipelineSettings(arbiter=arbiter_settings_for_model(recognizer))
    direct = score_stream(run_pipeline(stream, recognizer, settings).commands, stream)
    assert direct.f1 == ours["f1"]


def test_the_table_shows_conditions_pooled_and_targets(result) -> None:
    from rich.console import Console

    console = Console(width=120, record=True)
    console.print(result.table())
    text = console.export_text()
    for word in (*SUBSET, "pooled", "targets", "motion", "wall time"):
        assert word in text
    assert ("pass" in text) or ("miss" in text)


def test_cli_runs_a_subset() -> None:
    args = ["bench", "recognition", "--conditions", ",".join(SUBSET), "--seconds", str(SECONDS)]
    args += ["--streams-per-condition", "1", "--min-probability", "0.5", "--json"]
    cli = runner.invoke(app, args)
    assert cli.exit_code == 0, cli.output
    document = json.loads(cli.stdout)
    assert list(document["conditions"]) == SUBSET
    assert document["settings"]["min_probability"] == 0.5
    assert "wall time" in cli.stderr
    bad = runner.invoke(app, ["bench", "recognition", "--conditions", "nope", "--json"])
    assert bad.exit_code == 2 and "unknown condition" in bad.stderr
    assert bad.stdout == "" and "Traceback" not in bad.output
