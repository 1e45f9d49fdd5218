"""StudyTrials: a block of trials on a real task session, ended by the experimenter's keys."""

from __future__ import annotations

import csv
import json

from wovenskin.runtime import open_session
from wovenskin.study.session import StudyTrials, trial_seed
from wovenskin.teleop.keyboard import Keyboard


def test_seeds_are_stable_and_differ_by_trial():
    assert trial_seed("P01", "pour", 1) == trial_seed("P01", "pour", 1)
    assert len({trial_seed("P01", "pour", n) for n in range(1, 6)}) == 5
    assert trial_seed("P01", "pour", 1) != trial_seed("P02", "pour", 1)


def test_keys_end_trials_and_the_block_quits_the_session(tmp_path):
    keyboard = Keyboard()
    hooks = []
    # ticks begin after the skin calibrates (0.5 s); w, d: moves; y, n, x: verdicts
    script = {1.3: "w", 1.6: "y", 1.8: "n", 2.0: "d", 2.2: "x"}

    def on_tick(session):
        block = hooks[0]
        block.on_tick(session)
        for at, key in script.items():
            if abs(session.now - at) < 1e-9 and not block.key(key):
                keyboard.key_down(key)

    session = open_session("none:speed=0", task="pick_place", inputs=[keyboard], on_tick=on_tick)
    block = StudyTrials(session, session.task, tmp_path, "P01", "novice", "keyboard", 3)
    hooks.append(block)
    try:
        result = session.run(seconds=5.0)
    finally:
        block.close()
        session.close()
    assert block.done and result.ended == "all 3 trials done"
    assert [s.outcome for s in block.summaries] == ["success", "give_up", "aborted"]
    assert [s.commands for s in block.summaries] == [1, 0, 1]
    assert block.key("q") is False and block.keys("yqz") == "qz"
    rows = list(csv.DictReader((tmp_path / "trials.csv").open()))
    assert [r["trial"] for r in rows] == ["1", "2", "3"]
    first = json.loads((tmp_path / "trials/P01/pick_place-keyboard-1/trial.json").read_text())
    assert first["commands_by_kind"]["key"] == 1 and first["outcome"] == "success"
