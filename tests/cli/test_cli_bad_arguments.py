"""Bad arguments a newcomer gives: each is one line naming the user's own argument, exit 2,
no traceback, nothing written (a folder where a file belongs, a missing parent folder, an
unknown study task or interface)."""

from __future__ import annotations

import pytest
from cli_helpers import invoke, one_line_error


@pytest.mark.parametrize("command", ["replay", "eval-stream"])
def test_a_folder_given_as_a_stream_is_named_as_a_folder(command, tmp_path) -> None:
    one_line_error(invoke(command, tmp_path), f"{tmp_path}: is a folder")


def test_a_missing_parent_folder_is_named_never_a_temporary_file(tmp_path) -> None:
    out = tmp_path / "nodir" / "s.npz"
    result = invoke("simulate", "--out", out, "--seconds", "1")
    one_line_error(result, "no such folder")
    assert str(out) in result.stderr and ".partial" not in result.stderr
    assert not out.parent.exists()


@pytest.mark.parametrize(
    ("option", "value", "message"),
    [("--task", "bogus", "--task 'bogus'"), ("--interface", "mouse", "--interface 'mouse'")],
)
def test_study_simulate_refuses_an_unknown_task_or_interface_first(
    option, value, message, tmp_path
) -> None:
    result = invoke("study", "simulate", tmp_path / "s", option, value)
    one_line_error(result, message)
    assert "roughly" not in result.output  # refused before the estimate
    assert not (tmp_path / "s").exists()


# Every command that reads or writes a path the user names, with each kind of bad path:
# missing, a folder where a file belongs (or a file where a folder belongs), and a path
# under a file (its folder cannot exist).  Each ends in one line naming the user's own
# argument, exit 2, no traceback.
BAD_PATHS = {
    "info": [["nowhere.npz"], ["."], ["afile/x"]],
    "convert": [["nowhere.npz", "out.npz"], ["afile", "out.npz"]],
    "replay": [["nowhere.npz"], ["afile/x"]],
    "eval-stream": [["nowhere.npz"], ["."]],
    "study init": [["afile/x"]],
    "study plan": [["nowhere"], ["afile"]],
    "study report": [["nowhere"], ["afile"]],
    "study synthetic": [["afile/x"]],
    "simulate": [["--out", "afile/x.npz", "--seconds", "1"]],
    "record": [["--out", "afile/x.wsrec"]],
    "dataset": [["--out", "afile/x"]],
}


@pytest.mark.parametrize(
    ("command", "args"),
    [(command, args) for command, cases in BAD_PATHS.items() for args in cases],
    ids=lambda value: value if isinstance(value, str) else " ".join(value),
)
def test_a_bad_path_is_one_line_naming_it(command, args, tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)
    (tmp_path / "afile").write_bytes(b"")
    result = invoke(*command.split(), *args)
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    named = [a for a in args if not a.startswith("--") and a not in ("1", "out.npz")][0]
    assert named.split("/")[0] in lines[0], lines[0]
    assert ".partial" not in lines[0]


def _numeric_options() -> list[tuple[str, str, float, float, type]]:
    """``(command, option, least, most, int or float)`` for every numeric option."""
    import typing

    import typer

    from wovenskin.cli import app

    def walk(command, path):
        subs = getattr(command, "commands", None)
        if subs:
            for name, sub in subs.items():
                yield from walk(sub, [*path, name])
        else:
            yield " ".join(path), command

    found = []
    for path, command in walk(typer.main.get_command(app), []):
        for param in command.params:
            annotation = param.type_descriptor.annotation
            kinds = set(typing.get_args(annotation) or (annotation,)) - {type(None)}
            if kinds and kinds <= {int, float}:
                found.append((path, param.opts[0], param.min, param.max, kinds.pop()))
    return found


NUMERIC_OPTIONS = _numeric_options()


def test_every_numeric_option_declares_its_range() -> None:
    assert len(NUMERIC_OPTIONS) > 100
    unbounded = [f"{c} {o}" for c, o, least, most, _ in NUMERIC_OPTIONS if None in (least, most)]
    assert not unbounded, f"numeric options without a declared range: {unbounded}"


def _outside(least: float, most: float, kind: type) -> list[str]:
    below = least - 1 if kind is int else least - max(1.0, abs(least))
    above = most + 1 if kind is int else most * 10 + 1
    values = [str(int(below) if kind is int else below), str(int(above) if kind is int else above)]
    return [*values, "nan", "abc"]


@pytest.mark.parametrize(
    ("command", "option", "value"),
    [
        (command, option, value)
        for command, option, least, most, kind in NUMERIC_OPTIONS
        for value in _outside(least, most, kind)
    ],
)
def test_an_out_of_range_number_is_one_line_naming_it(command, option, value) -> None:
    """Refused before the command runs: exit 2, one line with the user's own option and
    value, no traceback."""
    result = invoke(*command.split(), f"{option}={value}")
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert f"{option} {value}" in lines[0], lines[0]
