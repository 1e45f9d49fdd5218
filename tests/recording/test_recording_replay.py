"""Tests for wovenskin.recording.replay: playing .npz streams and .wsrec recordings as a source."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import pytest

from wovenskin.recording.formats import LabelledStream, write_labelled_stream
from wovenskin.recording.replay import FAST_BATCH, ReplaySource
from wovenskin.recording.untrusted import FormatError
from wovenskin.recording.writer import RecordingWriter
from wovenskin.runtime.sources import open_source
from wovenskin.skin.frames import Frame, SkinInfo, SourceEvent
from wovenskin.skin.source import SkinSource

RATE = 200.0


def make_stream(path: Path, n_frames: int = 60, dtype=np.int16) -> Path:
    frames = np.arange(n_frames * 12, dtype=dtype).reshape(n_frames, 4, 3)
    stream = LabelledStream(
        frames=frames,
        t=np.arange(n_frames) / RATE,
        sample_rate_hz=RATE,
        event_start_s=np.array([0.05]),
        event_end_s=np.array([0.15]),
        event_labels=np.array(["swipe_left"]),
    )
    write_labelled_stream(path, stream)
    return path


def make_recording(path: Path) -> Path:
    """10 frames with a sequence gap (one dropped frame) and device times."""
    seq = np.array([0, 1, 2, 3, 5, 6, 7, 8, 9, 10])
    with RecordingWriter(path, SkinInfo(rows=2, cols=2, sample_rate_hz=100.0, device_id="d1")) as w:
        w.append_frames(
            seq, 1.0 + seq / 100.0, seq[:, None, None] * np.ones((1, 2, 2)), seq * 10_000
        )
        w.add_label("push", 1.02, 1.06)
        w.add_label("push", 1.0, 1.01, kind="prompt")
    return path


def drain(source: ReplaySource, max_polls: int = 10_000) -> list[Frame | SourceEvent]:
    """Poll until the end event (bounded, so a bug cannot hang the test)."""
    items: list[Frame | SourceEvent] = []
    for _ in range(max_polls):
        items.extend(source.poll(timeout=0.05))
        if any(isinstance(x, SourceEvent) and x.kind == "end" for x in items):
            return items
    raise AssertionError("replay never ended")


def frames_of(items) -> list[Frame]:
    return [x for x in items if isinstance(x, Frame)]


def test_fast_replay_of_a_stream_is_exact_and_in_order(tmp_path):
    path = make_stream(tmp_path / "s.npz", n_frames=FAST_BATCH + 44)
    source = ReplaySource.from_options(str(path), {"speed": "0"})
    assert isinstance(source, SkinSource)
    assert source.info.rows == 4 and source.info.cols == 3 and source.info.sample_rate_hz == RATE
    assert source.info.source == f"replay:{path}"
    assert source.events == [("swipe_left", 0.05, 0.15)]
    assert source.poll(timeout=0.01) == []  # not started yet
    source.start()
    first = source.poll()
    assert isinstance(first[0], SourceEvent) and first[0].kind == "connected"
    assert first[0].info == source.info
    assert len(frames_of(first)) == FAST_BATCH  # at most one batch per poll
    items = first + drain(source)
    frames = frames_of(items)
    assert [f.seq for f in frames] == list(range(FAST_BATCH + 44))
    np.testing.assert_array_equal([f.t for f in frames], np.arange(FAST_BATCH + 44) / RATE)
    expected = np.arange((FAST_BATCH + 44) * 12).reshape(-1, 4, 3).astype(np.float32)
    np.testing.assert_array_equal(np.stack([f.values for f in frames]), expected)
    assert all(f.values.dtype == np.float32 for f in frames)
    ends = [x for x in items if isinstance(x, SourceEvent) and x.kind == "end"]
    assert len(ends) == 1 and items[-1] is ends[0]
    assert source.poll(timeout=0.01) == [] and source.poll(timeout=0) == []  # end comes once
    assert source.stats().good_frames == FAST_BATCH + 44 and source.stats().dropped_frames == 0
    source.close()
    source.close()
    assert not source.stats().connected


def test_replay_of_a_native_recording(tmp_path):
    path = make_recording(tmp_path / "r.wsrec")
    source = open_source(f"replay:{path}?speed=0")
    assert isinstance(source, ReplaySource)
    assert source.info.device_id == "d1" and source.info.sample_rate_hz == 100.0
    assert source.events == [("push", 1.02, 1.06)]  # trial labels only
    source.start()
    frames = frames_of(drain(source))
    assert [f.seq for f in frames] == [0, 1, 2, 3, 5, 6, 7, 8, 9, 10]
    assert frames[4].t == pytest.approx(1.05)
    assert frames[4].device_t_us == 50_000
    assert frames[4].values.tolist() == [[5.0, 5.0], [5.0, 5.0]]
    assert source.stats().dropped_frames == 1


def test_looping_keeps_the_stream_clock_increasing(tmp_path):
    path = make_stream(tmp_path / "s.npz", n_frames=30)
    source = ReplaySource(path, speed=0, loop=True)
    source.start()
    frames: list[Frame] = []
    for _ in range(100):
        items = source.poll()
        assert not any(isinstance(x, SourceEvent) and x.kind == "end" for x in items)
        frames.extend(frames_of(items))
        if len(frames) >= 75:
            break
    frames = frames[:75]
    t = np.array([f.t for f in frames])
    np.testing.assert_allclose(t, np.arange(75) / RATE, atol=1e-9)
    assert [f.seq for f in frames] == list(range(75))
    np.testing.assert_array_equal(frames[30].values, frames[0].values)
    np.testing.assert_array_equal(frames[61].values, frames[1].values)


def test_start_s_skips_to_file_time(tmp_path):
    path = make_stream(tmp_path / "s.npz", n_frames=60)
    source = ReplaySource.from_options(str(path), {"speed": "0", "start_s": "0.1"})
    source.start()
    frames = frames_of(drain(source))
    assert frames[0].t == pytest.approx(0.1) and len(frames) == 40
    with pytest.raises(ValueError, match="past the end"):
        ReplaySource(path, start_s=5.0)


def test_real_time_pacing(tmp_path):
    path = make_stream(tmp_path / "s.npz", n_frames=41)  # 0.2 s of stream
    for speed, lasts_at_least in ((1.0, 0.2), (2.0, 0.1)):
        source = ReplaySource(path, speed=speed)
        started = time.monotonic()
        source.start()
        items = drain(source)
        took = time.monotonic() - started
        assert len(frames_of(items)) == 41
        assert took >= lasts_at_least * 0.99  # frames are never early; no upper bound asserted
        assert source.poll(timeout=0.01) == []


def test_real_time_poll_returns_early_and_in_pieces(tmp_path):
    path = make_stream(tmp_path / "s.npz", n_frames=2000)  # 10 s of stream
    source = ReplaySource(path, speed=1)
    source.start()
    source.start()  # idempotent
    first = source.poll()
    assert [x.kind for x in first if isinstance(x, SourceEvent)] == ["connected"]
    got = frames_of(source.poll(timeout=5.0))
    assert 1 <= len(got) < 2000  # returned as soon as something was due, not the whole file
    source.close()
    assert source.poll(timeout=0.01) == []


def test_commands_are_accepted_but_checked(tmp_path):
    source = ReplaySource(make_stream(tmp_path / "s.npz"))
    for command in ("start", "stop", "recalibrate"):
        source.send_command(command)
    with pytest.raises(ValueError, match="unknown command"):
        source.send_command("explode")


@pytest.mark.parametrize(
    ("options", "words"),
    [
        ({"speed": "fast"}, "speed: Input should be a valid number"),
        ({"speed": "-1"}, ">= 0"),
        ({"loop": "maybe"}, "loop: Input should be a valid boolean"),
        ({"start_s": "nan"}, "finite"),
        ({"sped": "2"}, "replay options: unknown setting 'sped'"),
    ],
)
def test_bad_options(tmp_path, options, words):
    path = make_stream(tmp_path / "s.npz")
    with pytest.raises(ValueError, match=words):
        ReplaySource.from_options(str(path), options)


def write_bad(tmp_path: Path, kind: str) -> Path:
    if kind == "missing":
        return tmp_path / "missing.npz"
    if kind == "text":
        path = tmp_path / "notes.wsrec"
        path.write_text("not a recording\n")
        return path
    if kind == "captures":
        path = tmp_path / "caps.npz"
        with open(path, "wb") as f:
            np.savez(
                f,
                frames=np.zeros((2, 3, 2, 2)),
                lengths=np.array([3, 3]),
                labels=np.array([0, 0]),
                class_names=np.array(["a"]),
                groups=np.array(["p", "q"]),
                sample_rate_hz=np.float64(10),
            )
        return path
    if kind == "nan":
        path = tmp_path / "nan.npz"
        with open(path, "wb") as f:
            np.savez(
                f,
                frames=np.full((3, 2, 2), np.nan),
                t=np.arange(3.0),
                sample_rate_hz=np.float64(10),
            )
        return path
    if kind == "empty recording":
        path = tmp_path / "empty.wsrec"
        RecordingWriter(path, SkinInfo()).close()
        return path
    if kind == "cut header":
        path = tmp_path / "cut.wsrec"
        RecordingWriter(path, SkinInfo()).close()
        path.write_bytes(path.read_bytes()[:40])
        return path
    raise AssertionError(kind)


@pytest.mark.parametrize(
    ("kind", "words"),
    [
        ("missing", "no such file"),
        ("text", "not a wovenskin data file"),  # the same words as every other command
        ("captures", "labelled captures"),
        ("nan", "NaN"),
        ("empty recording", "no frames"),
        ("cut header", "cut off inside its header"),
    ],
)
def test_bad_files_fail_when_the_source_is_created(tmp_path, kind, words):
    path = write_bad(tmp_path, kind)
    with pytest.raises(FormatError, match=words) as excinfo:
        ReplaySource.from_options(str(path), {})
    assert str(path) in str(excinfo.value) and "\n" not in str(excinfo.value)


def test_crashed_recording_replays_what_survived(tmp_path):
    path = make_recording(tmp_path / "r.wsrec")
    path.write_bytes(path.read_bytes()[:-10])  # footer lost
    source = ReplaySource(path, speed=0)
    source.start()
    items = drain(source)
    assert items[0].kind == "connected" and "cut off" in items[0].message
    assert len(frames_of(items)) == 10
