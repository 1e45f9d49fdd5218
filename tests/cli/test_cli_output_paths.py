"""Output paths are checked before the work starts: every writing command refuses, in one
line naming the user's path (never an internal ``.partial`` file), an output that could
not be written, before it simulates, trains, records or runs anything.

As root (where every folder is writable) the unwritable case is a path under a regular
file; a folder without write permission is tested through ``os.access``."""

from __future__ import annotations

import os

import pytest
from typer.testing import CliRunner

from wovenskin.cli import app
from wovenskin.outputs import OutputNotWritableError, check_new_output, check_writable

cli = CliRunner()


@pytest.fixture
def blocker(tmp_path):
    """A regular file where the outputs' folder should be."""
    path = tmp_path / "blocker"
    path.write_text("not a folder")
    return path


def refused_at_once(result, path, blocker) -> None:
    """One line naming the user's path and why; the work never started."""
    text = " ".join(result.output.split())
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output and ".partial" not in text
    assert f"cannot write {path}: {blocker} is a file, not a folder" in text, text


def work_must_not_start(monkeypatch, *targets: str) -> None:
    """Replace each ``module:function`` by one that fails the test if called."""

    def started(*args, **kwargs):
        raise AssertionError("the work started before the output was checked")

    for target in targets:
        module, name = target.split(":")
        monkeypatch.setattr(f"{module}.{name}", started)


def test_the_helper_names_the_reason(tmp_path, blocker, monkeypatch):
    assert check_writable(tmp_path / "new" / "deeper" / "x.npz") == tmp_path / "new/deeper/x.npz"
    assert check_writable(tmp_path / "folder", folder=True) == tmp_path / "folder"
    with pytest.raises(OutputNotWritableError, match="it is a folder"):
        check_writable(tmp_path)
    with pytest.raises(OutputNotWritableError, match="it is a file, not a folder"):
        check_writable(blocker, folder=True)
    with pytest.raises(OutputNotWritableError, match=f"{blocker} is a file, not a folder"):
        check_new_output(blocker / "sub" / "x.npz", overwrite=False)
    locked = tmp_path / "locked"
    locked.mkdir()
    real_access = os.access

    def access(path, mode) -> bool:
        return str(path) != str(locked) and real_access(path, mode)

    monkeypatch.setattr("wovenskin.outputs.os.access", access)
    with pytest.raises(OutputNotWritableError) as excinfo:
        check_writable(locked / "new" / "s.npz")
    assert str(excinfo.value) == (
        f"cannot write {locked / 'new' / 's.npz'}: the folder {locked} is not writable"
    )


def test_skin_commands_refuse_before_simulating_recording_or_viewing(blocker, monkeypatch):
    work_must_not_start(
        monkeypatch,
        "wovenskin.sim.stream:simulate_stream",
        "wovenskin.ui.record_session:run_record_session",
        "wovenskin.ui.view:run_view",
    )
    out = blocker / "s.npz"
    refused_at_once(
        cli.invoke(app, ["simulate", "--out", str(out), "--seconds", "2"]), out, blocker
    )
    out = blocker / "r.wsrec"
    refused_at_once(cli.invoke(app, ["record", "--out", str(out)]), out, blocker)
    out = blocker / "v.svg"
    result = cli.invoke(app, ["view", "--seconds", "0.2", "--snapshot", str(out)])
    refused_at_once(result, out, blocker)


def test_an_unwritable_folder_names_the_users_path_not_a_partial_file(tmp_path, monkeypatch):
    locked = tmp_path / "locked"
    locked.mkdir()
    work_must_not_start(monkeypatch, "wovenskin.sim.stream:simulate_stream")
    monkeypatch.setattr("wovenskin.outputs.os.access", lambda p, mode: str(p) != str(locked))
    out = locked / "s.npz"
    result = cli.invoke(app, ["simulate", "--out", str(out), "--seconds", "2"])
    assert result.exit_code == 2 and ".partial" not in result.output
    assert f"cannot write {out}: the folder {locked} is not writable" in " ".join(
        result.output.split()
    )


def test_run_refuses_its_trace_and_recording_before_the_session(tmp_path, blocker, monkeypatch):
    work_must_not_start(monkeypatch, "wovenskin.runtime.session:open_session")
    for option, name in (("--trace", "t.jsonl"), ("--record", "r.wsrec")):
        out = blocker / name
        result = cli.invoke(app, ["run", "--headless", "--seconds", "1", option, str(out)])
        refused_at_once(result, out, blocker)


def test_training_commands_refuse_before_building_or_training(blocker, monkeypatch):
    work_must_not_start(
        monkeypatch,
        "wovenskin.training.datasets.streams:run_jobs",
        "wovenskin.training.report:evaluate_on_dataset",
    )
    out = blocker / "ds"
    refused_at_once(cli.invoke(app, ["dataset", "--out", str(out)]), out, blocker)
    out = blocker / "model"
    refused_at_once(cli.invoke(app, ["train", "--out", str(out)]), out, blocker)
    out = blocker / "eval"
    refused_at_once(cli.invoke(app, ["eval", "--out", str(out)]), out, blocker)
    out = blocker / "compare"
    refused_at_once(cli.invoke(app, ["compare", "--out", str(out)]), out, blocker)


def test_adapt_reproduce_and_benches_refuse_at_once(tmp_path, blocker, monkeypatch):
    work_must_not_start(
        monkeypatch,
        "wovenskin.training.adapt:adapt_model",
        "wovenskin.bench.adapt:run_adapt_benchmark",
        "wovenskin.bench.ros2:run_ros2_benchmark",
        "wovenskin.bench.gestures:run_gestures_benchmark",
    )
    recording = tmp_path / "mine.npz"
    out = blocker / "adapted"
    refused_at_once(cli.invoke(app, ["adapt", str(recording), "--out", str(out)]), out, blocker)
    out = blocker / "report"
    result = cli.invoke(app, ["reproduce", "--out", str(out), "--size", "tiny"])
    assert f"cannot write {out / 'report.md'}: {blocker} is a file" in " ".join(
        result.output.split()
    )
    for bench, option in (("adapt", "--out"), ("ros2", "--out"), ("gestures", "--save-streams")):
        out = blocker / bench
        refused_at_once(cli.invoke(app, ["bench", bench, option, str(out)]), out, blocker)


def test_study_commands_refuse_before_any_trial(tmp_path, blocker, monkeypatch):
    work_must_not_start(monkeypatch, "wovenskin.study.simulate:run_jobs")
    out = blocker / "sim"
    result = cli.invoke(app, ["study", "simulate", str(out), "--participants", "1"])
    refused_at_once(result, out, blocker)
    out = blocker / "synthetic"
    refused_at_once(cli.invoke(app, ["study", "synthetic", str(out)]), out, blocker)
    study = tmp_path / "study"
    assert cli.invoke(app, ["study", "synthetic", str(study), "--participants", "1"]).exit_code == 0
    out = blocker / "report"
    result = cli.invoke(app, ["study", "report", str(study), "--out", str(out)])
    refused_at_once(result, out / "report.md", blocker)
