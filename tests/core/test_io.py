"""wovenskin.io: atomic writes leave the old file or the new one, never half; JSON-ready values."""

from __future__ import annotations

import json
import os
import stat
from pathlib import Path

import numpy as np
import pytest

from wovenskin.io import (
    atomic_write_bytes,
    atomic_write_text,
    atomic_writer,
    dumps,
    to_jsonable,
    write_json,
)


def test_a_failed_write_leaves_the_old_file_and_no_temporary(tmp_path: Path) -> None:
    target = tmp_path / "out.txt"
    atomic_write_text(target, "old")
    with pytest.raises(RuntimeError), atomic_writer(target, binary=False) as f:
        f.write("half of the new")
        raise RuntimeError("crash mid-write")
    assert target.read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.txt"]


def test_writes_replace_and_get_the_mode_a_plain_open_gives(tmp_path: Path) -> None:
    target = tmp_path / "out.bin"
    atomic_write_bytes(target, b"one")
    atomic_write_bytes(target, b"two")
    assert target.read_bytes() == b"two"
    plain = tmp_path / "plain.bin"
    plain.write_bytes(b"")
    assert stat.S_IMODE(os.stat(target).st_mode) == stat.S_IMODE(os.stat(plain).st_mode)


def test_numpy_values_paths_and_tuples_become_plain_json(tmp_path: Path) -> None:
    value = {
        "a": np.arange(3),
        "b": np.float32(0.5),
        "c": (np.int64(2), Path("x/y")),
        3: [np.bool_(True)],
    }
    assert to_jsonable(value) == {"a": [0, 1, 2], "b": 0.5, "c": [2, "x/y"], "3": [True]}
    write_json(tmp_path / "v.json", value)
    assert json.loads((tmp_path / "v.json").read_text())["a"] == [0, 1, 2]


def test_dumps_refuses_nan_unless_asked() -> None:
    with pytest.raises(ValueError):
        dumps({"x": float("nan")})
    assert dumps({"x": float("nan")}, allow_nan=True) == '{"x": NaN}'
