"""Running the ``wovenskin`` command line in a test: one runner, and the check that an
error a user can cause is one line on stderr with exit status 2."""

from __future__ import annotations

from typer.testing import CliRunner

from wovenskin.cli import app

runner = CliRunner()


def invoke(*args: object):
    """``wovenskin ARGS...`` in this process; the click ``Result``."""
    return runner.invoke(app, [str(a) for a in args])


def one_line_error(result, message: str) -> None:
    """``result`` ended with exit status 2 and one line on stderr holding ``message``."""
    assert result.exit_code == 2, result.output
    assert message in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and "Traceback" not in result.output
