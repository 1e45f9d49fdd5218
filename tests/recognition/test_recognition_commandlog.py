"""Tests of wovenskin.recognition.commandlog: the FORMATS.md command log, written and read."""

from __future__ import annotations

import io
import json

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wovenskin.recognition.arbiter import CommandChange
from wovenskin.recognition.commandlog import (
    Command,
    changes_only,
    commands_table,
    format_command_log,
    parse_command_log,
    read_command_log,
    write_command_log,
)


def test_format_writes_one_json_object_per_change() -> None:
    changes = [
        CommandChange(12.345, "swipe_up", "dwell"),
        CommandChange(12.9000000001, None, "lift-off"),
    ]
    text = format_command_log(changes)
    assert text == '{"t": 12.345, "gesture": "swipe_up"}\n{"t": 12.9, "gesture": null}\n'
    assert format_command_log([]) == ""


def test_lines_that_change_nothing_are_left_out() -> None:
    commands = [
        Command(0.5, None),  # the command is already none
        Command(1.0, "push"),
        Command(1.5, "push"),
        Command(2.0, "swipe_up"),
        Command(2.5, None),
        Command(3.0, None),
    ]
    assert changes_only(commands) == [
        Command(1.0, "push"),
        Command(2.0, "swipe_up"),
        Command(2.5, None),
    ]


def test_writer_refuses_bad_entries() -> None:
    with pytest.raises(ValueError, match="must not decrease"):
        format_command_log([Command(2.0, "push"), Command(1.0, None)])
    with pytest.raises(ValueError, match="finite number"):
        format_command_log([Command(float("nan"), "push")])
    with pytest.raises(ValueError, match="a name or None"):
        format_command_log([Command(1.0, 3)])  # type: ignore[arg-type]


def test_reader_ignores_lines_that_are_not_commands() -> None:
    text = "\n".join(
        [
            '{"t": 1.0, "gesture": "push"}',
            "",
            "# a comment",
            "not json at all",
            "[1, 2]",
            '{"t": 2.0}',
            '{"gesture": "push"}',
            '{"t": "soon", "gesture": "push"}',
            '{"t": NaN, "gesture": "push"}',
            '{"t": true, "gesture": "push"}',
            '{"t": 2.5, "gesture": 7}',
            '{"t": 3, "gesture": null, "reason": "lift-off"}',
            '{"t": 4.0, "gesture": null}',
        ]
    )
    assert parse_command_log(text) == [Command(1.0, "push"), Command(3.0, None), Command(4.0, None)]


def test_file_round_trip(tmp_path) -> None:
    path = tmp_path / "log.jsonl"
    commands = [Command(1.25, "circle_cw_2f"), Command(2.5, "push"), Command(3.0, None)]
    write_command_log(path, commands)
    assert read_command_log(path) == commands
    buffer = io.StringIO()
    write_command_log(buffer, commands)
    assert buffer.getvalue() == path.read_text()
    with pytest.raises(FileNotFoundError, match="no such file"):
        read_command_log(tmp_path / "missing.jsonl")
    binary = tmp_path / "binary.jsonl"
    binary.write_bytes(b"\xff\xfe\x00")
    with pytest.raises(ValueError, match="not a text file"):
        read_command_log(binary)


names = st.sampled_from(["swipe_up", "push", "pinch_in_5f", None])


@settings(max_examples=100, deadline=None)
@given(steps=st.lists(st.tuples(st.floats(0, 10, allow_nan=False), names), max_size=40))
def test_round_trip_keeps_every_change(steps) -> None:
    t, commands = 0.0, []
    for dt, gesture in steps:
        t += dt
        commands.append(Command(round(t, 6), gesture))
    text = format_command_log(commands)
    back = parse_command_log(text)
    assert back == changes_only(commands)
    for line in text.splitlines():
        assert set(json.loads(line)) == {"t", "gesture"}
    # Each consecutive pair differs (a line only when the command changes).
    assert all(a.gesture != b.gesture for a, b in zip(back, back[1:], strict=False))
    assert not back or back[0].gesture is not None


def test_commands_table_lists_reasons() -> None:
    table = commands_table(
        [CommandChange(1.0, "push", "dwell"), CommandChange(2.0, None, "lift-off")]
    )
    assert table.row_count == 2 and len(table.columns) == 3
    assert len(commands_table([Command(1.0, "push")]).columns) == 2
