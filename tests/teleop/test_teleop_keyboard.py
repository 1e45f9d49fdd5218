"""Tests of wovenskin.teleop.keyboard: keys held move the simulated arm through the session
and stop on release; the terminal's auto-repeat stands in for key-up; the key map."""

from __future__ import annotations

import numpy as np
import pytest
from session_helpers import at, idle_session, run_traced

from wovenskin.control.mapping import ActionMapping
from wovenskin.control.session_inputs import InputEvent
from wovenskin.errors import ConfigError
from wovenskin.teleop.keyboard import (
    DEFAULT_LAYOUT,
    KeyBinding,
    Keyboard,
    TerminalKeyboard,
    check_layout,
    key_map,
)


class Driven:
    """Calls ``schedule``'s functions at their session times, then polls ``device``."""

    def __init__(self, device, schedule) -> None:
        self.device = device
        self.schedule = sorted(schedule, key=lambda item: item[0])

    def poll(self, t: float) -> list[InputEvent]:
        while self.schedule and self.schedule[0][0] <= t:
            self.schedule.pop(0)[1]()
        return self.device.poll(t)


def test_a_held_key_moves_the_arm_and_its_release_stops_it(tmp_path) -> None:
    keys = Keyboard()
    schedule = [(1.5, lambda: keys.key_down("D")), (1.7, lambda: keys.key_down("d")),
                (2.5, lambda: keys.key_up("d")), (2.8, lambda: keys.key_down("g"))]  # fmt: skip
    session = idle_session(tmp_path, inputs=[Driven(keys, schedule)])
    records = run_traced(session)
    start, end, later = at(records, 1.5), at(records, 2.6), at(records, 3.5)
    moved = end["tcp"] - start["tcp"]
    tool_y = start["R"][:, 1]  # d is swipe_right: translate +y of the tool
    assert moved @ tool_y > 0.98 * np.linalg.norm(moved) > 0.04
    assert np.linalg.norm(later["tcp"] - end["tcp"]) < 0.003 and later["speed"] < 1e-4
    log = [(c.t, c.source, c.name, c.kind) for c in session.command_log]
    assert log == [
        (1.5, "keyboard", "swipe_right", "press"),
        (2.8, "keyboard", "toggle", "gripper"),
    ]
    assert session.gripper_closed and keys.down == frozenset({"g"})


def test_a_terminal_key_is_held_while_its_auto_repeat_lasts() -> None:
    now = [0.0]
    keys = TerminalKeyboard(initial_s=0.5, repeat_s=0.1, clock=lambda: now[0])
    assert keys.feed("wq ") == "q "  # unbound keys are handed back to the view
    assert [e.kind for e in keys.poll(0.0)] == ["press"]
    for step in range(1, 12):  # the repeat starts after 0.4 s, every 30 ms
        now[0] = 0.4 + 0.03 * step
        keys.feed("w")
        assert keys.poll(now[0]) == [] and keys.down == frozenset({"w"})
    now[0] += 0.09
    assert keys.poll(now[0]) == []
    now[0] += 0.02  # no repeat for 0.11 s: the key came up
    events = keys.poll(now[0])
    assert [(e.kind, e.name, e.counts) for e in events] == [("release", "pinch_in_2f", False)]
    keys.feed("s")  # a tap: held for initial_s
    now[0] += 0.45
    assert [e.kind for e in keys.poll(now[0])] == ["press"]
    now[0] += 0.1
    assert [e.kind for e in keys.poll(now[0])] == ["release"]
    with pytest.raises(ConfigError, match="timeouts"):
        TerminalKeyboard(initial_s=0.1, repeat_s=0.2)


def test_the_key_map_shows_every_action_of_the_vocabulary() -> None:
    rows = key_map()
    assert len(rows) == 15 and len({r.key for r in rows}) == 15
    mapping = ActionMapping.load()
    assert {r.gesture for r in rows[:-1]} == set(mapping.actions)  # the 14 gestures' actions
    assert KeyBinding("w", "pinch_in_2f", "translate +x") in rows
    assert KeyBinding("h", "pinch_out_5f", "pose home") in rows
    assert rows[-1].key == "g" and "gripper" in rows[-1].action
    assert {r.key for r in rows}.isdisjoint({" ", "q"})  # the view's stop and quit keys


def test_layouts_are_checked() -> None:
    assert check_layout({"W": "push"}) == {"w": "push"}
    for layout in ({"ww": "push"}, {"w": "wave"}, {"g": "push"}, {"w": "invalid"},
                   {"w": "push", "W": "push"}):  # fmt: skip
        with pytest.raises(ConfigError, match="key"):
            check_layout(layout)
    keys = Keyboard({"x": "push"})
    assert not keys.key_down("w") and keys.key_down("x") and keys.key_down("x")
    assert [e.name for e in keys.poll(0.0)] == ["push"]  # the repeat is no second press
    keys.release_all()
    assert [e.kind for e in keys.poll(0.0)] == ["release"] and keys.down == frozenset()
    assert len(DEFAULT_LAYOUT) == 14
