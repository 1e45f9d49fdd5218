"""``wovenskin bench adapt``'s pieces that need no training: its gestures and its F1 by class."""

from __future__ import annotations

from paths import REPO

from wovenskin.bench.adapt import CUSTOM, class_f1
from wovenskin.control.mapping import ActionMapping
from wovenskin.recognition.arbiter import CommandChange
from wovenskin.recognition.event_scoring import score_commands

EXAMPLE = REPO / "examples" / "three_finger_swipes.toml"


def test_the_bench_measures_the_documented_example():
    mapping = ActionMapping.load(EXAMPLE)
    assert {g.name: g for g in CUSTOM} == mapping.custom


def test_f1_of_some_classes_counts_their_hits_misses_and_false_moves():
    commands = [
        CommandChange(1.1, "swipe_up_3f", "dwell"), CommandChange(1.3, None, "lift-off"),
        CommandChange(3.1, "swipe_up_2f", "dwell"), CommandChange(3.3, None, "lift-off"),
        CommandChange(6.0, "swipe_up", "dwell"), CommandChange(6.2, None, "lift-off"),
    ]  # fmt: skip
    scores = score_commands(
        commands, [1.0, 3.0, 5.0], [1.5, 3.5, 5.5], ["swipe_up_3f", "swipe_up_3f", "push"], 10.0,
        known=["swipe_up_3f"],
    )  # fmt: skip
    assert class_f1(scores, ["swipe_up_3f"]) == 2 * 1 / (2 * 1 + 0 + 1)
    assert class_f1(scores, ["push", "swipe_up", "swipe_up_2f"]) == 0.0  # 2 false, 1 missed
