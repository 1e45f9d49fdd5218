"""The dashboard's simulated-person buttons and the mouse's release, in real headless Chromium.

Each of the 14 buttons is pressed :data:`PRESSES` times: the simulated person performs the
gesture on the simulated skin, the shipped recogniser reads it, and the commands the
session issued for that press must be exactly that gesture's, every time.  Then mouse swipes
drawn on the page are held and released, and the page's own clock measures how long the
release takes to show "no command" (``window.wovenskin.releaseMs``); the figures are saved
to ``artifacts/browser/buttons.json`` and reported in ``docs/benchmarks.md``, never asserted
(a timing depends on the machine).  Last, a drawn swipe held still for 30 s must keep its
command until the release.  Minutes of browser time: ``make test-acceptance``.
"""

from __future__ import annotations

import json
import time

import numpy as np
import pytest
from test_ui_dashboard_browser import (  # noqa: F401 - the fixtures
    SHOTS,
    _state,
    _wait_for,
    browser,
    dashboard,
    page,
)

from wovenskin.gestures import INVALID, SPECS

pytestmark = [pytest.mark.browser, pytest.mark.acceptance]

PRESSES = 20
GESTURES = [name for name in SPECS if name != INVALID]
PRESS_TIMEOUT_S = 10.0  # the person's idle gap, the performance and its lift-off, on a busy page


def _press(page, dashboard, name: str) -> list[str]:  # noqa: F811 - the fixtures
    """Click ``name``'s button once; the gestures the session commanded until the lift-off."""
    changes = dashboard.runner.session.pipeline.changes
    first = len(changes)
    page.click(f"#perform button[data-gesture='{name}']")
    started = time.monotonic()
    while time.monotonic() - started < PRESS_TIMEOUT_S:
        new = changes[first:]
        gestures = [c.gesture for c in new if c.gesture]
        if gestures and new[-1].gesture is None:
            return gestures
        time.sleep(0.05)
    return [c.gesture for c in changes[first:] if c.gesture] + ["(no lift-off)"]


def test_each_button_gives_its_own_command_every_time(page, dashboard) -> None:  # noqa: F811
    tally: dict[str, list[list[str]]] = {}
    for name in GESTURES:
        tally[name] = [_press(page, dashboard, name) for _ in range(PRESSES)]
    good = {name: sum(got == [name] for got in runs) for name, runs in tally.items()}
    wrong = {name: [got for got in runs if got != [name]] for name, runs in tally.items()}
    _merge_artifact({"presses": PRESSES, "buttons": good, "wrong": wrong})
    assert all(count == PRESSES for count in good.values()), (good, wrong)
    assert page.problems == []


def test_the_release_of_a_drawn_swipe_is_measured_on_the_page(page) -> None:  # noqa: F811
    """Twenty held swipes, alternately up and down, released with a command on."""
    box = page.locator("#skin").bounding_box()
    x = box["x"] + box["width"] * 0.5
    for k in range(20):
        y0, y1 = (0.8, 0.25) if k % 2 == 0 else (0.2, 0.75)
        before = len(page.evaluate("window.wovenskin.releaseMs"))
        page.mouse.move(x, box["y"] + box["height"] * y0)
        page.mouse.down()
        for step in range(1, 31):
            f = step / 30
            page.mouse.move(x, box["y"] + box["height"] * (y0 + (y1 - y0) * f))
            time.sleep(0.012)
        _wait_for(page, "window.wovenskin.state.recognition.command !== null", 3.0)
        time.sleep(0.3)
        page.mouse.up()
        _wait_for(page, f"window.wovenskin.releaseMs.length > {before}", 5.0)
    released = page.evaluate("window.wovenskin.releaseMs")
    assert len(released) >= 15, f"{len(released)} of 20 releases came with a command on"
    figures = np.asarray(released)
    _merge_artifact(
        {
            "release_to_no_command_ms": [round(v, 1) for v in released],
            "release_median_ms": round(float(np.median(figures)), 1),
            "release_p90_ms": round(float(np.percentile(figures, 90)), 1),
        }
    )
    assert "release to stop" in page.locator("#rates").inner_text()
    assert page.problems == []


def test_a_drawn_swipe_held_still_for_30_s_keeps_its_command(page, dashboard) -> None:  # noqa: F811
    """A swipe drawn with the mouse, then held still with the button down for 30 s: the
    command stays on (and the arm moving, within the workspace) until the release."""
    box = page.locator("#skin").bounding_box()
    x = box["x"] + box["width"] * 0.5
    page.mouse.move(x, box["y"] + box["height"] * 0.3)
    page.mouse.down()
    for step in range(1, 31):  # a downward swipe: the tool's -y, away from the limits
        page.mouse.move(x, box["y"] + box["height"] * (0.3 + 0.45 * step / 30))
        time.sleep(0.012)
    assert _wait_for(page, "window.wovenskin.state.recognition.command !== null", 5.0)
    held = _state(page)["recognition"]["command"]
    session = dashboard.runner.session
    first = len(session.pipeline.changes)
    started = time.monotonic()
    while time.monotonic() - started < 30.0:
        time.sleep(0.5)
        ended = [c for c in session.pipeline.changes[first:] if c.gesture != held]
        assert not ended, f"{held} ended after {time.monotonic() - started:.1f} s: {ended}"
    page.mouse.up()
    assert _wait_for(page, "window.wovenskin.state.recognition.command === null", 5.0)
    _merge_artifact({"held_30_s": held})


def _merge_artifact(figures: dict) -> None:
    SHOTS.mkdir(parents=True, exist_ok=True)
    path = SHOTS / "buttons.json"
    saved = json.loads(path.read_text()) if path.exists() else {}
    path.write_text(json.dumps({**saved, **figures}, indent=1))
