"""The ``wovenskin`` command line (Typer + Rich): one small module per group of commands.

:mod:`~wovenskin.cli.app` holds the Typer apps, the consoles and the error handling every
command shares; the other modules register their commands on import.
"""

from __future__ import annotations

from wovenskin.cli.app import app

# Importing a command module registers its commands; `--help` lists them in this order.
# isort: off
from wovenskin.cli import skin, stream, bench, training, robot  # noqa: F401, E402
# isort: on


def main() -> None:
    app()


__all__ = ["app", "main"]
