"""NASA-TLX raw and SUS scoring against worked examples; questionnaires.csv round trip."""

from __future__ import annotations

import pytest

from wovenskin.errors import DataError
from wovenskin.study.questionnaires import (
    QuestionnaireRow,
    read_questionnaires,
    record_questionnaire,
    sus_score,
    tlx_raw,
)


@pytest.mark.parametrize(
    ("answers", "score"),
    [
        ((3,) * 10, 50.0),  # all neutral
        ((5, 1) * 5, 100.0),  # best
        ((1, 5) * 5, 0.0),  # worst
        ((4, 2) * 5, 75.0),
        # odd items (4,5,4,4,3) give 3+4+3+3+2 = 15, even (2,1,2,1,2) give 3+4+3+4+3 = 17
        ((4, 2, 5, 1, 4, 2, 4, 1, 3, 2), 80.0),
    ],
)
def test_sus_scores_worked_examples(answers, score):
    assert sus_score(answers) == score


def test_tlx_raw_is_the_mean_of_six_subscales():
    assert tlx_raw((50, 20, 35, 10, 45, 0)) == pytest.approx(160 / 6)
    assert tlx_raw((100,) * 6) == 100


@pytest.mark.parametrize(
    ("fn", "answers", "needle"),
    [
        (sus_score, (3,) * 9, "10 answers"),
        (sus_score, (3,) * 9 + (6,), "1-5"),
        (sus_score, (3,) * 9 + (2.5,), "whole"),
        (tlx_raw, (50,) * 5 + (101,), "0-100"),
        (tlx_raw, (50,) * 5 + (float("nan"),), "0-100"),
    ],
)
def test_bad_answers_are_data_errors(fn, answers, needle):
    with pytest.raises(DataError, match=needle):
        fn(answers)


def test_answers_round_trip_through_questionnaires_csv(tmp_path):
    record_questionnaire(
        tmp_path, QuestionnaireRow("P01", "novice", "skin", "", (50, 20, 35, 10, 45, 0), None)
    )
    record_questionnaire(
        tmp_path, QuestionnaireRow("P01", "novice", "pendant", "pour", None, (4, 2) * 5)
    )
    with (tmp_path / "questionnaires.csv").open("a") as f:
        f.write("P02,expert,skin,,1,2")  # torn
    rows, warnings = read_questionnaires(tmp_path)
    assert [(r.interface, r.tlx_raw, r.sus_score) for r in rows] == [
        ("skin", pytest.approx(160 / 6), None),
        ("pendant", None, 75.0),
    ]
    assert "torn" in warnings[0]
    with pytest.raises(DataError, match="needs"):
        record_questionnaire(tmp_path, QuestionnaireRow("P01", "novice", "skin", "", None, None))
