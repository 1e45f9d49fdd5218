"""The "Record & adapt" panel in headless Chromium: name, record (prompt, countdown, live
heatmap), adapt (a stand-in worker: the real one takes minutes), the before/after table and
"Use this model".  Screenshots go to ``artifacts/browser/adapt-*.png``."""

from __future__ import annotations

import pytest
from stand_ins import ContactMeans
from test_dashboard_adapt import fake_worker
from test_ui_dashboard_browser import SHOTS, browser, open_page  # noqa: F401 - the fixture

from wovenskin.runtime.session import open_session
from wovenskin.ui.dashboard.adapt_flow import AdaptFlow
from wovenskin.ui.dashboard.runner import DashboardRunner
from wovenskin.ui.dashboard.server import BackgroundServer

pytestmark = pytest.mark.browser  # drives chromium: `make test-fast` leaves it out


@pytest.fixture()
def server(tmp_path):
    def opener(skin: str, robot: str, task=None, model=None):
        recognizer = ContactMeans("swipe_up")
        return open_session(skin, robot, recognizer=recognizer, poses=tmp_path / "poses.toml")

    short = {"countdown_s": 0.5, "trial_s": 2.5, "invalid_trials": 0}
    flow = AdaptFlow(tmp_path / "adapt", worker=fake_worker("done"), defaults=short)
    server = BackgroundServer(DashboardRunner(opener, "sim:auto=0,seed=5", "sim", adapt=flow))
    server.start()
    yield server
    server.stop()


def test_record_and_adapt_in_the_page(browser, server) -> None:  # noqa: F811
    page = open_page(browser, server.url, "!window.wovenskin.state.skin.calibrating")
    try:
        page.click("#adapt-open")
        page.fill("#adapt-name", "Ana")
        page.fill("#adapt-trials", "1")
        page.click("#adapt-form details > summary")  # open the gesture list
        for box in page.locator("#adapt-gestures input").all():
            if box.get_attribute("value") != "swipe_up":
                box.uncheck()
        page.wait_for_function(  # the estimate follows the boxes on the next state update
            "document.querySelector('#adapt-estimate').innerText.startsWith('1 trials')",
            timeout=10_000,
        )
        page.click("#adapt-start")
        page.wait_for_function(
            "document.querySelector('#adapt-what').classList.contains('trial')", timeout=30_000
        )
        assert page.inner_text("#adapt-what") == "swipe up"
        assert page.inner_text("#adapt-trial") == "trial 1 of 1"
        assert page.evaluate("window.wovenskin.state.safety.user_stopped")  # the arm is held
        SHOTS.mkdir(parents=True, exist_ok=True)
        page.screenshot(path=str(SHOTS / "adapt-recording.png"))
        page.wait_for_selector("#adapt-result:not([hidden])", timeout=60_000)
        assert "installed" in page.inner_text("#adapt-verdict")
        assert "event F1" in page.inner_text("#adapt-figures")
        page.screenshot(path=str(SHOTS / "adapt-result.png"))
        page.click("#adapt-use")
        page.wait_for_function(
            "document.querySelector('#adapt-model').textContent.includes('model')"
            " && !document.querySelector('#adapt-revert').hidden",
            timeout=30_000,
        )
        assert server.runner.model is not None and server.runner.model.endswith("model")
        assert page.problems == []
    finally:
        page.context.close()
