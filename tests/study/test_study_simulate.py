"""Simulated studies: real trials by simulated operators, recorded as a person's, reproducible."""

import json
from typing import get_args

import pytest

from wovenskin.errors import ConfigError
from wovenskin.operators.profiles import sample_profile
from wovenskin.study.definition import (
    HANDS_SOURCES,
    Participant,
    SimulatedHands,
    StudyDefinition,
    load_study,
    parse_study,
)
from wovenskin.study.reader import read_trials
from wovenskin.study.report import SIMULATED_BANNER, write_report
from wovenskin.study.simulate import (
    HANDS,
    SKINS,
    run_trial,
    simulate_study,
    simulated_participants,
    trial_objects,
)


def test_participants_alternate_novice_and_expert_with_their_own_profiles():
    people = simulated_participants(6, seed=3)
    assert [p.expertise for p, _ in people] == ["novice", "expert"] * 3
    assert len({profile.think_s for _, profile in people}) == 6
    assert all(profile.expertise == p.expertise for p, profile in people)


def test_pick_place_trials_move_one_object_in_turn_or_all():
    assert [trial_objects(n, "one") for n in (1, 2, 3, 4)] == [
        ("cube",),
        ("cylinder",),
        ("prism",),
        ("cube",),
    ]
    assert trial_objects(1, "all") is None
    with pytest.raises(ConfigError, match="'one' or 'all'"):
        trial_objects(1, "two")


@pytest.mark.slow
def test_an_expert_seats_the_cube_with_the_keyboard_and_the_same_seed_repeats_it(tmp_path):
    person = Participant("S02", "expert")
    profile = sample_profile("S02", "expert", 5)
    runs = [
        run_trial(tmp_path / name, person, profile, "pick_place", "keyboard", 1, time_limit_s=200)
        for name in ("a", "b")
    ]
    first, second = (r.summary for r in runs)
    assert first.outcome == "success", runs[0].gave_up
    assert first.measures["objects_seated"] == 1.0
    assert first.commands >= 6 and first.commands_by_kind["gripper"] >= 2
    assert (first.duration_s, first.commands) == (second.duration_s, second.commands)
    trials, warnings = read_trials(tmp_path / "a")
    assert not warnings and trials[0].outcome == "success"


@pytest.mark.slow
def test_a_whole_small_study_is_written_labelled_simulated(tmp_path):
    study, runs = simulate_study(
        tmp_path / "s", participants=1, trials=1, tasks=("pour",), interfaces=("pendant",),
        time_limit_s=8.0,
    )  # fmt: skip
    assert study.simulated and not study.synthetic
    assert load_study(tmp_path / "s").simulated
    assert (tmp_path / "s" / "SIMULATED.md").is_file() and (tmp_path / "s" / "plan.csv").is_file()
    operators = json.loads((tmp_path / "s" / "operators.json").read_text())
    assert operators["simulated"] and operators["operators"][0]["expertise"] == "novice"
    (run,) = runs
    assert run.summary.outcome == "timeout"  # 8 s cannot pour: the limit ends the trial
    assert run.summary.duration_s == pytest.approx(8.0, abs=0.05)
    report = write_report(tmp_path / "s")
    assert SIMULATED_BANNER in report.markdown.read_text() and not report.synthetic


def test_refuses_an_interface_it_has_no_hand_for_and_a_full_folder(tmp_path):
    with pytest.raises(ConfigError, match="skin_registered"):
        simulate_study(tmp_path / "x", interfaces=("skin_registered",))
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "f").write_text("x")
    with pytest.raises(Exception, match="full"):
        simulate_study(tmp_path / "full", participants=1, trials=1)


def test_the_hands_are_checked_before_anything_is_written(tmp_path):
    assert tuple(HANDS_SOURCES) == get_args(SimulatedHands) == tuple(SKINS)
    assert HANDS == "independent"
    with pytest.raises(ConfigError, match="hands must be 'independent' or 'sim', got 'robot'"):
        simulate_study(tmp_path / "x", participants=1, trials=1, hands="robot")
    assert not (tmp_path / "x").exists()
    with pytest.raises(ValueError, match="only a simulated study"):
        StudyDefinition(name="real", hands="sim")
    with pytest.raises(ConfigError, match="hands"):
        parse_study('name = "s"\nsimulated = true\nhands = "robot"\n')


@pytest.mark.parametrize("hands", ["independent", "sim"])
def test_a_skin_trial_records_whose_hands_touched(tmp_path, hands):
    folder = tmp_path / hands
    study, (run,) = simulate_study(
        folder, participants=1, trials=1, tasks=("pour",), interfaces=("skin",),
        time_limit_s=2.0, hands=hands,
    )  # fmt: skip
    assert study.hands == hands and load_study(folder).hands == hands
    assert f'hands = "{hands}"' in (folder / "study.toml").read_text()
    operators = json.loads((folder / "operators.json").read_text())
    assert operators["hands"] == hands and operators["hands_source"] == HANDS_SOURCES[hands]
    assert run.summary.outcome == "timeout" and run.summary.commands >= 1
    report = write_report(folder).markdown.read_text()
    assert f"Simulated hands: `{hands}`" in report and HANDS_SOURCES[hands] in report
