"""study.toml: the template, participants added, bad files as one ConfigError line."""

from __future__ import annotations

import pytest

from wovenskin.errors import ConfigError
from wovenskin.outputs import OutputExistsError
from wovenskin.study.definition import (
    StudyDefinition,
    add_participant,
    init_study,
    load_study,
    parse_study,
)


def test_the_template_is_a_valid_study_with_the_papers_conditions(tmp_path):
    path = init_study(tmp_path, "pilot")
    study = load_study(tmp_path)
    assert study.name == "pilot" and study.participants == ()
    assert study.tasks == ("pick_place", "pour")
    assert study.interfaces == ("skin", "keyboard", "pendant")
    assert "# " in path.read_text()  # commented
    with pytest.raises(OutputExistsError):
        init_study(tmp_path)


def test_add_participant_keeps_comments_and_order(tmp_path):
    init_study(tmp_path, 'quote " and \\ back')
    add_participant(tmp_path, "P01", "novice", notes="left-handed")
    study = add_participant(tmp_path, "P02", "expert")
    assert [(p.id, p.expertise) for p in study.participants] == [
        ("P01", "novice"),
        ("P02", "expert"),
    ]
    assert study.participants[0].notes == "left-handed"
    assert study.name == 'quote " and \\ back'
    assert "# Participants" in (tmp_path / "study.toml").read_text()


def test_add_participant_refuses_duplicates_and_bad_expertise_leaving_the_file(tmp_path):
    init_study(tmp_path)
    add_participant(tmp_path, "P01", "novice")
    before = (tmp_path / "study.toml").read_text()
    with pytest.raises(ConfigError, match="already"):
        add_participant(tmp_path, "P01", "expert")
    with pytest.raises(ConfigError, match="expertise"):
        add_participant(tmp_path, "P02", "guru")
    with pytest.raises(ConfigError, match="participant id"):
        add_participant(tmp_path, "../evil", "novice")
    assert (tmp_path / "study.toml").read_text() == before


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        ('name = "s"\ncolour = "red"\n', "unknown setting 'colour'"),
        ('name = "s"\n[[participants]]\nid = "P1"\nexpertise = "guru"\n', "expertise"),
        ('name = "s"\ntasks = ["juggle"]\n', "tasks.0"),
        ('name = "s"\ninterfaces = ["skin", "skin"]\n', "each value once"),
        ('name = "s"\ntrials_per_condition = 0\n', "trials_per_condition"),
        (
            'name = "s"\n[[participants]]\nid = "P1"\nexpertise = "novice"\n'
            '[[participants]]\nid = "P1"\nexpertise = "expert"\n',
            "given twice",
        ),
        ("name = ", "not valid TOML"),
    ],
)
def test_a_bad_study_file_is_one_config_error_line(text, needle):
    with pytest.raises(ConfigError, match=needle) as info:
        parse_study(text)
    assert "\n" not in str(info.value)


def test_a_missing_study_file_says_how_to_make_one(tmp_path):
    with pytest.raises(ConfigError, match="study init"):
        load_study(tmp_path)


def test_participant_lookup():
    study = StudyDefinition(name="s")
    with pytest.raises(ConfigError, match="no participant"):
        study.participant("P9")
