"""Append-only CSV and JSON-lines logs flushed line by line, and their tolerant readers."""

from __future__ import annotations

import csv
import json
import math
import os
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

from wovenskin.errors import DataError
from wovenskin.io import dumps


def _cell(value: Any) -> Any:
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else ""
    if value is None:
        return ""
    return value


class LineLog:
    """A CSV (``columns`` given) or JSON-lines file, appended and flushed one line at a
    time: a process killed at any moment leaves every earlier line whole (at most the last
    one torn, which :func:`read_csv_rows` and :func:`read_jsonl` drop)."""

    def __init__(self, path: str | Path, columns: Sequence[str] | None = None) -> None:
        self.path = Path(path)
        self.columns = tuple(columns) if columns is not None else None
        existed = self.path.exists() and self.path.stat().st_size > 0
        if existed and self.columns is not None:
            header = read_header(self.path)
            if header != list(self.columns):
                raise DataError(f"{self.path}: its columns {header} are not {list(self.columns)}")
        self._file = open(self.path, "a", newline="", encoding="utf-8")  # noqa: SIM115
        if existed:
            self._end_torn_line()
        self._csv = csv.writer(self._file, lineterminator="\n") if self.columns else None
        if self.columns is not None and not existed:
            self.write_row(self.columns)

    def _end_torn_line(self) -> None:
        """A file whose last line was torn by a crash gets a newline first: the torn line
        stays as it is (readers drop it) and the next line starts whole."""
        with open(self.path, "rb") as f:
            f.seek(-1, os.SEEK_END)
            if f.read(1) != b"\n":
                self._file.write("\n")

    def write_row(self, values: Iterable[Any]) -> None:
        assert self._csv is not None, "a JSON-lines log takes write_json"
        self._csv.writerow([_cell(v) for v in values])
        self._file.flush()

    def write_json(self, value: Any) -> None:
        self._file.write(dumps(value) + "\n")
        self._file.flush()

    def sync(self) -> None:
        """Flush and ask the OS to put the file on disk (survives a power cut too)."""
        if not self._file.closed:
            self._file.flush()
            os.fsync(self._file.fileno())

    def close(self) -> None:
        if not self._file.closed:
            self._file.close()


def _whole_lines(path: Path) -> tuple[list[str], bool]:
    """The lines of ``path`` that end in a newline, and whether a torn one followed."""
    text = path.read_text(encoding="utf-8", errors="replace")
    lines = text.split("\n")
    torn = lines.pop() != ""
    return lines, torn


def read_header(path: str | Path) -> list[str]:
    with open(path, newline="", encoding="utf-8") as f:
        return next(csv.reader(f), [])


def read_csv_rows(path: str | Path) -> tuple[list[dict[str, str]], bool]:
    """The whole rows of the CSV log ``path`` as dicts, and whether a torn last line (or a
    row of the wrong width, a torn line left mid-file by a crash) was dropped."""
    lines, torn = _whole_lines(Path(path))
    rows = list(csv.reader(lines))
    if not rows:
        return [], torn
    header, body = rows[0], [row for row in rows[1:] if row]
    whole = [dict(zip(header, row, strict=True)) for row in body if len(row) == len(header)]
    return whole, torn or len(whole) != len(body)


def read_jsonl(path: str | Path) -> tuple[list[dict[str, Any]], bool]:
    """The whole records of the JSON-lines log ``path``, and whether a torn one was dropped."""
    lines, torn = _whole_lines(Path(path))
    records = []
    for line in lines:
        if not line.strip():
            continue
        try:
            records.append(json.loads(line))
        except json.JSONDecodeError:
            torn = True
    return records, torn
