"""`wovenskin reproduce` end to end on its tiny size: one report with every section."""

import json
from dataclasses import asdict

import pytest
from typer.testing import CliRunner

from wovenskin.cli import app
from wovenskin.errors import ConfigError
from wovenskin.reproduce import study
from wovenskin.reproduce.paper import PAPER_TABLES, paper_reduction
from wovenskin.reproduce.report import reproduce
from wovenskin.reproduce.study import _command, _differences
from wovenskin.study.simulate import HANDS


def test_the_papers_tables_and_reductions():
    assert PAPER_TABLES["pick_place"][("skin", "novice")].time_mean == 85.4
    assert PAPER_TABLES["pour"][("pendant", "expert")].success_rate == 93.4
    # the paper's own means: 146.7 s keyboard against 85.4 s skin for novices
    assert paper_reduction("pick_place", "novice", "keyboard") == pytest.approx(41.8, abs=0.05)


def test_differences_are_said_plainly():
    figures = {
        "pour": {
            "reductions": {
                "novice/keyboard": {"paper": 40.8, "simulated": -12.0},
                "expert/pendant": {"paper": 45.3, "simulated": 44.0},
                "expert/keyboard": {"paper": 30.7, "simulated": float("nan")},
            }
        }
    }
    notes = _differences(figures)
    assert any("NOT faster than the keyboard" in n and "-12.0 %" in n for n in notes)
    assert any("no simulated figure" in n for n in notes)
    assert not any("pendant" in n for n in notes)  # within 15 points: nothing to say


@pytest.mark.slow
def test_tiny_report_end_to_end(tmp_path):
    out = tmp_path / "report"
    result = CliRunner().invoke(app, ["reproduce", "--out", str(out), "--size", "tiny"])
    assert result.exit_code == 0, result.output
    md = (out / "report.md").read_text()
    assert md.startswith("# wovenskin: the paper's evaluation, regenerated")
    for needle in ("Table I: pick-and-place", "What this report cannot show", "BiLSTM",
                   "wovenskin study simulate", "Simulated operators, not people"):  # fmt: skip
        assert needle in md, needle
    html = (out / "report.html").read_text()
    assert "data:image/png;base64," in html
    figures = json.loads((out / "figures.json").read_text())
    assert figures["size"] == "tiny" and figures["study"]["trials"] == 1
    cell = figures["study"]["pick_place"]["cells"]["keyboard/novice"]
    assert cell["trials"] == 1 and cell["time_mean"] > 0
    assert (out / "study" / "study.toml").read_text().count("simulated = true") == 1
    again = CliRunner().invoke(app, ["reproduce", "--out", str(out), "--size", "tiny"])
    assert again.exit_code != 0 and "overwrite" in again.output.lower()


def test_the_study_part_takes_the_hands_and_refuses_bad_ones_before_running(tmp_path):
    assert study.TINY.hands == HANDS == "independent"
    assert _command(study.TINY).endswith("--hands independent")
    sim = study.StudyConfig(**{**asdict(study.TINY), "hands": "sim"})
    assert _command(sim).endswith("--hands sim")
    with pytest.raises(ConfigError, match="hands must be 'independent' or 'sim'"):
        reproduce(tmp_path / "r", "tiny", hands="robot")
    assert not (tmp_path / "r").exists()
