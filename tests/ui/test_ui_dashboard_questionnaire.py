"""Tests of the page's questionnaires (wovenskin.ui.dashboard.questionnaire)."""

from __future__ import annotations

import pytest

from wovenskin.errors import WovenskinError
from wovenskin.study.definition import add_participant, init_study
from wovenskin.study.questionnaires import read_questionnaires
from wovenskin.ui.dashboard.questionnaire import SUS_ITEMS, TLX_ITEMS, forms, record_answers


@pytest.fixture()
def study(tmp_path):
    init_study(tmp_path / "s", "q")
    add_participant(tmp_path / "s", "P07", "expert")
    return tmp_path / "s"


def _answers(**over):
    message = {
        "participant": "P07", "task": "pour", "interface": "keyboard",
        "tlx": [10, 20, 30, 40, 50, 60], "sus": [5, 1, 5, 1, 5, 1, 5, 1, 5, 1],
    }  # fmt: skip
    return message | over


def test_forms_follow_the_study_definition(study, tmp_path):
    shown = forms(study)
    assert [i["key"] for i in shown["nasa_tlx"]] == [k for k, _, _ in TLX_ITEMS]
    assert len(shown["sus"]) == 10 and shown["sus"][0] == SUS_ITEMS[0]
    toml = study / "study.toml"
    toml.write_text(toml.read_text().replace('["nasa_tlx", "sus"]', '["sus"]'))
    assert set(forms(study)) == {"sus"}
    assert forms(None) == {} and forms(tmp_path / "nowhere") == {}


def test_answers_are_scored_into_the_study_folder(study):
    line = record_answers(study, _answers())
    assert "P07" in line and "TLX 35.0" in line and "SUS 100.0" in line
    rows, warnings = read_questionnaires(study)
    assert warnings == [] and len(rows) == 1
    row = rows[0]
    assert (row.participant, row.expertise, row.interface, row.task) == (
        "P07", "expert", "keyboard", "pour",
    )  # fmt: skip
    assert row.tlx_raw == pytest.approx(35.0) and row.sus_score == pytest.approx(100.0)
    record_answers(study, _answers(sus=None, task=""))  # TLX alone, about every task
    rows, _ = read_questionnaires(study)
    assert rows[1].sus is None and rows[1].task == ""


@pytest.mark.parametrize(
    ("over", "message"),
    [
        ({"participant": "P99"}, "no participant"),
        ({"interface": "joystick"}, "unknown interface"),
        ({"task": "juggling"}, "unknown task"),
        ({"tlx": [10, 20]}, "6 answers"),
        ({"tlx": [10, 20, 30, 40, 50, 101]}, "0-100"),
        ({"tlx": [10, 20, 30, 40, 50, "x"]}, "numbers"),
        ({"sus": [3] * 9 + [6]}, "1-5"),
        ({"sus": [3] * 9 + [2.5]}, "whole numbers"),
        ({"tlx": None, "sus": None}, "needs NASA-TLX or SUS"),
    ],
)
def test_bad_answers_are_one_line_and_write_nothing(study, over, message):
    with pytest.raises(WovenskinError, match=message):
        record_answers(study, _answers(**over))
    assert read_questionnaires(study) == ([], [])


def test_without_a_study_folder_nothing_is_recorded():
    with pytest.raises(WovenskinError, match="no study folder"):
        record_answers(None, _answers())
