"""``wovenskin study ...`` through typer's CliRunner on the sub-app."""

from __future__ import annotations

import csv

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


def test_simulate_then_report(tmp_path):
    folder = tmp_path / "demo"
    args = ["simulate", str(folder), "--participants", "2", "--seed", "4", "--trials", "1"]
    result = RUN.invoke(study_app, args, env=ENV)
    assert result.exit_code == 0 and "SYNTHETIC" in result.output
    result = RUN.invoke(study_app, ["simulate", str(folder)], env=ENV)
    assert result.exit_code == 2 and "--overwrite" in result.output
    result = RUN.invoke(study_app, ["report", str(folder), "--out", str(tmp_path / "r")], env=ENV)
    assert result.exit_code == 0, result.output
    assert "SYNTHETIC" in result.output and "4 PNGs" in result.output
    assert (tmp_path / "r" / "report.html").exists()
