"""``wovenskin --help``: flags are shown as flags (no ``<bool>`` as if they took a value)."""

from __future__ import annotations

from typer.testing import CliRunner

from wovenskin.cli import app


def test_flags_show_no_type_in_help() -> None:
    for args in (["--help"], ["view", "--help"], ["simulate", "--help"]):
        result = CliRunner().invoke(app, args, env={"COLUMNS": "140"})
        assert result.exit_code == 0, result.output
        assert "<bool>" not in result.output
        assert "--help" in result.output
    view = CliRunner().invoke(app, ["view", "--help"], env={"COLUMNS": "140"}).output
    assert "<float>" in view  # options that take a value keep their type


def test_version_prints_the_version() -> None:
    from wovenskin import __version__

    result = CliRunner().invoke(app, ["--version"])
    assert result.exit_code == 0 and result.output.strip() == f"wovenskin {__version__}"
