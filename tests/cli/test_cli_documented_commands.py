"""Every ``wovenskin ...`` command line the README and docs/ show parses: its options exist
and its values lie in their declared ranges (parsed, never run)."""

from __future__ import annotations

import re
import shlex

import pytest
import typer
from paths import REPO

from wovenskin.cli import app

_BLOCK = re.compile(r"```(?:bash|sh|console|shell)?\n(.*?)```", re.S)


def _documented() -> list[tuple[str, str]]:
    found = []
    for path in [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]:
        for block in _BLOCK.findall(path.read_text()):
            for line in block.replace("\\\n", " ").splitlines():
                line = line.strip().removeprefix("$ ").removeprefix(".venv/bin/")
                if not line.startswith("wovenskin ") or "..." in line:
                    continue
                for end in (" #", " | ", " && ", " > ", " 2>"):
                    line = line.split(end)[0]
                found.append((path.name, line))
    return found


DOCUMENTED = _documented()


def test_the_docs_show_commands() -> None:
    assert len(DOCUMENTED) > 50


@pytest.mark.parametrize(("doc", "line"), DOCUMENTED, ids=[line for _, line in DOCUMENTED])
def test_a_documented_command_line_parses(doc: str, line: str) -> None:
    command = typer.main.get_command(app)
    words, path = shlex.split(line)[1:], ["wovenskin"]
    while hasattr(command, "commands") and words and words[0] in command.commands:
        path.append(words[0])
        command = command.commands[words.pop(0)]
    if hasattr(command, "commands"):  # a group shown alone: its help
        return
    try:
        command.make_context(" ".join(path), words)
    except Exception as exc:
        if type(exc).__name__ == "Exit":  # --help, --version
            return
        shown = exc.format_message() if hasattr(exc, "format_message") else str(exc)
        pytest.fail(f"{doc}: {line}: {shown}")
