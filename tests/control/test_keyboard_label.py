"""A held key shows what it does: pressing W says "translate +x (keyboard)" (its action
in the mapping), not the gesture it stands for ("pinch_in_2f")."""

from __future__ import annotations

from wovenskin.runtime.session import open_session
from wovenskin.teleop.keyboard import DEFAULT_LAYOUT, Keyboard


def test_a_held_key_is_shown_as_its_action(tmp_path):
    keyboard = Keyboard()
    session = open_session("none:speed=0", "sim", poses=tmp_path / "poses.toml")
    session.add_input(keyboard)
    seen: list[tuple[str | None, str]] = []
    try:
        keyboard.key_down("w")
        session.run(seconds=0.5)
        seen.append((session.state.held, str(session.state.action)))
    finally:
        session.close()
    held, action = seen[0]
    gesture = DEFAULT_LAYOUT["w"]  # the gesture W stands for (pinch_in_2f)
    assert held == "translate +x (keyboard)", held
    assert gesture not in action and "translate +x" in action, action
