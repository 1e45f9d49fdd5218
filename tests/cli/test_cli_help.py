"""``wovenskin --help``: flags are shown as flags (no ``<bool>`` as if they took a value)."""

from __future__ import annotations

import subprocess
import sys

from typer.testing import CliRunner

from wovenskin.cli import app


def test_flags_show_no_type_in_help() -> None:
    for args in (["--help"], ["view", "--help"], ["simulate", "--help"]):
        result = CliRunner().invoke(app, args, env={"COLUMNS": "140"})
        assert result.exit_code == 0, result.output
        assert "<bool>" not in result.output
        assert "--help" in result.output
    view = CliRunner().invoke(app, ["view", "--help"], env={"COLUMNS": "140"}).output
    assert "<float" in view  # options that take a value keep their type (and range)


def test_version_prints_the_version() -> None:
    from wovenskin import __version__

    result = CliRunner().invoke(app, ["--version"])
    assert result.exit_code == 0 and result.output.strip() == f"wovenskin {__version__}"


def test_the_command_line_loads_no_pipeline_stage_until_a_command_runs() -> None:
    """Every command starts a fresh Python: importing the command line must not import the
    simulator, training, torch, MuJoCo or ONNX Runtime (seconds of start-up for each
    subprocess a test or a script runs; `wovenskin --help` took 2.6 s when it did)."""
    # Settings dataclasses that only import ``wovenskin.errors`` may be read for the
    # options' defaults (each default written once): they cost nothing to import.
    settings_only = ("wovenskin.training", "wovenskin.training.adapt_settings")
    code = (
        "import sys, wovenskin.cli\n"
        "heavy = ('torch', 'mujoco', 'onnxruntime', 'scipy', 'wovenskin.sim',"
        " 'wovenskin.training', 'wovenskin.runtime', 'wovenskin.recognition')\n"
        f"light = {settings_only!r}\n"
        "print(sorted(m for m in sys.modules if m.startswith(heavy) and m not in light))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", out.stdout
