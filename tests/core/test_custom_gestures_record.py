"""Recording gestures of a user's own: ``wovenskin record --mapping`` prompts them with their
descriptions, the simulated person performs them from their strokes, and the trials carry
their names."""

from __future__ import annotations

import io

from paths import REPO
from rich.console import Console
from typer.testing import CliRunner

from wovenskin.cli import app
from wovenskin.control.mapping import ActionMapping
from wovenskin.custom_gestures import CustomGesture, custom_from_settings
from wovenskin.errors import ConfigError
from wovenskin.recording.native import read_recording
from wovenskin.ui.record_session import RecordPlan, prompt_for, run_record_session

EXAMPLE = REPO / "examples" / "custom_gestures.toml"


def test_the_sim_performs_custom_gestures_into_labelled_trials(tmp_path) -> None:
    custom = ActionMapping.load(EXAMPLE).custom
    prompts = {name: gesture.prompt for name, gesture in custom.items()}
    assert prompt_for("l_stroke", prompts) == "l stroke: draw an L: down, then right"
    assert prompt_for("double_tap", prompts) == "double tap: tap twice with one fingertip, quickly"
    assert prompt_for("swipe_up", prompts) == "swipe up"
    out = tmp_path / "mine.wsrec"
    screen = io.StringIO()
    plan = RecordPlan(["double_tap", "l_stroke"], 2, 1, countdown_s=0.4, trial_s=2.0, seed=3)
    summary = run_record_session(
        out, "sim:seed=4,speed=0", plan, console=Console(file=screen, width=120), custom=custom
    )
    assert not summary.aborted
    recording = read_recording(out)
    trials = [label for label in recording.labels if label.kind == "trial"]
    assert sorted(t.label for t in trials) == ["double_tap"] * 2 + ["invalid"] + ["l_stroke"] * 2
    for trial in trials:
        if trial.label != "invalid":  # performed, and the contact window found
            assert trial.extra["contact_found"], trial
            assert 0.1 < trial.end_s - trial.start_s < 2.0
    assert custom_from_settings(recording.settings) == custom  # the definitions travel along
    shown = screen.getvalue()  # the last screen: a custom gesture's prompt or the invalid one
    assert any(prompt_for(t.label, prompts) in shown for t in trials), shown
    stream = recording.to_labelled_stream()
    assert set(stream.event_labels) == {"double_tap", "l_stroke", "invalid"}


def test_a_custom_gesture_without_strokes_is_refused_before_recording_on_the_sim(tmp_path) -> None:
    out = tmp_path / "never.wsrec"
    custom = {"wave": CustomGesture("wave", 1, "wave")}
    try:
        run_record_session(
            out, "sim:speed=0", RecordPlan(["wave"]), console=Console(file=io.StringIO()),
            custom=custom,
        )  # fmt: skip
    except ConfigError as exc:
        assert "'wave' has no strokes" in str(exc) and "\n" not in str(exc)
    else:
        raise AssertionError("a gesture the simulated person cannot perform was recorded")
    assert not out.exists()
    try:
        run_record_session(out, "sim:speed=0", RecordPlan(["wave"]), console=Console())
    except ConfigError as exc:
        assert "unknown gesture 'wave'" in str(exc)
    else:
        raise AssertionError("an undefined gesture was prompted")
    assert not out.exists()


def test_record_with_a_mapping_on_the_command_line(tmp_path) -> None:
    out = tmp_path / "cli.wsrec"
    args = [
        "record", "--out", str(out), "--skin", "sim:seed=2,speed=0", "--mapping", str(EXAMPLE),
        "--gestures", "double_tap", "--trials", "1", "--invalid-trials", "0",
        "--countdown", "0.3", "--trial-seconds", "1.5",
    ]  # fmt: skip
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    assert "1 labelled trial (0 without contact)" in result.output
    assert [label.label for label in read_recording(out).labels if label.kind == "trial"] == [
        "double_tap"
    ]
    info = CliRunner().invoke(app, ["info", str(out)])
    assert info.exit_code == 0 and "double_tap 1" in info.output
    assert "unknown gesture" not in info.output  # the recording defines it


def test_record_refuses_what_the_mapping_does_not_know(tmp_path) -> None:
    out = tmp_path / "x.wsrec"
    base = ["record", "--out", str(out), "--skin", "sim:speed=0"]
    result = CliRunner().invoke(app, [*base, "--gestures", "double_tap"])  # no --mapping
    assert result.exit_code == 2 and "unknown gesture 'double_tap'" in result.output
    bad = tmp_path / "bad.toml"
    bad.write_text('[gestures]\ntriple_tap = "pose home"\n')
    result = CliRunner().invoke(app, [*base, "--mapping", str(bad)])
    assert result.exit_code == 2 and "gestures.triple_tap: unknown gesture" in result.output
    assert not out.exists()
