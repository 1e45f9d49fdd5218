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
