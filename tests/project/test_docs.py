"""The repository stands alone: its README and docs link only what a clone contains."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from paths import REPO

ROOT = REPO
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
LINK = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_every_relative_link_stays_inside_the_repository(page: Path) -> None:
    text = page.read_text(encoding="utf-8")
    if page.name == "README.md":  # benchmarks.md may quote the commands it ran
        assert "../shared" not in text, "the README points outside the repository"
    for target in LINK.findall(text):
        if "://" in target or target.startswith("mailto:"):
            continue
        path = (page.parent / target).resolve()
        assert path.is_relative_to(ROOT.resolve()), f"{page.name}: {target} leaves the repository"
        assert path.exists(), f"{page.name}: {target} does not exist"


def test_the_docs_a_newcomer_needs_are_there() -> None:
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert "## The first ten minutes" in readme and "swipe_up` lowers the" in readme
    for name in ("gestures.md", "formats.md", "recording-format.md", "protocol.md"):
        assert (ROOT / "docs" / name).exists()
    formats = (ROOT / "docs" / "formats.md").read_text(encoding="utf-8")
    for key in ("event_start_s", "class_names", "groups", '"gesture": null', "metadata_json"):
        assert key in formats
    gestures = (ROOT / "docs" / "gestures.md").read_text(encoding="utf-8")
    from wovenskin.gestures import CLASS_NAMES

    assert all(f"`{name}`" in gestures for name in CLASS_NAMES)
