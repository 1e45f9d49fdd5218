"""Tests of wovenskin.control.trace: exact keys, units, files, stdout and bad lines."""

from __future__ import annotations

import io
import json

import numpy as np
import pytest

from wovenskin.control.trace import TRACE_KEYS, TraceWriter, read_trace, trace_record
from wovenskin.robots.base import Pose, RobotState


def state(x: float = 0.4, vx: float = 0.03) -> RobotState:
    half = np.sqrt(0.5)
    return RobotState(
        t=12.0,
        q=np.array([0.1, -0.2, 0.3, -0.4, 0.5, -0.6]),
        dq=np.zeros(6),
        tcp=Pose(np.array([x, -0.1, 0.25]), np.array([half, half, 0.0, 0.0])),
        tcp_twist=np.array([vx, 0.04, 0.0, 0.2, 0.0, 0.0]),
    )


def test_a_record_has_exactly_the_keys_in_si_units() -> None:
    record = trace_record(3.25, "swipe_up", state())
    assert tuple(record) == TRACE_KEYS == ("t", "gesture", "tcp", "quat", "tcp_speed", "q")
    assert record["t"] == 3.25 and record["gesture"] == "swipe_up"
    assert record["tcp"] == [0.4, -0.1, 0.25]  # metres, as the robot reports them
    assert record["quat"] == pytest.approx([np.sqrt(0.5), np.sqrt(0.5), 0.0, 0.0])
    assert record["tcp_speed"] == pytest.approx(0.05)  # |(0.03, 0.04, 0)| m/s; rotation ignored
    assert record["q"] == pytest.approx([0.1, -0.2, 0.3, -0.4, 0.5, -0.6])
    assert trace_record(0.0, None, state())["gesture"] is None
    json.dumps(record)  # plain JSON values only
    with pytest.raises(ValueError, match="finite"):
        trace_record(float("nan"), None, state())


def test_writer_and_reader_round_trip(tmp_path) -> None:
    path = tmp_path / "trace.jsonl"
    with TraceWriter(path, flush_every=2) as writer:
        for i in range(5):
            writer.write(i / 200, "push" if i % 2 else None, state(x=0.4 + i * 0.001))
    assert writer.lines == 5
    lines = path.read_text().splitlines()
    assert len(lines) == 5 and all(tuple(json.loads(line)) == TRACE_KEYS for line in lines)
    records = read_trace(path)
    assert [r["t"] for r in records] == [0.0, 0.005, 0.01, 0.015, 0.02]
    assert [r["gesture"] for r in records] == [None, "push", None, "push", None]
    assert records[4]["tcp"][0] == pytest.approx(0.404)
    with pytest.raises(ValueError, match="closed"):
        writer.write(1.0, None, state())
    writer.close()  # twice is fine


def test_an_existing_file_is_kept_unless_overwritten(tmp_path) -> None:
    path = tmp_path / "trace.jsonl"
    path.write_text("keep me\n")
    with pytest.raises(FileExistsError, match="exists"):
        TraceWriter(path)
    assert path.read_text() == "keep me\n"
    with TraceWriter(path, overwrite=True) as writer:
        writer.write(1.0, None, state())
    assert len(read_trace(path)) == 1


def test_stdout_and_streams(capsys) -> None:
    with TraceWriter("-") as writer:
        writer.write(0.5, "swipe_left", state())
    out = capsys.readouterr().out
    assert json.loads(out)["gesture"] == "swipe_left" and out.count("\n") == 1
    buffer = io.StringIO()
    with TraceWriter(buffer) as writer:
        writer.write(0.5, None, state())
    assert not buffer.closed  # a stream the writer did not open stays open
    assert json.loads(buffer.getvalue())["t"] == 0.5


def test_read_trace_names_a_bad_line(tmp_path) -> None:
    path = tmp_path / "bad.jsonl"
    good = json.dumps(trace_record(0.0, None, state()))
    path.write_text(good + "\n{not json\n")
    with pytest.raises(ValueError, match=r"bad.jsonl:2: not JSON"):
        read_trace(path)
    path.write_text(good + "\n" + json.dumps({"t": 1.0, "gesture": None}) + "\n")
    with pytest.raises(ValueError, match=r":2: a trace line needs exactly"):
        read_trace(path)
