"""Line logs: flushed per line, a torn last line dropped on reading and fenced on append."""

from __future__ import annotations

import pytest

from wovenskin.errors import DataError
from wovenskin.study.logfiles import LineLog, read_csv_rows, read_jsonl


def test_each_line_is_on_disk_before_the_log_is_closed(tmp_path):
    log = LineLog(tmp_path / "a.csv", ("t", "x"))
    log.write_row((0.5, "a,b"))
    rows, torn = read_csv_rows(tmp_path / "a.csv")  # read while still open
    assert rows == [{"t": "0.5", "x": "a,b"}] and not torn
    log.close()


def test_a_torn_last_line_is_dropped_and_the_next_append_starts_whole(tmp_path):
    path = tmp_path / "a.csv"
    log = LineLog(path, ("t", "x"))
    log.write_row((1.0, 2))
    log.write_row((2.0, 3))
    log.close()
    path.write_bytes(path.read_bytes()[:-3])  # killed mid-line
    rows, torn = read_csv_rows(path)
    assert rows == [{"t": "1.0", "x": "2"}] and torn
    log = LineLog(path, ("t", "x"))
    log.write_row((3.0, 4))
    log.close()
    rows, torn = read_csv_rows(path)
    assert rows == [{"t": "1.0", "x": "2"}, {"t": "3.0", "x": "4"}] and torn


def test_jsonl_drops_a_torn_record(tmp_path):
    log = LineLog(tmp_path / "e.jsonl")
    log.write_json({"t": 1})
    log.close()
    with (tmp_path / "e.jsonl").open("a") as f:
        f.write('{"t": 2, "ev')
    records, torn = read_jsonl(tmp_path / "e.jsonl")
    assert records == [{"t": 1}] and torn


def test_an_existing_log_with_other_columns_is_refused(tmp_path):
    LineLog(tmp_path / "a.csv", ("t", "x")).close()
    with pytest.raises(DataError, match="columns"):
        LineLog(tmp_path / "a.csv", ("t", "y"))
