"""Tests of the ``wovenskin`` command line: commands run, and user errors are one line."""

import numpy as np
import pytest
from typer.testing import CliRunner

from wovenskin.cli import app
from wovenskin.recording.formats import read_labelled_stream

runner = CliRunner()


def test_help_lists_the_commands():
    result = runner.invoke(app, ["--help"])
    assert result.exit_code == 0
    for command in ("view", "simulate", "record", "devices", "info", "convert", "bench"):
        assert command in result.output


def test_simulate_writes_a_labelled_stream(tmp_path):
    out = tmp_path / "s.npz"
    result = runner.invoke(app, ["simulate", "--out", str(out), "--seconds", "6", "--seed", "3"])
    assert result.exit_code == 0, result.output
    stream = read_labelled_stream(out)
    assert stream.frames.shape == (1200, 10, 10)
    assert len(stream.event_labels) >= 1
    again = tmp_path / "again.npz"
    runner.invoke(app, ["simulate", "--out", str(again), "--seconds", "6", "--seed", "3"])
    np.testing.assert_array_equal(read_labelled_stream(again).frames, stream.frames)


def test_simulate_rejects_unknown_gesture(tmp_path):
    result = runner.invoke(
        app, ["simulate", "--out", str(tmp_path / "x.npz"), "--gestures", "wave"]
    )
    assert result.exit_code == 2
    assert "unknown gesture 'wave'" in result.output
    assert "Traceback" not in result.output


def test_info_and_convert_round_trip(tmp_path):
    src = tmp_path / "s.npz"
    runner.invoke(app, ["simulate", "--out", str(src), "--seconds", "4", "--seed", "1"])
    result = runner.invoke(app, ["info", str(src)])
    assert result.exit_code == 0 and "stream" in result.output
    rec = tmp_path / "s.wsrec"
    result = runner.invoke(app, ["convert", str(src), str(rec)])
    assert result.exit_code == 0, result.output
    result = runner.invoke(app, ["info", str(rec)])
    assert result.exit_code == 0 and "recording" in result.output
    back = tmp_path / "back.npz"
    assert runner.invoke(app, ["convert", str(rec), str(back)]).exit_code == 0
    a, b = read_labelled_stream(src), read_labelled_stream(back)
    np.testing.assert_array_equal(a.frames, b.frames)
    assert list(a.event_labels) == list(b.event_labels)
    # refuses to overwrite without being asked
    result = runner.invoke(app, ["convert", str(src), str(rec)])
    assert result.exit_code == 2 and "exists" in result.output


@pytest.mark.parametrize(
    "content, message",
    [(None, "no such file"), (b"not a zip and not a recording", "")],
)
def test_info_on_bad_files_is_one_line(tmp_path, content, message):
    path = tmp_path / "bad.npz"
    if content is not None:
        path.write_bytes(content)
    result = runner.invoke(app, ["info", str(path)])
    assert result.exit_code == 2
    assert "Traceback" not in result.output
    assert len(result.output.strip().splitlines()) == 1
    assert message in result.output


def test_view_a_replay_to_the_end(tmp_path):
    src = tmp_path / "s.npz"
    runner.invoke(app, ["simulate", "--out", str(src), "--seconds", "3", "--seed", "2"])
    snap = tmp_path / "screen.svg"
    result = runner.invoke(
        app,
        ["view", "--skin", f"replay:{src}?speed=0", "--seconds", "20", "--snapshot", str(snap)],
    )
    assert result.exit_code == 0, result.output
    assert "0 bad frames" in result.output
    assert snap.read_text().lstrip().startswith("<svg") and "frames" in snap.read_text()


def test_view_missing_replay_file_is_one_line(tmp_path):
    result = runner.invoke(app, ["view", "--skin", f"replay:{tmp_path / 'none.npz'}"])
    assert result.exit_code == 2
    assert "Traceback" not in result.output


def test_unknown_skin_source_is_one_line():
    result = runner.invoke(app, ["view", "--skin", "bluetooth:x"])
    assert result.exit_code == 2
    assert "unknown skin source" in result.output
