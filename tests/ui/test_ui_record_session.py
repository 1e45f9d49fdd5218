"""Tests of the guided recording session, driven by the simulated person at full speed."""

import io

import numpy as np
from rich.console import Console

from wovenskin.recording.formats import write_labelled_stream
from wovenskin.recording.native import read_recording
from wovenskin.sim.stream import simulate_stream
from wovenskin.ui.record_session import RecordPlan, run_record_session


def test_plan_is_shuffled_deterministically():
    plan = RecordPlan(["swipe_up", "push"], trials_per_gesture=3, invalid_trials=2, seed=4)
    order = plan.trials()
    assert sorted(order) == sorted(["swipe_up"] * 3 + ["push"] * 3 + ["invalid"] * 2)
    assert order == RecordPlan(["swipe_up", "push"], 3, 2, seed=4).trials()


def test_session_records_frames_calibration_and_labelled_trials(tmp_path):
    out = tmp_path / "p01.wsrec"
    plan = RecordPlan(
        ["swipe_up", "pinch_in_5f"],
        trials_per_gesture=1,
        invalid_trials=1,
        countdown_s=0.5,
        trial_s=2.5,
        seed=1,
    )
    summary = run_record_session(
        out,
        "sim:seed=5,speed=0",
        plan,
        provenance={"participant": "P01"},
        console=Console(file=io.StringIO(), width=100),
    )
    assert not summary.aborted
    rec = read_recording(out)
    assert rec.clean_close
    assert rec.provenance["participant"] == "P01"
    assert rec.info.source.startswith("sim")
    assert len(rec.calibrations) == 1
    # every frame from the start, at the full rate, none missing
    assert np.all(np.diff(rec.seq) == 1)
    np.testing.assert_allclose(np.diff(rec.t), 1 / 200, atol=1e-9)
    trials = [lab for lab in rec.labels if lab.kind == "trial"]
    assert sorted(lab.label for lab in trials) == ["invalid", "pinch_in_5f", "swipe_up"]
    for lab in trials:
        extra = lab.extra
        assert extra["prompt_start_s"] <= lab.start_s < lab.end_s
        if lab.label != "invalid":  # the person performs the prompted gesture
            assert extra["contact_found"], lab
            assert lab.end_s - lab.start_s > 0.1


def test_an_ending_source_stops_the_session_and_keeps_the_data(tmp_path):
    src = tmp_path / "short.npz"
    write_labelled_stream(src, simulate_stream(3.0, seed=2))
    out = tmp_path / "r.wsrec"
    summary = run_record_session(
        out,
        f"replay:{src}?speed=0",
        RecordPlan(["push"], 5, 0, countdown_s=0.5, trial_s=1.0),
        console=Console(file=io.StringIO()),
    )
    assert "ended" in summary.aborted
    rec = read_recording(out)
    assert len(rec.frames) == 600
