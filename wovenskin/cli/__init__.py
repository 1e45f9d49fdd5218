"""The ``wovenskin`` command line (Typer + Rich): one small module per group of commands.

:mod:`~wovenskin.cli.app` holds the Typer apps, the consoles and the error handling every
command shares; the other modules register their commands on import.
"""

from __future__ import annotations

from wovenskin.cli.app import app

# Importing a command module registers its commands; `--help` lists them in this order.
# isort: off
from wovenskin.cli import skin, stream, bench, dataset, training, adapt, robot, reproduce, ros2  # noqa: F401, E402
from wovenskin.cli.study import study_app  # noqa: E402
# isort: on

app.add_typer(study_app, name="study")


def main() -> None:
    app()


__all__ = ["app", "main"]
