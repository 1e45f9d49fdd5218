"""Tests of the robot commands: ``wovenskin run``, ``pose set``/``pose show``.

``run`` goes through the whole path with a tiny untrained checkpoint (an ONNX model
exported like the shipped one), a replayed simulated stream and the simulated arm.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from cli_helpers import invoke, one_line_error
from tiny_models import save_tiny_model

from wovenskin.control.trace import TRACE_KEYS, read_trace
from wovenskin.gestures import CLASS_NAMES
from wovenskin.recording.formats import write_labelled_stream
from wovenskin.recording.native import read_recording
from wovenskin.sim.stream import simulate_stream


@pytest.fixture(scope="module")
def model_dir(tmp_path_factory) -> Path:
    """A tiny untrained TCN checkpoint with model.onnx (as in the pipeline tests)."""
    return save_tiny_model(tmp_path_factory.mktemp("model"), seed=1)


@pytest.fixture(scope="module")
def stream_file(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("stream") / "s.npz"
    write_labelled_stream(path, simulate_stream(4.0, seed=2))
    return path


def test_headless_run_writes_the_trace_and_nothing_to_stdout(model_dir, stream_file, tmp_path):
    trace = tmp_path / "trace.jsonl"
    record = tmp_path / "session.wsrec"
    result = invoke(
        "run", "--skin", f"replay:{stream_file}", "--robot", "sim", "--model", model_dir,
        "--headless", "--trace", trace, "--record", record, "--poses", tmp_path / "p.toml",
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    assert result.stdout == ""
    assert "control ticks" in result.stderr and "the skin stream ended" in result.stderr
    records = read_trace(trace)
    assert len(records) > 600  # 4 s at 200 Hz less the calibration
    for r in records[:: len(records) // 10]:
        assert tuple(r) == TRACE_KEYS
        assert len(r["tcp"]) == 3 and len(r["quat"]) == 4 and len(r["q"]) == 6
        assert 0.1 < sum(v * v for v in r["tcp"]) ** 0.5 < 1.5  # metres, within the arm's reach
        assert r["gesture"] is None or r["gesture"] in CLASS_NAMES
    assert 0.4 < records[0]["t"] < 1.0 and records[-1]["t"] <= 4.0  # the stream's own clock
    recording = read_recording(record)
    assert len(recording.t) == 800 and recording.annotations_of("robot")


def test_trace_to_stdout_is_only_json_lines(model_dir, stream_file, tmp_path) -> None:
    result = invoke(
        "run", "--skin", f"replay:{stream_file}", "--model", model_dir, "--headless",
        "--trace", "-", "--seconds", "2", "--poses", tmp_path / "p.toml",
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    lines = result.stdout.splitlines()
    assert len(lines) > 250
    assert all(tuple(json.loads(line)) == TRACE_KEYS for line in lines)
    assert "2 s elapsed" in result.stderr


def test_run_refuses_bad_options_in_one_line(model_dir, stream_file, tmp_path) -> None:
    skin = f"replay:{stream_file}"
    one_line_error(
        invoke("run", "--skin", skin, "--model", model_dir, "--headless", "--robot", "abb:x"),
        "robot spec 'abb:x'",
    )
    one_line_error(
        invoke("run", "--skin", skin, "--model", model_dir, "--trace", "-"), "needs --headless"
    )
    one_line_error(
        invoke("run", "--skin", skin, "--model", tmp_path / "nowhere", "--headless"),
        "no such model directory",
    )
    existing = tmp_path / "t.jsonl"
    existing.write_text("")
    one_line_error(
        invoke("run", "--skin", skin, "--model", model_dir, "--headless", "--trace", existing),
        "exists",
    )
    one_line_error(
        invoke("run", "--skin", "replay:missing.npz", "--model", model_dir, "--headless"),
        "no such file",
    )


def test_pose_set_and_show(tmp_path) -> None:
    poses = tmp_path / "poses.toml"
    result = invoke("pose", "show", "--poses", poses)
    assert result.exit_code == 0 and "no poses stored" in result.stdout
    # Go home / Go to initial work from the simulated arm's built-in poses: shown, with where
    # they come from, not just "no poses"
    assert "built-in poses of the simulated TM5-900" in result.stdout
    assert "tm5_900.py" in result.stdout
    assert "  home: joints [0.0, 0.0, 0.0, 0.0, 0.0, 0.0] deg" in result.stdout
    assert "  initial: joints [0.0, 0.0, 90.0, 0.0, 90.0, 0.0] deg" in result.stdout
    result = invoke("pose", "set", "initial", "--robot", "sim", "--poses", poses)
    assert result.exit_code == 0, result.output
    assert result.stdout.startswith("stored initial: joints [") and "TCP x" in result.stdout
    assert poses.is_file()
    result = invoke("pose", "show", "--poses", poses)
    assert result.exit_code == 0 and result.stdout.startswith("initial: joints [")
    assert "0.0, 0.0, 90.0, 0.0, 90.0, 0.0] deg" in result.stdout  # the sim arm's ready pose
    assert f"stored in {poses}" in result.stdout
    assert "  home: joints" in result.stdout and "  initial:" not in result.stdout  # built-in
    one_line_error(invoke("pose", "set", "initial", "--robot", "tm", "--poses", poses), "robot")
    one_line_error(invoke("pose", "set", "work", "--poses", poses), "unknown pose name")


def _free_port() -> int:
    import socket

    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


@pytest.mark.slow
def test_run_opens_the_dashboard_by_default_and_ends_after_seconds(model_dir, tmp_path) -> None:
    port = _free_port()
    record = tmp_path / "dash.wsrec"
    result = invoke(
        "run", "--model", model_dir, "--no-open", "--port", port, "--seconds", 3,
        "--record", record, "--poses", tmp_path / "p.toml",
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    assert f"http://127.0.0.1:{port}/" in result.stdout
    assert "skin sim:auto=0" in result.stdout and "robot sim" in result.stdout
    assert "dashboard closed" in result.stdout
    assert len(read_recording(record).t) > 200  # the command line's recording was written


def test_the_dashboard_refuses_bad_options_in_one_line(model_dir) -> None:
    import socket

    one_line_error(invoke("run", "--view", "vr", "--model", model_dir), "--view must be")
    one_line_error(invoke("run", "--ui-rate", 200, "--model", model_dir), "--ui-rate must be")
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        one_line_error(
            invoke("run", "--port", port, "--model", model_dir, "--no-open"), "cannot listen"
        )


def test_run_inputs_and_tasks_refuse_bad_combinations_in_one_line(model_dir) -> None:
    one_line_error(
        invoke("run", "--input", "pendant", "--view", "terminal"), "panel of the web dashboard"
    )
    one_line_error(invoke("run", "--input", "mouse"), "--input must be")
    one_line_error(invoke("run", "--input", "keyboard", "--headless"), "needs a view")
    one_line_error(
        invoke("run", "--view", "terminal", "--study", "somewhere", "--model", model_dir),
        "study panel",
    )
    one_line_error(
        invoke("run", "--headless", "--task", "pour", "--robot", "tm:10.0.0.9", "--model",
               model_dir),
        "tasks run on the simulated arm",
    )  # fmt: skip
    one_line_error(
        invoke("run", "--headless", "--task", "juggle", "--model", model_dir), "unknown task"
    )


def test_keyboard_run_on_a_task_in_the_terminal_view(model_dir) -> None:
    result = invoke(
        "run", "--input", "keyboard", "--task", "pick_place", "--seconds", "0.5",
        "--model", model_dir,
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    assert "task pick_place" in result.output and "g: gripper" in result.output


def test_headless_run_without_a_skin_on_a_task(model_dir) -> None:
    result = invoke(
        "run", "--headless", "--skin", "none:speed=0", "--task", "pour", "--seconds", "1",
        "--model", model_dir,
    )  # fmt: skip
    assert result.exit_code == 0, result.output


def test_ctrl_c_in_run_exits_130_after_its_summary(model_dir, stream_file, monkeypatch) -> None:
    from wovenskin.control.session import ControlSession

    def interrupted(self, seconds=None, should_continue=None):
        raise KeyboardInterrupt

    monkeypatch.setattr(ControlSession, "run", interrupted)
    result = invoke(
        "run", "--skin", f"replay:{stream_file}", "--model", model_dir, "--headless",
    )  # fmt: skip
    assert result.exit_code == 130, result.output
    assert "interrupted (Ctrl-C)" in result.stderr


@pytest.mark.parametrize("port", ["99999", "-1", "0"])
def test_a_port_out_of_range_is_one_line(port) -> None:
    result = invoke("run", "--port", port)
    assert result.exit_code == 2 and "Traceback" not in result.output
    assert "--port" in result.output
