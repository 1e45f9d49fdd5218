"""The README leads a newcomer and quotes only figures docs/benchmarks.md holds."""

from __future__ import annotations

import re

from paths import REPO

ROOT = REPO
README = (ROOT / "README.md").read_text(encoding="utf-8")
BENCHMARKS = (ROOT / "docs" / "benchmarks.md").read_text(encoding="utf-8")
FIGURE = re.compile(r"\d[\d,]*(?:\.\d+)?(?: ?(?:%|ms|s|Hz))?(?: of \d[\d,]*)?")


def _section(title: str) -> str:
    start = README.index(f"## {title}")
    end = README.find("\n## ", start + 1)
    return README[start : end if end >= 0 else None]


def test_it_opens_with_the_project_the_two_commands_and_the_first_ten_minutes():
    opening = README[: README.index("## ")]
    assert "make run" in opening and "make test" in opening
    titles = re.findall(r"^## (.+)$", README, flags=re.MULTILINE)
    assert titles[:2] == ["The first ten minutes", "Using the command line afterwards"]
    assert len(README.splitlines()) <= 150  # reference material lives in docs/


def test_it_says_how_to_reach_the_command_and_what_needs_pytorch():
    cli = _section("Using the command line afterwards")
    assert "source .venv/bin/activate" in cli and ".venv/bin/wovenskin" in cli
    assert "pip install -e '.[train]'" in cli and "PyTorch" in cli


def test_every_figure_it_quotes_is_one_benchmarks_md_holds():
    table = [line for line in _section("Where it stands").splitlines() if line.startswith("| ")]
    quoted = []
    for row in table[1:]:  # past the header (the rule line starts "|-")
        figures = row.split("|")[2]
        quoted += [f.strip() for f in FIGURE.findall(figures)]
    assert len(quoted) >= 8
    missing = [f for f in quoted if f not in BENCHMARKS]
    assert not missing, f"README figures not in docs/benchmarks.md: {missing}"
