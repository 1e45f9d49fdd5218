"""Small texts of the dashboard page: the page rate is never "Infinity Hz", the Skin and
Robot fields are not cut to a fixed width, and the tracks sit where the contacts are drawn.

The page's functions are taken from dashboard.js and run in Node (no browser needed)."""

from __future__ import annotations

import json
import re
import shutil
import subprocess

import pytest
from paths import REPO

STATIC = REPO / "wovenskin" / "ui" / "dashboard" / "static"


def js_function(name: str) -> str:
    """The source of a top-level ``function name(...) { ... }`` of dashboard.js."""
    text = (STATIC / "dashboard.js").read_text()
    found = re.search(rf"^function {name}\(.*?^}}$", text, re.S | re.M)
    assert found, f"dashboard.js has no top-level function {name}"
    return found.group(0)


@pytest.mark.skipif(shutil.which("node") is None, reason="needs Node.js")
def test_the_page_rate_is_finite_or_unknown() -> None:
    cases = [[], [5.0], [7.0, 7.0], [7.0, 7.0, 7.0], [0.0, 500.0, 1000.0], [0.0, 0.0, 100.0]]
    script = (
        js_function("ratePerSecond")
        + f"\nconsole.log(JSON.stringify({json.dumps(cases)}.map(ratePerSecond)));"
    )
    out = subprocess.run(["node", "-e", script], capture_output=True, text=True, check=True)
    assert json.loads(out.stdout) == [None, None, None, None, 2.0, 20.0]


def test_the_skin_and_robot_fields_have_no_fixed_width() -> None:
    html = (STATIC / "index.html").read_text()
    for field in ("skin-spec", "robot-spec"):
        tag = re.search(rf'<label class="spec">\w+ <input id="{field}"[^>]*>', html)
        assert tag and "size=" not in tag.group(0), f"{field} is not a growing spec field"
    css = (STATIC / "dashboard.css").read_text()
    assert re.search(r"label\.spec input \{[^}]*flex:1", css)


@pytest.mark.skipif(shutil.which("node") is None, reason="needs Node.js")
def test_tracks_are_drawn_in_the_contacts_coordinates_with_their_velocity() -> None:
    tracks = [
        {"id": 3, "row": 0.0, "col": 2.0, "v_row": 0.0, "v_col": 10.0, "merged": False},
        {"id": 4, "row": 4.5, "col": 4.5, "v_row": -2.0, "v_col": 0.0, "merged": True},
    ]
    script = (
        "const TRACK_ARROW_S = 0.15;\n"
        + js_function("trackMarks")
        + f"\nconsole.log(JSON.stringify(trackMarks({json.dumps(tracks)}, 20, 30)));"
    )
    out = subprocess.run(["node", "-e", script], capture_output=True, text=True, check=True)
    first, second = json.loads(out.stdout)
    assert (first["x"], first["y"]) == (50, 15)  # (col + 0.5) x cell, as the contacts
    assert first["toX"] == pytest.approx(50 + 10 * 0.15 * 20) and first["toY"] == 15
    assert first["label"] == "3" and not first["merged"]
    assert (second["x"], second["y"]) == (100, 150) and second["toY"] == pytest.approx(141)
    assert second["label"] == "4 merged" and second["merged"]
