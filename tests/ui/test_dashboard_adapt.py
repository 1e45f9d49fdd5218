"""The dashboard's "Record & adapt" panel: the shared recording driver, the request checks,
the adapt child process and its protocol, and the whole flow through the server's routes
on the simulated skin (with a stand-in adapt worker: the real one takes minutes)."""

from __future__ import annotations

import json
import sys
import textwrap
from types import SimpleNamespace

import numpy as np
import pytest
from fastapi.testclient import TestClient
from stand_ins import ContactMeans, wait_until

from wovenskin.custom_gestures import CustomGesture
from wovenskin.errors import ConfigError
from wovenskin.recording.native import read_recording
from wovenskin.runtime.session import open_session
from wovenskin.ui.dashboard.adapt_flow import AdaptFlow, check_record_request, report_summary
from wovenskin.ui.dashboard.adapt_job import AdaptJob
from wovenskin.ui.dashboard.runner import DashboardRunner
from wovenskin.ui.dashboard.server import create_app
from wovenskin.ui.record_session import RecordAborted, RecordDriver, RecordPlan

# -- the recording driver (shared with `wovenskin record`) -------------------------------


class Labels:
    """A stand-in recording writer: keeps the labels the driver writes."""

    def __init__(self) -> None:
        self.labels: list[tuple] = []

    def add_label(self, label, start_s, end_s, kind="trial", **extra) -> None:
        self.labels.append((label, start_s, end_s, kind, extra))


def _block(t0: float, n: int, touched: bool) -> SimpleNamespace:
    t = t0 + np.arange(n) / 200.0
    return SimpleNamespace(t=t, cond=SimpleNamespace(touched=np.full(n, touched)))


def test_the_driver_prompts_counts_down_and_labels_contact_windows_on_stream_time() -> None:
    writer, performed = Labels(), []
    plan = RecordPlan(["push"], 1, 0, countdown_s=1.0, trial_s=1.0, max_overrun_s=0.5)
    driver = RecordDriver(plan, writer, perform=performed.append)
    assert driver.prompt(0.0).phase == "calibrating"
    driver.feed(0.0, None, calibrating=True)
    driver.feed(0.5, None, calibrating=False)  # calibrated: the countdown starts at 0.5 s
    assert driver.prompt(0.9).to_dict() == {
        "phase": "countdown", "label": "push", "what": "push", "number": 1, "total": 1,
        "seconds_left": 0.6,
    }  # fmt: skip
    driver.feed(1.4, None)
    assert performed == []
    driver.feed(1.5, None)  # countdown over: the trial starts and the person is asked
    assert performed == ["push"] and driver.phase == "trial"
    driver.feed(1.8, _block(1.7, 21, False))
    driver.feed(2.2, _block(1.805, 80, True))  # touching from 1.805 s on
    driver.feed(2.6, _block(2.205, 80, True))  # past the trial's end but still touching
    assert driver.phase == "trial"
    driver.feed(2.8, _block(2.605, 40, False))  # lifted: the trial ends
    assert driver.done and len(driver.trials) == 1
    label, start, end, kind, extra = writer.labels[0]
    assert (label, kind) == ("push", "trial")
    assert start == pytest.approx(1.805) and end == pytest.approx(2.6)
    assert extra["prompt_start_s"] == 1.5 and extra["contact_found"] is True


def test_the_driver_repeats_a_stalled_trial_once_and_gives_up_on_calibration() -> None:
    writer, messages = Labels(), []
    driver = RecordDriver(RecordPlan(["push"], 1, 0, 0.2, 0.5), writer, messages=messages)
    driver.feed(0.0, None, calibrating=False)
    driver.feed(0.2, None)
    driver.feed(0.5, None, stalled=True)
    driver.feed(0.8, None)
    assert driver.phase == "countdown" and "will be repeated" in messages[-1]
    for t in (1.0, 1.6, 1.7, 2.0, 2.2):
        driver.feed(t, None)
    assert driver.done and [lab[4]["interrupted"] for lab in writer.labels] == [True, False]
    stuck = RecordDriver(RecordPlan(["push"], calibration_timeout_s=1.0), Labels())
    stuck.feed(5.0, None, calibrating=True)
    with pytest.raises(RecordAborted, match="calibration did not finish"):
        stuck.feed(6.5, None, calibrating=True)


# -- the checks of a record request --------------------------------------------------------


def test_a_record_request_is_checked_in_one_line() -> None:
    gestures = ["swipe_up", "push", "l_stroke"]
    custom = {"l_stroke": CustomGesture("l_stroke", 1, "an L")}  # no strokes
    ok = check_record_request({"name": "Ana Lee", "gestures": ["push"]}, gestures, True, {})
    assert ok == {"name": "Ana_Lee", "plan": {"gestures": ["push"], "trials_per_gesture": 3},
                  "perform": True}  # fmt: skip
    everything = check_record_request({"name": "b", "trials": "2"}, gestures, False, custom)
    assert everything["plan"]["gestures"] == gestures and everything["perform"] is False
    bad = [
        ({"name": ""}, "enter a name"),
        ({"name": "../x"}, "enter a name"),
        ({"name": "a", "gestures": ["wave"]}, "does not know 'wave'"),
        ({"name": "a", "trials": 0}, "trials must lie in 1-20"),
        ({"name": "a", "trials": 2.5}, "whole number"),
        ({"name": "a", "trials": "NaN"}, "finite number"),
        ({"name": "a", "trial_s": 1e9}, "trial_s must lie in"),
        ({"name": "a", "gestures": ["l_stroke"]}, "cannot perform 'l_stroke'"),
    ]
    for body, why in bad:
        with pytest.raises(ConfigError, match=why) as caught:
            check_record_request(body, gestures, True, custom)
        assert "\n" not in str(caught.value)
    # drawn by the person on the virtual skin, a gesture without strokes is fine
    drawn = check_record_request(
        {"name": "a", "gestures": ["l_stroke"], "perform": False}, gestures, True, custom
    )
    assert drawn["perform"] is False


def test_the_page_table_of_an_adapt_report() -> None:
    report = {
        "held_out_before": {"f1": 0.8, "false_activations_per_min": 1.0,
                            "median_latency_s": 0.3, "per_class_recall": {"push": 0.5}},
        "held_out_after": {"f1": 1.0, "false_activations_per_min": 0.0,
                           "median_latency_s": 0.2, "per_class_recall": {"push": 1.0},
                           "per_class_events": {"push": 2}},
        "arbiter": {"min_probability": 0.6}, "accepted": True, "new_classes": [],
    }  # fmt: skip
    table = report_summary(report)
    assert table["figures"][0] == {"name": "event F1", "before": 0.8, "after": 1.0}
    assert table["figures"][2]["before"] == 300.0  # ms
    assert table["classes"] == [{"name": "push", "events": 2, "after": 1.0, "before": 0.5}]
    assert table["min_probability"] == 0.6 and report_summary(None) is None


# -- the adapt child process -----------------------------------------------------------------

REPORT = {
    "held_out_before": {"f1": 0.5, "false_activations_per_min": 2.0, "median_latency_s": 0.3,
                        "per_class_recall": {"swipe_up": 0.5}},
    "held_out_after": {"f1": 0.9, "false_activations_per_min": 0.5, "median_latency_s": 0.2,
                       "per_class_recall": {"swipe_up": 1.0}, "per_class_events": {"swipe_up": 1}},
    "arbiter": {"min_probability": 0.5}, "new_classes": [],
}  # fmt: skip


def fake_worker(outcome: str = "done", exit_code: int = 0) -> list[str]:
    """A stand-in for the adapt child: the same protocol, in a fraction of a second."""
    report = {**REPORT, "accepted": outcome == "done"}
    code = textwrap.dedent(f"""
        import json, pathlib, sys
        request = json.loads(sys.argv[1])
        pathlib.Path(request["out"]).mkdir(parents=True, exist_ok=True)
        for k in range(3):
            print(json.dumps({{"event": "progress", "stage": "fine-tuning", "done": k,
                              "total": 3, "note": "loss 0.1"}}), flush=True)
        print("a line that is not JSON", flush=True)
        if {outcome!r} != "none":
            print(json.dumps({{"event": {outcome!r}, "report": {report!r},
                              "verdict": "installed: " + request["out"],
                              "message": "refused: worse than the base"}}), flush=True)
        sys.exit({exit_code})
    """)
    return [sys.executable, "-c", code]


def test_the_adapt_job_reads_progress_and_the_outcome(tmp_path) -> None:
    job = AdaptJob(["a.wsrec"], tmp_path / "model", command=fake_worker("done"))
    job.start()
    assert wait_until(lambda: job.status().finished)
    status = job.status()
    assert status.state == "done" and status.stages == ["fine-tuning"]
    assert status.message == f"installed: {tmp_path / 'model'}"
    assert status.report["held_out_after"]["f1"] == 0.9
    crashed = AdaptJob(["a.wsrec"], tmp_path / "m2", command=fake_worker("none", exit_code=3))
    crashed.start()
    assert wait_until(lambda: crashed.status().finished)
    assert crashed.status().state == "failed" and "exit code 3" in crashed.status().message


def test_the_worker_speaks_the_protocol(tmp_path, monkeypatch, capsys) -> None:
    pytest.importorskip("torch")
    from wovenskin.training.adapt import AdaptEvent, AdaptRefused
    from wovenskin.ui.dashboard import adapt_worker

    class Report:
        def to_dict(self) -> dict:
            return {**REPORT, "seconds": float("nan")}  # not finite: sent as null

        def verdict(self) -> str:
            return "installed"

    def fake_adapt(paths, out, base, settings, progress):
        assert settings.epochs == 1 and paths == ["x.wsrec"]
        progress(AdaptEvent("fine-tuning", 1, 2, "loss 0.5"))
        if base == "refuse":
            raise AdaptRefused("worse than the base", Report())
        return Report()

    monkeypatch.setattr(adapt_worker, "adapt_model", fake_adapt)
    monkeypatch.setattr(adapt_worker.os, "nice", lambda n: 0)
    request = {"paths": ["x.wsrec"], "out": str(tmp_path), "base": None,
               "settings": {"epochs": 1}}  # fmt: skip
    assert adapt_worker.main([json.dumps(request)]) == 0
    lines = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert lines[0] == {"event": "progress", "stage": "fine-tuning", "done": 1, "total": 2,
                        "note": "loss 0.5"}  # fmt: skip
    assert lines[1]["event"] == "done" and lines[1]["report"]["seconds"] is None
    assert adapt_worker.main([json.dumps({**request, "base": "refuse"})]) == 0
    assert json.loads(capsys.readouterr().out.splitlines()[-1])["event"] == "refused"
    assert adapt_worker.main([json.dumps({**request, "settings": {"epochs": 0}})]) == 0
    failed = json.loads(capsys.readouterr().out.splitlines()[-1])
    assert failed["event"] == "failed" and "epochs" in failed["message"]


# -- the whole flow through the server ------------------------------------------------------


class LocalClient(TestClient):
    """A test client naming the server 127.0.0.1, as a browser on this machine does."""

    def __init__(self, app) -> None:
        super().__init__(app, base_url="http://127.0.0.1")


@pytest.fixture()
def dashboard(tmp_path):
    """A running dashboard on the simulated skin (real time) with a stand-in recogniser and
    adapt worker; ``opened`` lists the model each session was opened with."""
    opened: list = []

    def opener(skin: str, robot: str, task=None, model=None):
        opened.append(model)
        recognizer = ContactMeans("swipe_up")  # acts on any touch: the arm would move
        return open_session(skin, robot, recognizer=recognizer, poses=tmp_path / "poses.toml")

    flow = AdaptFlow(root=tmp_path / "adapt", worker=fake_worker("done"))
    runner = DashboardRunner(opener, "sim:auto=0,seed=3", "sim", adapt=flow)
    runner.start()
    assert wait_until(lambda: (runner.latest() or {}).get("skin", {}).get("calibrating") is False)
    client = LocalClient(create_app(runner))
    yield SimpleNamespace(runner=runner, flow=flow, client=client, opened=opened)
    runner.close()


SHORT = {"name": "Ana", "gestures": ["swipe_up"], "trials": 1, "invalid_trials": 0,
         "countdown_s": 0.3, "trial_s": 2.5}  # fmt: skip


def _post(client, op: str, body: dict | None = None):
    return client.post(f"/api/adapt/{op}", json=body or {})


def test_record_adapt_and_use_through_the_server(dashboard) -> None:
    runner, client = dashboard.runner, dashboard.client
    state = client.get("/api/adapt").json()
    assert state["phase"] == "idle" and "swipe_up" in state["gestures"]
    assert state["defaults"]["trials"] == 3 and state["defaults"]["simulated"] is True
    tcp = runner.latest()["robot"]["tcp"]["pos"]
    reply = _post(client, "record", SHORT)
    assert reply.status_code == 202, reply.text
    assert wait_until(lambda: client.get("/api/adapt").json()["phase"] == "recording")
    busy = _post(client, "record", SHORT)
    assert busy.status_code == 400 and "already recording" in busy.json()["error"]
    assert wait_until(lambda: (client.get("/api/adapt").json()["prompt"] or {}).get("phase")
                      in ("countdown", "trial"))  # fmt: skip
    prompt = client.get("/api/adapt").json()["prompt"]
    assert prompt["label"] == "swipe_up" and prompt["total"] == 1
    assert prompt["hint"].startswith("1 finger")
    runner.submit({"cmd": "resume"})  # refused while recording: the arm stays held
    seen_held = []

    def finished() -> bool:
        snapshot = runner.latest()
        seen_held.append(snapshot["safety"]["user_stopped"])
        return snapshot["adapt"]["phase"] not in ("recording", "adapting")

    assert wait_until(finished, timeout=60.0)
    state = client.get("/api/adapt").json()
    assert state["phase"] == "done", state["message"]
    assert all(seen_held) and runner.latest()["safety"]["user_stopped"]
    messages = " ".join(runner.latest()["messages"])
    assert "recording for adapt: the arm stays held" in messages
    assert "command swipe_up" in messages  # the recogniser acted on the gesture ...
    assert runner.latest()["robot"]["tcp"]["pos"] == tcp  # ... and the arm did not move
    # the recording: a labelled, calibrated .wsrec in runs/adapt/<name>-<time>/
    run_dir = dashboard.flow.run_dir
    assert run_dir.parent == dashboard.flow.root and run_dir.name.startswith("Ana-")
    recording = read_recording(run_dir / "Ana.wsrec")
    assert recording.clean_close and recording.provenance["participant"] == "Ana"
    assert len(recording.calibrations) == 1
    trials = [label for label in recording.labels if label.kind == "trial"]
    assert [t.label for t in trials] == ["swipe_up"] and trials[0].extra["contact_found"]
    assert state["summary"]["figures"][0] == {"name": "event F1", "before": 0.5, "after": 0.9}
    assert state["report"]["held_out_after"]["f1"] == 0.9
    # use the adapted model, then go back
    assert _post(client, "use").status_code == 202
    model = str(run_dir / "model")
    assert wait_until(lambda: runner.model == model and dashboard.opened[-1] == model)
    assert wait_until(lambda: runner.latest()["adapt"]["model"]["in_use"] == model)
    assert _post(client, "revert").status_code == 202
    assert wait_until(lambda: not runner.latest()["adapt"]["model"]["can_revert"])
    assert runner.model is None and dashboard.opened[-1] is None
    again = _post(client, "revert")
    assert again.status_code == 400 and "no previous model" in again.json()["error"]


def test_a_refused_model_cannot_be_used_and_bad_requests_are_refused(dashboard) -> None:
    client, flow = dashboard.client, dashboard.flow
    flow.worker = fake_worker("refused")
    assert _post(client, "use").status_code == 400  # nothing adapted yet
    assert _post(client, "cancel").status_code == 400  # nothing running
    assert _post(client, "record", {**SHORT, "name": ""}).status_code == 400
    assert client.post("/api/adapt/record", content=json.dumps(SHORT)).status_code == 415
    foreign = client.post("/api/adapt/record", json=SHORT, headers={"origin": "http://evil.test"})
    assert foreign.status_code == 403
    assert client.post("/api/adapt/explode", json={}).status_code == 400
    assert _post(client, "record", SHORT).status_code == 202
    assert wait_until(lambda: client.get("/api/adapt").json()["phase"] == "refused", timeout=60.0)
    refused = _post(client, "use")
    assert refused.status_code == 400 and "refused" in refused.json()["error"]
    assert dashboard.runner.model is None


def test_without_pytorch_the_recording_is_kept_and_the_panel_says_so(dashboard) -> None:
    client, flow = dashboard.client, dashboard.flow
    flow.torch = (
        "adapting needs PyTorch, which is not installed here: pip install 'wovenskin[train]'"
    )
    assert wait_until(lambda: client.get("/api/adapt").json()["torch"].startswith("adapting needs"))
    assert _post(client, "record", SHORT).status_code == 202
    assert wait_until(lambda: client.get("/api/adapt").json()["phase"] == "saved", timeout=60.0)
    state = client.get("/api/adapt").json()
    assert "needs PyTorch" in state["message"] and state["recording"].endswith("Ana.wsrec")
    assert read_recording(state["recording"]).clean_close


def test_cancelling_a_recording_keeps_what_was_recorded(dashboard) -> None:
    client, runner = dashboard.client, dashboard.runner
    assert _post(client, "record", {**SHORT, "trial_s": 10.0}).status_code == 202
    assert wait_until(lambda: client.get("/api/adapt").json()["phase"] == "recording")
    assert _post(client, "cancel").status_code == 202
    assert wait_until(lambda: client.get("/api/adapt").json()["phase"] == "idle")
    assert "cancelled" in client.get("/api/adapt").json()["message"]
    assert runner.session.recorder is None and runner.session.live_skin.on_block is None
    assert read_recording(dashboard.flow.recording).clean_close
    runner.submit({"cmd": "resume"})  # allowed again once the recording ended
    assert wait_until(lambda: not runner.latest()["safety"]["user_stopped"])


def test_an_error_in_the_panel_never_stops_the_control_loop(dashboard, monkeypatch) -> None:
    runner, flow = dashboard.runner, dashboard.flow

    def broken(runner, session):
        raise RuntimeError("boom")

    monkeypatch.setattr(flow, "_tick", broken)
    assert wait_until(lambda: runner.latest()["adapt"]["phase"] == "failed")
    assert "RuntimeError: boom" in runner.latest()["adapt"]["message"]
    seq = runner.latest()["seq"]
    assert wait_until(lambda: runner.latest()["seq"] > seq + 5) and runner.running
