"""What a newcomer reads first: counts agree with their nouns, ``study simulate`` says up
front how many trials it runs and roughly how long, and the event-score table of
``eval-stream`` fits an 80-column console."""

from __future__ import annotations

from rich.console import Console
from typer.testing import CliRunner

from wovenskin.cli import app
from wovenskin.recognition.event_scoring import EventScores, aggregate, scores_table
from wovenskin.study.simulate import (
    SIM_S_PER_WALL_S,
    TRIALS_PER_CONDITION,
    WALL_S_PER_TRIAL,
    estimate_wall_s,
)
from wovenskin.wording import duration, quantity

cli = CliRunner()
ENV = {"COLUMNS": "200"}


def test_counts_agree_with_their_nouns():
    assert quantity(1, "participant") == "1 participant"
    assert quantity(0, "trial") == "0 trials"
    assert quantity(2, "person", "people") == "2 people"
    assert [duration(s) for s in (40, 600, 4824, 12600)] == ["40 s", "10 min", "80 min", "3.5 h"]


def test_one_participant_is_not_participants(tmp_path):
    assert cli.invoke(app, ["study", "init", str(tmp_path)]).exit_code == 0
    args = ["study", "add-participant", str(tmp_path), "P01", "--expertise", "novice"]
    result = cli.invoke(app, args, env=ENV)
    assert result.exit_code == 0 and "1 participant in" in result.output, result.output
    result = cli.invoke(app, ["study", "plan", str(tmp_path)], env=ENV)
    assert "1 participant:" in result.output and "1 participants" not in result.output


def test_the_estimate_follows_the_measured_trial_times():
    per_condition = 6 * TRIALS_PER_CONDITION * 2
    expected = per_condition * sum(WALL_S_PER_TRIAL.values())
    assert estimate_wall_s(6, TRIALS_PER_CONDITION, 2, tuple(WALL_S_PER_TRIAL), 1) == expected
    assert estimate_wall_s(1, 1, 1, ("keyboard",), 1) == WALL_S_PER_TRIAL["keyboard"]
    short = estimate_wall_s(1, 1, 1, ("keyboard",), 1, time_limit_s=20.0)
    assert short == 20.0 / SIM_S_PER_WALL_S["keyboard"]  # the limit ends a trial sooner


def test_simulate_says_how_many_trials_and_how_long_before_it_starts(tmp_path, monkeypatch):
    monkeypatch.setattr("wovenskin.study.simulate.run_jobs", lambda *args, **kwargs: [])
    result = cli.invoke(app, ["study", "simulate", str(tmp_path / "s")], env=ENV)
    assert result.exit_code == 0, result.output
    first = result.output.splitlines()[0]
    trials = 6 * TRIALS_PER_CONDITION * 2 * 3
    assert first.startswith(f"{trials} simulated trials (6 operators x "), first
    guess = estimate_wall_s(6, TRIALS_PER_CONDITION, 2, ("skin", "keyboard", "pendant"), 1)
    assert f"roughly {duration(guess)} with --jobs 1" in first
    assert "Ctrl-C" in first


def test_the_event_score_table_fits_80_columns():
    s = EventScores(
        n_events=1200, n_detected=1100, n_activations=1180, n_false=8, n_duplicates=2,
        duration_s=600.0, latencies_s=[0.41], motion_latencies_s=[0.25],
    )  # fmt: skip
    name = "robustness-noise-strong-seed-3.npz"
    console = Console(width=80, record=True, color_system=None)
    console.print(scores_table([(name, s)], aggregate([s])))
    text = console.export_text()
    lines = text.splitlines()
    assert max(len(line) for line in lines) <= 80
    row = next(line for line in lines if line.startswith(name[:6]))
    for figure in ("1200", "1100", "0.80", "410", "250"):
        assert figure in row.split(), row  # every figure whole, on the stream's first line
    assert name in "".join(line.split()[0] for line in lines if line and not line[0].isspace())


def test_the_pytorch_hint_is_the_command_for_this_install() -> None:
    """From a clone the hint is the README's own command, not the package index's."""
    from wovenskin.wording import train_extra_hint

    assert train_extra_hint().startswith(".venv/bin/pip install -e '.[train]'")
