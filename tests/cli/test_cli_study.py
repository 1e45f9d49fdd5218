"""``wovenskin study ...`` through typer's CliRunner on the sub-app."""

from __future__ import annotations

import csv

import pytest
from typer.testing import CliRunner

from wovenskin.cli.study import study_app

RUN = CliRunner()
ENV = {"COLUMNS": "160"}


def test_init_add_participants_and_plan(tmp_path):
    assert RUN.invoke(study_app, ["init", str(tmp_path), "--name", "pilot"]).exit_code == 0
    for pid, level in (("P01", "novice"), ("P02", "expert")):
        result = RUN.invoke(
            study_app, ["add-participant", str(tmp_path), pid, "--expertise", level]
        )
        assert result.exit_code == 0, result.output
    result = RUN.invoke(study_app, ["plan", str(tmp_path)], env=ENV)
    assert result.exit_code == 0, result.output
    assert "skin > keyboard > pendant" in result.output
    assert "keyboard > pendant > skin" in result.output
    assert "multiple of 6" in result.output
    rows = list(csv.DictReader((tmp_path / "plan.csv").open()))
    assert len(rows) == 2 * 2 * 3


def test_user_errors_are_one_line_with_exit_code_2(tmp_path):
    result = RUN.invoke(study_app, ["plan", str(tmp_path)], env=ENV)
    assert result.exit_code == 2 and "study init" in result.output
    RUN.invoke(study_app, ["init", str(tmp_path)])
    result = RUN.invoke(
        study_app, ["add-participant", str(tmp_path), "P1", "--expertise", "guru"], env=ENV
    )
    assert result.exit_code == 2
    assert result.output.strip().count("\n") == 0 and "expertise" in result.output
    (tmp_path / "study.toml").write_text('name = "s"\nflavour = 1\n')
    result = RUN.invoke(study_app, ["plan", str(tmp_path)], env=ENV)
    assert result.exit_code == 2 and "unknown setting 'flavour'" in result.output
    result = RUN.invoke(study_app, ["init", str(tmp_path)], env=ENV)
    assert result.exit_code == 2 and "--overwrite" in result.output


def test_synthetic_then_report(tmp_path):
    folder = tmp_path / "demo"
    args = ["synthetic", str(folder), "--participants", "2", "--seed", "4", "--trials", "1"]
    result = RUN.invoke(study_app, args, env=ENV)
    assert result.exit_code == 0 and "SYNTHETIC" in result.output
    result = RUN.invoke(study_app, ["synthetic", str(folder)], env=ENV)
    assert result.exit_code == 2 and "--overwrite" in result.output
    result = RUN.invoke(study_app, ["report", str(folder), "--out", str(tmp_path / "r")], env=ENV)
    assert result.exit_code == 0, result.output
    assert "SYNTHETIC" in result.output and "4 PNGs" in result.output
    assert (tmp_path / "r" / "report.html").exists()


def _study(tmp_path):
    RUN.invoke(study_app, ["init", str(tmp_path)])
    RUN.invoke(study_app, ["add-participant", str(tmp_path), "P01", "--expertise", "novice"])
    return str(tmp_path)


def test_run_refuses_what_the_study_does_not_hold(tmp_path):
    folder = _study(tmp_path)
    base = ["run", folder, "--participant", "P01", "--task", "pour", "--interface"]
    result = RUN.invoke(study_app, [*base, "pendant"], env=ENV)
    assert result.exit_code == 2 and "web dashboard" in result.output
    result = RUN.invoke(study_app, [*base, "mouse"], env=ENV)
    assert result.exit_code == 2 and "not in the study" in result.output
    result = RUN.invoke(study_app, ["run", folder, "--participant", "P09", "--task", "pour",
                                    "--interface", "skin"], env=ENV)  # fmt: skip
    assert result.exit_code == 2 and "no participant" in result.output


def test_run_bounded_by_seconds_leaves_the_trial_incomplete(tmp_path):
    folder = _study(tmp_path)
    args = ["run", folder, "--participant", "P01", "--task", "pick_place", "--interface",
            "keyboard", "--skin", "none:speed=0", "--seconds", "0.5"]  # fmt: skip
    result = RUN.invoke(study_app, args, env=ENV)
    assert result.exit_code == 0, result.output
    assert "0 of 3 trials finished" in result.output
    trial = tmp_path / "trials" / "P01" / "pick_place-keyboard-1"
    assert (trial / "trajectory.csv").exists() and not (trial / "trial.json").exists()
    result = RUN.invoke(study_app, args, env=ENV)
    assert result.exit_code == 2 and "--overwrite" in result.output


@pytest.mark.slow
def test_run_skin_trials_end_at_the_time_limit(tmp_path):
    folder = _study(tmp_path)
    args = ["run", folder, "--participant", "P01", "--task", "pick_place", "--interface",
            "skin", "--skin", "sim:speed=0,seed=3,idle=0.3", "--trials", "2", "--time-limit",
            "0.5", "--seconds", "60"]  # fmt: skip
    result = RUN.invoke(study_app, args, env=ENV)
    assert result.exit_code == 0, result.output
    assert "trial 1: timeout" in result.output and "trial 2: timeout" in result.output
    rows = list(csv.DictReader((tmp_path / "trials.csv").open()))
    assert [r["outcome"] for r in rows] == ["timeout", "timeout"]
    assert all(float(r["duration_s"]) == 0.5 and int(r["gesture_commands"]) >= 1 for r in rows)


def test_simulate_runs_simulated_operators_and_reports_them(tmp_path):
    folder = tmp_path / "sim"
    args = ["simulate", str(folder), "--participants", "1", "--trials", "1", "--task", "pour",
            "--interface", "keyboard", "--time-limit", "5"]  # fmt: skip
    result = RUN.invoke(study_app, args, env=ENV)
    assert result.exit_code == 0, result.output
    assert "SIMULATED" in result.output and "S01 pour/keyboard trial 1: timeout" in result.output
    result = RUN.invoke(study_app, ["simulate", str(folder)], env=ENV)
    assert result.exit_code == 2 and "--overwrite" in result.output
    result = RUN.invoke(study_app, ["report", str(folder), "--out", str(tmp_path / "r")], env=ENV)
    assert result.exit_code == 0, result.output
    assert "SIMULATED OPERATORS" in (tmp_path / "r" / "report.md").read_text()


def test_simulate_hands_option_selects_and_refuses_in_one_line(tmp_path):
    folder = tmp_path / "sim"
    args = ["simulate", str(folder), "--participants", "1", "--trials", "1", "--task", "pour",
            "--interface", "keyboard", "--time-limit", "2"]  # fmt: skip
    result = RUN.invoke(study_app, [*args, "--hands", "robot"], env=ENV)
    assert result.exit_code == 2 and result.output.strip().count("\n") == 0
    assert "hands must be 'independent' or 'sim', got 'robot'" in result.output
    assert not folder.exists()
    result = RUN.invoke(study_app, [*args, "--hands", "sim"], env=ENV)
    assert result.exit_code == 0, result.output
    assert "sim hands" in result.output
    assert 'hands = "sim"' in (folder / "study.toml").read_text()
    result = RUN.invoke(study_app, [*args, "--overwrite"], env=ENV)
    assert result.exit_code == 0 and "independent hands" in result.output
    assert 'hands = "independent"' in (folder / "study.toml").read_text()
