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
