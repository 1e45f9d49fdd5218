"""Data is never lost: every writing command refuses an existing output unless
``--overwrite`` (and says so), Ctrl-C in ``record`` exits 130 keeping what was recorded,
and streams whose labels wovenskin does not know are flagged and never scored."""

from __future__ import annotations

import numpy as np
import pytest
from typer.testing import CliRunner

from wovenskin.cli import app
from wovenskin.outputs import OutputExistsError, check_new_output, open_new
from wovenskin.recognition.event_scoring import score_commands
from wovenskin.recording.formats import read_labelled_stream, write_labelled_stream
from wovenskin.recording.native import read_recording
from wovenskin.sim.stream import simulate_stream

cli = CliRunner()
PRECIOUS = b"sixty seconds of somebody's recording"


def refused(result, path) -> None:
    """A one-line refusal naming the file and the flag; the file is untouched."""
    text = " ".join(result.output.split())
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    assert f"{path} exists; pass --overwrite to replace it" in text, text
    assert "overwrite=True" not in text  # Python wording stays in Python
    assert path.read_bytes() == PRECIOUS


def test_the_library_refusal_names_the_keyword_and_the_cli_the_flag(tmp_path):
    path = tmp_path / "x"
    path.write_bytes(PRECIOUS)
    with pytest.raises(OutputExistsError, match="pass overwrite=True") as excinfo:
        check_new_output(path, overwrite=False)
    assert excinfo.value.message("--overwrite") == f"{path} exists; pass --overwrite to replace it"
    with pytest.raises(FileExistsError):  # still a FileExistsError for older callers
        open_new(path, overwrite=False)
    assert check_new_output(path, overwrite=True) == path
    assert check_new_output(tmp_path / "new", overwrite=False) == tmp_path / "new"


def test_simulate_refuses_to_replace_a_stream(tmp_path):
    out = tmp_path / "s.npz"
    out.write_bytes(PRECIOUS)
    refused(cli.invoke(app, ["simulate", "--out", str(out), "--seconds", "2"]), out)
    result = cli.invoke(app, ["simulate", "--out", str(out), "--seconds", "2", "--overwrite"])
    assert result.exit_code == 0, result.output
    assert read_labelled_stream(out).frames.shape[0] == 400


def test_record_refuses_naming_the_flag(tmp_path):
    out = tmp_path / "r.wsrec"
    out.write_bytes(PRECIOUS)
    refused(cli.invoke(app, ["record", "--out", str(out), "--gestures", "push"]), out)


def test_convert_and_run_trace_refuse_naming_the_flag(tmp_path):
    src = tmp_path / "s.npz"
    write_labelled_stream(src, simulate_stream(2.0, seed=1))
    out = tmp_path / "out.wsrec"
    out.write_bytes(PRECIOUS)
    refused(cli.invoke(app, ["convert", str(src), str(out)]), out)
    trace = tmp_path / "t.jsonl"
    trace.write_bytes(PRECIOUS)
    args = ["run", "--headless", "--skin", f"replay:{src}", "--trace", str(trace)]
    refused(cli.invoke(app, args), trace)


def test_view_refuses_to_replace_a_snapshot_before_it_starts(tmp_path):
    snapshot = tmp_path / "v.svg"
    snapshot.write_bytes(PRECIOUS)
    args = ["view", "--skin", "sim", "--seconds", "0.2", "--snapshot", str(snapshot)]
    refused(cli.invoke(app, args), snapshot)


def test_train_refuses_to_replace_a_trained_model(tmp_path):
    out = tmp_path / "model"
    out.mkdir()
    (out / "model.onnx").write_bytes(PRECIOUS)
    result = cli.invoke(app, ["train", "--data", str(tmp_path / "nowhere"), "--out", str(out)])
    text = " ".join(result.output.split())
    assert result.exit_code == 2, result.output
    assert "already holds a trained model" in text and "--overwrite" in text
    assert (out / "model.onnx").read_bytes() == PRECIOUS


def test_ctrl_c_in_record_exits_130_and_keeps_what_was_recorded(tmp_path, monkeypatch):
    from wovenskin.ui import record_session

    real_pump = record_session._Session._pump
    calls = {"n": 0}

    def pump_then_ctrl_c(self, prompt):
        calls["n"] += 1
        if calls["n"] > 150:  # past calibration: some frames are in the file
            raise KeyboardInterrupt
        return real_pump(self, prompt)

    monkeypatch.setattr(record_session._Session, "_pump", pump_then_ctrl_c)
    out = tmp_path / "r.wsrec"
    result = cli.invoke(app, ["record", "--out", str(out), "--gestures", "push", "--trials", "1"])
    assert result.exit_code == 130, result.output
    text = " ".join(result.output.split())
    assert "cut short by Ctrl-C" in text and str(out) in text
    recording = read_recording(out)
    assert recording.clean_close and len(recording.t) > 0


# ------------------------------------------------------------------ unknown labels


@pytest.fixture()
def wave_hello(tmp_path):
    """A stream whose events carry a label wovenskin does not know."""
    stream = simulate_stream(3.0, seed=1)
    stream.event_labels = np.array(["wave_hello"] * len(stream.event_labels))
    assert len(stream.event_labels)
    path = tmp_path / "wave.npz"
    write_labelled_stream(path, stream)
    return path


def test_info_flags_an_unknown_gesture_label(wave_hello):
    result = cli.invoke(app, ["info", str(wave_hello)])
    assert result.exit_code == 0, result.output
    text = " ".join(result.output.split())
    assert "unknown gesture label 'wave_hello'" in text


def test_eval_stream_refuses_to_score_unknown_labels(wave_hello):
    result = cli.invoke(app, ["eval-stream", str(wave_hello)])
    assert result.exit_code == 2, result.output
    text = " ".join(result.output.split())
    assert "unknown gesture label 'wave_hello'" in text and "not scored" in text


def test_scoring_refuses_labels_no_command_can_match():
    with pytest.raises(ValueError, match="cannot score events labelled 'wave_hello'"):
        score_commands([], [1.0], [2.0], ["wave_hello"], 10.0)


def test_compare_refuses_a_directory_holding_a_comparison(tmp_path):
    """A finished comparison (its compare.json and checkpoints) is not trained over unless
    --resume or --overwrite; the refusal comes before any data set is opened or built."""
    pytest.importorskip("torch")
    out = tmp_path / "cmp"
    (out / "grouped" / "transformer").mkdir(parents=True)
    (out / "grouped" / "transformer" / "model.onnx").write_bytes(PRECIOUS)
    missing = tmp_path / "no-such-dataset"
    result = cli.invoke(app, ["compare", "--data", str(missing), "--out", str(out)])
    text = " ".join(result.output.split())
    assert result.exit_code == 2, result.output
    assert f"{out} already holds a comparison" in text and "--overwrite" in text, text
    assert (out / "grouped" / "transformer" / "model.onnx").read_bytes() == PRECIOUS
    # with --overwrite the check passes and the command goes on to the (missing) data set
    result = cli.invoke(app, ["compare", "--data", str(missing), "--out", str(out), "--overwrite"])
    assert "already holds a comparison" not in result.output
    assert result.exit_code != 0
