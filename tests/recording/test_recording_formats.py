"""Tests for wovenskin.recording.formats: the labelled-stream and labelled-captures .npz files."""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tests.conftest import SHARED
from wovenskin.recording.formats import (
    METADATA_JSON_KEY,
    LabelledCaptures,
    LabelledStream,
    read_labelled_captures,
    read_labelled_stream,
    write_labelled_captures,
    write_labelled_stream,
)
from wovenskin.recording.untrusted import FormatError

HAART = SHARED / "datasets" / "haart" / "haart-train.npz"


def stream_arrays(n_frames: int = 20, rows: int = 4, cols: int = 3) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(0)
    return {
        "frames": rng.normal(100.0, 1.0, (n_frames, rows, cols)).astype(np.float32),
        "t": np.arange(n_frames) / 200.0,
        "sample_rate_hz": np.float64(200.0),
        "event_start_s": np.array([0.01, 0.05]),
        "event_end_s": np.array([0.03, 0.09]),
        "event_labels": np.array(["swipe_up", "invalid"]),
    }


def captures_arrays(n: int = 6, t_max: int = 8) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(1)
    return {
        "frames": rng.integers(0, 1023, (n, t_max, 3, 3)).astype(np.uint16),
        "lengths": np.array([t_max, 3, 5, t_max, 1, 7][:n], dtype=np.int64),
        "labels": np.arange(n, dtype=np.int64) % 3,
        "class_names": np.array(["pat", "rub", "stroke"]),
        "groups": np.array(["p1", "p1", "p2", "p2", "p3", "p3"][:n]),
        "sample_rate_hz": np.float64(54.0),
    }


def save(path: Path, arrays: dict[str, np.ndarray]) -> Path:
    with open(path, "wb") as f:
        np.savez(f, **arrays)
    return path


def assert_one_line_error(excinfo: pytest.ExceptionInfo, path: Path, *words: str) -> None:
    message = str(excinfo.value)
    assert "\n" not in message
    assert str(path) in message
    for word in words:
        assert word in message, message


# ----------------------------------------------------------------------------- HAART


@pytest.mark.skipif(not HAART.exists(), reason=f"HAART data set not present at {HAART}")
def test_reads_the_haart_captures():
    captures = read_labelled_captures(HAART)
    assert captures.frames.shape == (588, 540, 10, 10)
    assert captures.frames.dtype == np.uint16  # integer frames are kept as read
    assert captures.class_names == [
        "constant", "notouch", "pat", "rub", "scratch", "stroke", "tickle",
    ]  # fmt: skip
    assert sorted(set(captures.groups.tolist())) == ["p10", "p3", "p4", "p5", "p6", "p7", "p8"]
    assert captures.sample_rate_hz == 54.0
    assert captures.lengths.dtype == np.int64 and np.all(captures.lengths == 540)
    assert np.bincount(captures.labels).tolist() == [84] * 7
    assert set(captures.metadata) == {"substrate", "cover"}
    assert captures.metadata["cover"].shape == (588,)


@pytest.mark.skipif(not HAART.exists(), reason=f"HAART data set not present at {HAART}")
def test_haart_subset_round_trips(tmp_path):
    captures = read_labelled_captures(HAART)
    keep = np.flatnonzero(captures.groups == "p3")[:12]
    subset = LabelledCaptures(
        frames=captures.frames[keep],
        lengths=captures.lengths[keep],
        labels=captures.labels[keep],
        class_names=captures.class_names,
        groups=captures.groups[keep],
        sample_rate_hz=captures.sample_rate_hz,
        metadata={k: v[keep] for k, v in captures.metadata.items()},
    )
    write_labelled_captures(tmp_path / "subset.npz", subset)
    back = read_labelled_captures(tmp_path / "subset.npz")
    np.testing.assert_array_equal(back.frames, subset.frames)
    np.testing.assert_array_equal(back.labels, subset.labels)
    np.testing.assert_array_equal(back.metadata["substrate"], subset.metadata["substrate"])


# ----------------------------------------------------------------------------- round trips


def test_stream_round_trip_keeps_everything(tmp_path):
    arrays = stream_arrays()
    stream = LabelledStream(
        frames=arrays["frames"],
        t=arrays["t"],
        sample_rate_hz=200.0,
        event_start_s=arrays["event_start_s"],
        event_end_s=arrays["event_end_s"],
        event_labels=arrays["event_labels"],
        metadata={"participant": "p7", "gain": [1.0, 2.0], "mask": np.eye(3, dtype=bool)},
    )
    path = tmp_path / "s.npz"
    write_labelled_stream(path, stream)
    back = read_labelled_stream(path)
    np.testing.assert_array_equal(back.frames, stream.frames)
    assert back.frames.dtype == np.float32
    np.testing.assert_array_equal(back.t, stream.t)
    assert back.sample_rate_hz == 200.0
    assert back.event_labels.tolist() == ["swipe_up", "invalid"]
    np.testing.assert_array_equal(back.event_end_s, stream.event_end_s)
    assert back.metadata["participant"] == "p7" and back.metadata["gain"] == [1.0, 2.0]
    np.testing.assert_array_equal(back.metadata["mask"], np.eye(3, dtype=bool))
    assert not list(tmp_path.glob("*.partial"))


def test_stream_metadata_is_a_plain_json_string_other_tools_can_ignore(tmp_path):
    path = tmp_path / "s.npz"
    write_labelled_stream(
        path, LabelledStream(np.zeros((3, 2, 2)), np.arange(3.0), 10.0, metadata={"a": 1})
    )
    with np.load(path, allow_pickle=False) as npz:
        assert npz[METADATA_JSON_KEY].dtype.kind == "U"
        assert npz["frames"].shape == (3, 2, 2)


def test_stream_without_events_and_with_integer_frames(tmp_path):
    arrays = stream_arrays()
    arrays = {k: arrays[k] for k in ("t", "sample_rate_hz")}
    arrays["frames"] = np.arange(20 * 12, dtype=np.int16).reshape(20, 4, 3)
    stream = read_labelled_stream(save(tmp_path / "s.npz", arrays))
    assert stream.frames.dtype == np.int16  # kept as read
    assert stream.event_labels.size == 0 and stream.event_start_s.size == 0
    assert stream.metadata == {}


@settings(max_examples=25, deadline=None)
@given(
    n_frames=st.integers(1, 12),
    rows=st.integers(1, 5),
    cols=st.integers(1, 5),
    n_events=st.integers(0, 4),
    dtype=st.sampled_from(["float32", "float64", "uint16", "int32"]),
    seed=st.integers(0, 2**16),
)
def test_stream_round_trip_property(tmp_path_factory, n_frames, rows, cols, n_events, dtype, seed):
    rng = np.random.default_rng(seed)
    frames = (rng.random((n_frames, rows, cols)) * 1000).astype(dtype)
    starts = rng.random(n_events) * 5
    stream = LabelledStream(
        frames=frames,
        t=np.cumsum(rng.random(n_frames) + 1e-3),
        sample_rate_hz=float(rng.integers(1, 1000)),
        event_start_s=starts,
        event_end_s=starts + rng.random(n_events),
        event_labels=np.array([f"g{i}" for i in range(n_events)], dtype=str),
    )
    path = tmp_path_factory.mktemp("prop") / "s.npz"
    write_labelled_stream(path, stream)
    back = read_labelled_stream(path)
    np.testing.assert_array_equal(
        back.frames, frames.astype(np.float32) if "float" in dtype else frames
    )
    np.testing.assert_array_equal(back.t, stream.t)
    np.testing.assert_array_equal(back.event_start_s, stream.event_start_s)
    assert back.event_labels.tolist() == stream.event_labels.tolist()


def test_captures_round_trip_keeps_extra_keys(tmp_path):
    arrays = captures_arrays()
    arrays["cover"] = np.array(["fur", "none", "fur", "fur", "none", "fur"])
    first = read_labelled_captures(save(tmp_path / "c.npz", arrays))
    assert first.metadata.keys() == {"cover"}
    first.metadata["note"] = "subset"
    write_labelled_captures(tmp_path / "c2.npz", first)
    back = read_labelled_captures(tmp_path / "c2.npz")
    np.testing.assert_array_equal(back.frames, arrays["frames"])
    assert back.frames.dtype == np.uint16
    assert back.class_names == ["pat", "rub", "stroke"]
    np.testing.assert_array_equal(back.groups, arrays["groups"])
    np.testing.assert_array_equal(back.metadata["cover"], arrays["cover"])
    assert back.metadata["note"] == "subset"


def test_captures_nan_only_in_padding_is_accepted(tmp_path):
    arrays = captures_arrays()
    frames = arrays["frames"].astype(np.float32)
    frames[1, 3:] = np.nan  # capture 1 has 3 valid frames
    arrays["frames"] = frames
    assert read_labelled_captures(save(tmp_path / "c.npz", arrays)).frames.dtype == np.float32
    frames[1, 2, 0, 0] = np.nan
    with pytest.raises(FormatError, match="NaN"):
        read_labelled_captures(save(tmp_path / "c.npz", arrays))


# ----------------------------------------------------------------------------- bad files


def with_change(base: dict, **changes) -> dict:
    out = {**base, **changes}
    return {k: v for k, v in out.items() if v is not None}


BAD_STREAMS = {
    "missing key": (with_change(stream_arrays(), t=None), ["missing key 't'"]),
    "frames 2-D": (with_change(stream_arrays(), frames=np.zeros((20, 12))), ["'frames'", "shape"]),
    "frames text": (with_change(stream_arrays(), frames=np.full((20, 4, 3), "x")), ["dtype"]),
    "frames bool": (with_change(stream_arrays(), frames=np.zeros((20, 4, 3), bool)), ["dtype"]),
    "frames empty": (with_change(stream_arrays(), frames=np.zeros((0, 4, 3))), ["empty"]),
    "frames NaN": (
        with_change(
            stream_arrays(), frames=np.where(np.eye(3)[0], np.nan, 1.0) * np.ones((20, 4, 3))
        ),
        ["NaN", "'frames'"],
    ),
    "t short": (with_change(stream_arrays(), t=np.arange(19.0)), ["'t'", "(20,)"]),
    "t decreasing": (with_change(stream_arrays(), t=np.arange(20.0)[::-1]), ["increasing"]),
    "t NaN": (with_change(stream_arrays(), t=np.r_[np.arange(19.0), np.nan]), ["'t'", "NaN"]),
    "rate zero": (with_change(stream_arrays(), sample_rate_hz=np.float64(0)), ["> 0"]),
    "rate array": (with_change(stream_arrays(), sample_rate_hz=np.ones(3)), ["scalar"]),
    "events partial": (with_change(stream_arrays(), event_end_s=None), ["come together"]),
    "events lengths": (with_change(stream_arrays(), event_end_s=np.ones(3)), ["'event_end_s'"]),
    "event backwards": (
        with_change(stream_arrays(), event_end_s=np.array([0.0, 0.09])),
        ["event 0", "before it starts"],
    ),
    "labels not str": (with_change(stream_arrays(), event_labels=np.array([1, 2])), ["strings"]),
    "bad metadata": (
        with_change(stream_arrays(), **{METADATA_JSON_KEY: np.array("{not json")}),
        ["not valid JSON"],
    ),
}


BAD_CAPTURES = {
    "missing key": (with_change(captures_arrays(), groups=None), ["missing key 'groups'"]),
    "frames 3-D": (with_change(captures_arrays(), frames=np.zeros((6, 8, 9))), ["(N, T, R, C)"]),
    "length zero": (
        with_change(captures_arrays(), lengths=np.array([8, 0, 5, 8, 1, 7])),
        ["capture 1", "[1, 8]"],
    ),
    "length too long": (
        with_change(captures_arrays(), lengths=np.array([8, 9, 5, 8, 1, 7])),
        ["capture 1"],
    ),
    "lengths float": (with_change(captures_arrays(), lengths=np.ones(6)), ["integers"]),
    "label out of range": (
        with_change(captures_arrays(), labels=np.array([0, 1, 2, 3, 0, 0])),
        ["capture 3", "class_names"],
    ),
    "groups short": (with_change(captures_arrays(), groups=np.array(["p1"] * 5)), ["'groups'"]),
    "duplicate classes": (
        with_change(captures_arrays(), class_names=np.array(["pat", "pat", "rub"])),
        ["duplicates"],
    ),
    "NaN": (
        with_change(captures_arrays(), frames=np.full((6, 8, 3, 3), np.nan, np.float32)),
        ["NaN"],
    ),
}


BAD_FILES = {
    **{f"stream: {case}": (read_labelled_stream, *bad) for case, bad in BAD_STREAMS.items()},
    **{f"captures: {case}": (read_labelled_captures, *bad) for case, bad in BAD_CAPTURES.items()},
}


@pytest.mark.parametrize("case", sorted(BAD_FILES))
def test_a_bad_file_gives_a_clear_error(tmp_path, case):
    read, arrays, words = BAD_FILES[case]
    path = save(tmp_path / "bad.npz", arrays)
    with pytest.raises(FormatError) as excinfo:
        read(path)
    assert_one_line_error(excinfo, path, *words)


def test_missing_file(tmp_path):
    path = tmp_path / "nope.npz"
    with pytest.raises(FormatError) as excinfo:
        read_labelled_stream(path)
    assert_one_line_error(excinfo, path, "no such file")


def test_not_an_npz(tmp_path):
    path = tmp_path / "text.npz"
    path.write_text("frames,t\n1,2\n")
    with pytest.raises(FormatError) as excinfo:
        read_labelled_captures(path)
    # every reader names a foreign file the same way (files.py: one reader decides)
    assert_one_line_error(excinfo, path, "not a wovenskin data file")


def test_a_directory_is_not_a_file(tmp_path):
    with pytest.raises(FormatError) as excinfo:
        read_labelled_stream(tmp_path)
    assert_one_line_error(excinfo, tmp_path, "is a folder, not a file")


def test_corrupt_zip(tmp_path):
    good = save(tmp_path / "good.npz", stream_arrays(n_frames=400))
    data = bytearray(good.read_bytes())
    data[200:260] = bytes(60)  # damage the first member's data
    path = tmp_path / "corrupt.npz"
    path.write_bytes(bytes(data))
    with pytest.raises(FormatError) as excinfo:
        read_labelled_stream(path)
    assert_one_line_error(excinfo, path)


def test_truncated_npz(tmp_path):
    good = save(tmp_path / "good.npz", stream_arrays())
    path = tmp_path / "cut.npz"
    path.write_bytes(good.read_bytes()[: good.stat().st_size // 2])
    with pytest.raises(FormatError) as excinfo:
        read_labelled_stream(path)
    assert_one_line_error(excinfo, path)


def test_pickled_arrays_are_never_loaded(tmp_path):
    arrays = stream_arrays()
    arrays["event_labels"] = np.array(["swipe_up", "invalid"], dtype=object)
    path = save(tmp_path / "pickled.npz", arrays)
    with pytest.raises(FormatError) as excinfo:
        read_labelled_stream(path)
    assert_one_line_error(excinfo, path, "pickle")


def test_zip_member_that_is_not_an_array(tmp_path):
    path = save(tmp_path / "odd.npz", stream_arrays())
    with zipfile.ZipFile(path, "a") as archive:
        archive.writestr("readme.txt", "hello")
    with pytest.raises(FormatError) as excinfo:
        read_labelled_stream(path)
    assert_one_line_error(excinfo, path, "not a NumPy array")


def test_captures_file_read_as_a_stream_says_so(tmp_path):
    path = save(tmp_path / "c.npz", captures_arrays())
    with pytest.raises(FormatError, match="labelled-captures file"):
        read_labelled_stream(path)


def test_writers_refuse_invalid_data_and_leave_no_file(tmp_path):
    path = tmp_path / "out.npz"
    bad = LabelledStream(np.zeros((3, 2, 2)), np.array([0.0, 0.0, 1.0]), 100.0)
    with pytest.raises(FormatError, match="cannot write .*increasing"):
        write_labelled_stream(path, bad)
    clash = LabelledStream(np.zeros((3, 2, 2)), np.arange(3.0), 100.0, metadata={"t": np.ones(2)})
    with pytest.raises(FormatError, match="reserved"):
        write_labelled_stream(path, clash)
    odd = LabelledStream(np.zeros((3, 2, 2)), np.arange(3.0), 100.0, metadata={"x": object()})
    with pytest.raises(FormatError, match="JSON"):
        write_labelled_stream(path, odd)
    arrays = captures_arrays()
    captures = LabelledCaptures(
        frames=arrays["frames"],
        lengths=arrays["lengths"],
        labels=arrays["labels"] + 5,
        class_names=arrays["class_names"].tolist(),
        groups=arrays["groups"],
        sample_rate_hz=54.0,
    )
    with pytest.raises(FormatError, match="class_names"):
        write_labelled_captures(path, captures)
    assert not list(tmp_path.iterdir())
