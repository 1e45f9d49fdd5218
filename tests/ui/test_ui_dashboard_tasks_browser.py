"""The dashboard's study tasks in real headless Chromium: keys, the jog panel, a trial, pouring.

Like ``test_ui_dashboard_browser``: Debian's chromium through Playwright, skipped without
them unless ``WOVENSKIN_REQUIRE_BROWSER=1``.  The session runs without a skin (``none``):
the keyboard and the pendant drive the simulated arm in the task's physics scene.
"""

from __future__ import annotations

import json
import time

import numpy as np
import pytest
from stand_ins import ContactMeans
from test_ui_dashboard_browser import _save, _wait_for, browser, open_page  # noqa: F401 - the fixture

from wovenskin.runtime.session import open_session
from wovenskin.study.definition import add_participant, init_study
from wovenskin.study.questionnaires import read_questionnaires
from wovenskin.ui.dashboard.runner import DashboardRunner
from wovenskin.ui.dashboard.server import BackgroundServer

pytestmark = pytest.mark.browser  # drives chromium: `make test-fast` leaves it out


@pytest.fixture()
def study_dir(tmp_path):
    init_study(tmp_path / "study", "browser")
    add_participant(tmp_path / "study", "P01", "novice")
    return tmp_path / "study"


@pytest.fixture()
def dashboard(tmp_path, study_dir):
    def opener(skin: str, robot: str, task=None):
        return open_session(
            skin, robot, recognizer=ContactMeans("swipe_up"), poses=tmp_path / "poses.toml",
            task=task,
        )  # fmt: skip

    runner = DashboardRunner(opener, "none", "sim", task="pick_place", study_dir=study_dir)
    server = BackgroundServer(runner)
    server.start()
    yield server
    server.stop()


@pytest.fixture()
def page(browser, dashboard):  # noqa: F811 - the browser fixture imported above
    ready = "window.wovenskin.task && window.wovenskin.task.moving > 0"
    page = open_page(browser, dashboard.url, ready)
    yield page
    page.context.close()


def _state(page) -> dict:
    return page.evaluate("window.wovenskin.state")


def _tcp(page) -> np.ndarray:
    return np.array(_state(page)["robot"]["tcp"]["pos"])


def _choose(page, interface: str) -> None:
    page.select_option("#interface", interface)
    assert _wait_for(page, f"window.wovenskin.state.teleop.interface === '{interface}'", 10)


def _moved(page, before: np.ndarray, metres: float, timeout_s: float = 20) -> bool:
    b = json.dumps([float(v) for v in before])
    return _wait_for(
        page,
        f"(() => {{ const p = window.wovenskin.state.robot.tcp.pos, b = {b};"
        f" return Math.hypot(p[0]-b[0], p[1]-b[1], p[2]-b[2]) > {metres}; }})()",
        timeout_s,
    )


def test_pick_place_with_the_keyboard_moves_along_the_key_axis_and_closes_the_gripper(
    page,
) -> None:
    names = page.evaluate("window.wovenskin.scene.task.moving.map((s) => s.name)")
    assert {"cube", "cylinder", "prism", "finger_left", "finger_right"} <= set(names)
    _choose(page, "keyboard")
    assert page.locator("#keymap span").count() == 15  # 14 gestures and the gripper
    before = _tcp(page)
    z_axis = np.array(_state(page)["robot"]["tcp"]["z_axis"])
    page.keyboard.down("r")  # swipe_up: translate +z in the tool frame
    assert _moved(page, before, 0.02)
    page.keyboard.up("r")
    assert _wait_for(page, "window.wovenskin.state.teleop.held === null", 10)
    moved = _tcp(page) - before
    assert moved @ z_axis / np.linalg.norm(moved) > 0.95
    left, right = names.index("finger_left"), names.index("finger_right")

    def gap() -> float:
        geoms = _state(page)["task"]["geoms"]
        return float(np.linalg.norm(np.subtract(geoms[left][:3], geoms[right][:3])))

    open_gap = gap()
    page.keyboard.press("g")
    assert _wait_for(page, "window.wovenskin.state.teleop.gripper_closed", 10)
    deadline = time.monotonic() + 20
    while gap() > open_gap - 0.03 and time.monotonic() < deadline:
        time.sleep(0.1)
    assert gap() < open_gap - 0.03  # the fingers closed (on nothing)
    assert _state(page)["teleop"]["commands"] == 2
    _save(page, "dashboard-pick-place-keyboard.png")
    assert page.problems == []


def test_the_pendant_jogs_in_base_frame_and_steps_by_its_increment(page) -> None:
    _choose(page, "pendant")
    assert page.locator("#pendant").is_visible()
    before = _tcp(page)
    button = page.locator('#jog-axes button[data-axis="z"][data-sign="1"]')
    button.scroll_into_view_if_needed()
    box = button.bounding_box()
    page.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
    page.mouse.down()  # held: a continuous jog along the base frame's z
    assert _moved(page, before, 0.015)
    page.mouse.up()
    assert _wait_for(page, "window.wovenskin.state.teleop.pendant.jogging === null", 10)
    time.sleep(0.4)  # the brake
    moved = _tcp(page) - before
    assert moved[2] > 0.015 and np.hypot(moved[0], moved[1]) < 0.1 * moved[2]
    page.select_option("#jog-step", "10")
    assert _wait_for(page, "window.wovenskin.state.teleop.pendant.step_size === 10", 10)
    before = _tcp(page)
    page.click('#jog-axes button[data-axis="x"][data-sign="1"]')
    assert _moved(page, before, 0.0095)
    time.sleep(0.5)
    moved = _tcp(page) - before
    assert moved[0] == pytest.approx(0.010, abs=0.001) and np.hypot(moved[1], moved[2]) < 0.001
    assert page.problems == []


def test_a_trial_run_from_the_study_panel_is_written_to_the_study_folder(page, study_dir) -> None:
    page.fill("#participant", "P01")
    page.click("#trial-start")
    assert _wait_for(page, "window.wovenskin.state.study.running", 15)
    page.click("#gripper")  # the skin interface's gripper button: one command
    assert _wait_for(page, "window.wovenskin.state.study.started", 15)
    assert "s" in page.text_content("#trial-timer")
    page.click("#trial-success")
    assert _wait_for(page, "!window.wovenskin.state.study.running", 15)
    folder = study_dir / "trials" / "P01" / "pick_place-skin-1"
    summary = json.loads((folder / "trial.json").read_text())
    assert summary["outcome"] == "success" and summary["commands"] == 1
    rows = (study_dir / "trials.csv").read_text().splitlines()
    assert len(rows) == 2 and "pick_place,skin,1,success" in rows[1]
    assert "success" in page.text_content("#trial-status")
    assert page.problems == []


def test_the_pour_scene_draws_its_particles(page) -> None:
    page.select_option("#task", "pour")
    assert _wait_for(page, "window.wovenskin.task && window.wovenskin.task.particles === 100", 30)
    assert page.evaluate("window.wovenskin.scene.task.particles.count") == 100
    counted = "window.wovenskin.task.state && window.wovenskin.task.state.total === 100"
    assert _wait_for(page, counted, 10)
    _save(page, "dashboard-pour.png")
    assert page.problems == []


def test_a_questionnaire_answered_in_the_page_is_scored_into_the_study(page, study_dir) -> None:
    _choose(page, "keyboard")
    page.fill("#participant", "P01")
    assert _wait_for(page, "!document.getElementById('q-open').hidden", 10)
    page.click("#q-open")
    assert page.locator("#q-tlx input[type=range]").count() == 6
    assert page.locator("#q-sus input[type=radio]").count() == 50
    for key, value in {"mental": 80, "physical": 20, "temporal": 45, "performance": 10,
                       "effort": 60, "frustration": 5}.items():  # fmt: skip
        page.locator(f"#q-tlx-{key}").fill(str(value))
    for item in range(1, 10):  # one statement left unanswered: the page asks for it
        page.check(f'input[name="q-sus-{item}"][value="{4 if item % 2 else 2}"]')
    page.click("#q-submit")
    assert "every SUS statement" in page.text_content("#q-prompt")
    page.check('input[name="q-sus-10"][value="2"]')
    page.click("#q-submit")
    assert _wait_for(page, "document.getElementById('questionnaire').hidden", 10)
    path = study_dir / "questionnaires.csv"
    deadline = time.monotonic() + 15
    while not path.exists() and time.monotonic() < deadline:
        time.sleep(0.1)
    rows, warnings = read_questionnaires(study_dir)
    assert warnings == [] and len(rows) == 1
    row = rows[0]
    assert (row.participant, row.interface, row.task) == ("P01", "keyboard", "pick_place")
    assert row.tlx == (80, 20, 45, 10, 60, 5) and row.tlx_raw == pytest.approx(220 / 6)
    assert row.sus_score == pytest.approx(75.0)  # odd 4 -> 3 each, even 2 -> 3 each: 30 x 2.5
    said = "[...document.querySelectorAll('#messages li')].some((li) =>"
    assert _wait_for(page, f"{said} li.textContent.includes('questionnaire of P01'))", 10)
    _save(page, "dashboard-questionnaire.png")
    assert page.problems == []


def test_the_panel_shows_the_participants_planned_condition_and_uses_it(page) -> None:
    _choose(page, "pendant")
    page.fill("#participant", "P01")  # the first row of the Williams squares
    shown = "document.getElementById('plan').textContent"
    assert _wait_for(page, f"{shown}.includes('step 1 of 6')", 15)
    assert "pick place with skin" in page.text_content("#plan")
    page.click("#plan-use")
    assert _wait_for(page, "window.wovenskin.state.teleop.interface === 'skin'", 15)
    assert page.problems == []
