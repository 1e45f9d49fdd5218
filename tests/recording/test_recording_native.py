"""Tests for wovenskin.recording.native: the crash-safe .wsrec recording format."""

from __future__ import annotations

import os
import signal
import struct
import subprocess
import sys
import threading
import time
import zlib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from paths import REPO

from wovenskin.recording import native
from wovenskin.recording.documents import decode_document, encode_document
from wovenskin.recording.formats import LabelledStream, read_labelled_stream, write_labelled_stream
from wovenskin.recording.native import (
    Recording,
    read_recording,
    recording_from_labelled_stream,
    write_recording,
)
from wovenskin.recording.records import MAGIC, SYNC, RecordType
from wovenskin.recording.untrusted import FormatError
from wovenskin.recording.writer import RecordingWriter
from wovenskin.skin.frames import Frame, SkinInfo

REPO = REPO
INFO = SkinInfo(rows=3, cols=2, sample_rate_hz=200.0, device_id="skin-7", source="test")


def frame_values(seq: int, rows: int = 3, cols: int = 2) -> np.ndarray:
    return (seq * 10 + np.arange(rows * cols, dtype=np.float32)).reshape(rows, cols)


def write_small(path: Path, n_frames: int = 5) -> Path:
    """A small complete recording: each append of 2 frames spans 0.3 s >= the 0.25 s flush
    interval, so it becomes one FRAMES record at once."""
    with RecordingWriter(path, INFO, {"participant": "p1"}, {"alpha": 0.5}) as writer:
        writer.add_calibration({"baseline": np.ones((3, 2)), "noise": np.full((3, 2), 0.1)})
        for i in range(n_frames):
            writer.append_frames(
                [2 * i, 2 * i + 1],
                [0.6 * i, 0.6 * i + 0.3],
                np.stack([frame_values(2 * i), frame_values(2 * i + 1)]),
            )
            if i == 2:
                writer.add_label("swipe_up", 0.3, 0.9, attempt=1)
                writer.add_annotation("command", 0.9, {"gesture": "swipe_up"})
    return path


def parse_records(data: bytes) -> list[tuple[int, int, int]]:
    """Independent parser of the documented layout: (offset, type, payload length) per record."""
    assert data.startswith(MAGIC)
    pos, records = len(MAGIC), []
    while pos < len(data):
        sync, rtype, length = struct.unpack_from("<4sBI", data, pos)
        assert sync == SYNC
        payload = data[pos + 9 : pos + 9 + length]
        (crc,) = struct.unpack_from("<I", data, pos + 9 + length)
        assert crc == zlib.crc32(data[pos + 4 : pos + 9] + payload)
        records.append((pos, rtype, length))
        pos += 9 + length + 4
    return records


# ----------------------------------------------------------------------------- round trip


def test_everything_written_reads_back(tmp_path):
    path = write_small(tmp_path / "r.wsrec")
    rec = read_recording(path)
    assert rec.clean_close and rec.warnings == []
    assert rec.info == INFO
    assert rec.provenance["participant"] == "p1"
    for key in ("host", "user", "wovenskin_version", "started_utc", "command_line"):
        assert key in rec.provenance
    assert rec.settings == {"alpha": 0.5}
    np.testing.assert_array_equal(rec.seq, np.arange(10))
    np.testing.assert_allclose(rec.t, np.arange(10) * 0.3)
    np.testing.assert_array_equal(rec.frames, np.stack([frame_values(i) for i in range(10)]))
    assert rec.frames.dtype == np.float32 and rec.frames.shape == (10, 3, 2)
    np.testing.assert_array_equal(rec.device_t_us, -np.ones(10))
    assert len(rec.calibrations) == 1
    np.testing.assert_array_equal(rec.calibrations[0]["noise"], np.full((3, 2), 0.1))
    assert [(x.label, x.start_s, x.end_s, x.kind, x.extra) for x in rec.labels] == [
        ("swipe_up", 0.3, 0.9, "trial", {"attempt": 1})
    ]
    assert rec.annotations_of("command")[0].payload == {"gesture": "swipe_up"}
    assert rec.footer["frames"] == 10 and rec.footer["labels"] == 1


def test_file_follows_the_documented_layout(tmp_path):
    data = write_small(tmp_path / "r.wsrec").read_bytes()
    types = [rtype for _, rtype, _ in parse_records(data)]
    assert types[0] == RecordType.HEADER and types[-1] == RecordType.FOOTER
    assert types.count(RecordType.FRAMES) == 5
    header = decode_document(data[len(MAGIC) + 9 : len(MAGIC) + 9 + parse_records(data)[0][2]])
    assert header["format"] == "wovenskin.wsrec" and header["format_version"] == 1


def test_append_frame_and_device_time(tmp_path):
    path = tmp_path / "r.wsrec"
    with RecordingWriter(path, INFO) as writer:
        writer.append_frame(Frame(seq=4, t=1.0, values=frame_values(4), device_t_us=123))
        writer.append_frame(Frame(seq=5, t=1.005, values=frame_values(5)))
    rec = read_recording(path)
    assert rec.device_t_us.tolist() == [123, -1] and rec.seq.tolist() == [4, 5]


def test_writer_rejects_misuse(tmp_path):
    path = tmp_path / "r.wsrec"
    writer = RecordingWriter(path, INFO)
    with pytest.raises(ValueError, match=r"\(3, 2\)"):
        writer.append_frames(0, 0.0, np.zeros((2, 3)))
    with pytest.raises(ValueError, match="2 entries"):
        writer.append_frames([0], [0.0, 1.0], np.zeros((2, 3, 2)))
    with pytest.raises(ValueError, match="before it starts"):
        writer.add_label("push", 2.0, 1.0)
    with pytest.raises(TypeError, match="object"):
        writer.add_annotation("x", 0.0, {"bad": object()})
    writer.close()
    writer.close()  # twice is fine
    with pytest.raises(ValueError, match="closed"):
        writer.append_frames(0, 0.0, np.zeros((3, 2)))
    assert read_recording(path).clean_close


def test_refuses_to_overwrite(tmp_path):
    path = write_small(tmp_path / "r.wsrec")
    with pytest.raises(FileExistsError, match="overwrite=True"):
        RecordingWriter(path, INFO)
    assert read_recording(path).seq.size == 10
    with RecordingWriter(path, INFO, overwrite=True) as writer:
        writer.append_frames(0, 0.0, frame_values(0))
    assert read_recording(path).seq.size == 1


def test_exception_in_with_block_is_noted_in_the_footer(tmp_path):
    path = tmp_path / "r.wsrec"
    with pytest.raises(RuntimeError), RecordingWriter(path, INFO) as writer:
        writer.append_frames(0, 0.0, frame_values(0))
        raise RuntimeError("sensor unplugged")
    rec = read_recording(path)
    assert rec.clean_close and rec.seq.size == 1
    assert rec.footer["error"] == "RuntimeError: sensor unplugged"


@settings(max_examples=30, deadline=None)
@given(
    st.recursive(
        st.none()
        | st.booleans()
        | st.integers(-(2**40), 2**40)
        | st.text(max_size=8)
        | st.floats(allow_nan=False),
        lambda inner: (
            st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=5), inner, max_size=3)
        ),
        max_leaves=12,
    ),
    st.sampled_from(["<f4", ">f8", "<i2", "|u1", "|b1"]),
    st.lists(st.integers(0, 3), max_size=3),
)
def test_documents_round_trip(value, dtype, shape):
    array = np.arange(int(np.prod(shape)), dtype=np.int64).reshape(shape).astype(dtype)
    document = {"value": value, "nested": [{"array": array}]}
    back = decode_document(encode_document(document))
    assert back["value"] == value
    np.testing.assert_array_equal(back["nested"][0]["array"], array)
    assert back["nested"][0]["array"].dtype == array.dtype.newbyteorder("=")


# ----------------------------------------------------------------------------- damage


def test_truncation_at_every_byte_never_raises(tmp_path):
    data = write_small(tmp_path / "full.wsrec").read_bytes()
    records = parse_records(data)
    header_end = records[1][0]
    full = read_recording(tmp_path / "full.wsrec")
    cut_path = tmp_path / "cut.wsrec"
    previous = 0
    for cut in range(len(data) + 1):
        cut_path.write_bytes(data[:cut])
        if cut < header_end:
            # an empty file is named as such by every reader (recording/files.py)
            words = "empty file" if cut == 0 else "cut off inside its header"
            with pytest.raises(FormatError, match=words):
                read_recording(cut_path)
            continue
        rec = read_recording(cut_path)
        n = rec.seq.size
        assert previous <= n  # never fewer frames from a longer prefix
        previous = n
        np.testing.assert_array_equal(rec.frames, full.frames[:n])
        assert rec.clean_close == (cut == len(data))
        assert (rec.warnings == []) == (cut == len(data))
        assert all("\n" not in warning for warning in rec.warnings)
        complete = [r for r in records if r[0] + 9 + r[2] + 4 <= cut]
        assert n == 2 * sum(r[1] == RecordType.FRAMES for r in complete)
    assert previous == 10


def test_corrupt_record_in_the_middle_is_skipped(tmp_path):
    path = write_small(tmp_path / "r.wsrec")
    data = bytearray(path.read_bytes())
    frame_records = [r for r in parse_records(bytes(data)) if r[1] == RecordType.FRAMES]
    offset = frame_records[1][0]
    data[offset + 20] ^= 0xFF
    path.write_bytes(bytes(data))
    rec = read_recording(path)
    assert rec.seq.tolist() == [0, 1, 4, 5, 6, 7, 8, 9]
    assert rec.clean_close and len(rec.labels) == 1
    assert len(rec.warnings) == 1 and f"at byte {offset}" in rec.warnings[0]


def test_corrupt_length_field_is_skipped_by_resyncing(tmp_path):
    path = write_small(tmp_path / "r.wsrec")
    data = bytearray(path.read_bytes())
    offset = [r for r in parse_records(bytes(data)) if r[1] == RecordType.FRAMES][0][0]
    data[offset + 5 : offset + 9] = struct.pack("<I", 0xFFFFFF)
    path.write_bytes(bytes(data))
    rec = read_recording(path)
    assert rec.seq.tolist() == list(range(2, 10)) and rec.clean_close


@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(st.data())
def test_random_damage_after_the_header_never_raises(tmp_path, data):
    source = tmp_path / "src.wsrec"
    if not source.exists():
        write_small(source)
    raw = bytearray(source.read_bytes())
    header_end = parse_records(bytes(raw))[1][0]
    for _ in range(data.draw(st.integers(1, 6))):
        pos = data.draw(st.integers(header_end, len(raw) - 1))
        raw[pos] = data.draw(st.integers(0, 255))
    cut = data.draw(st.integers(header_end, len(raw)))
    damaged = tmp_path / "damaged.wsrec"
    damaged.write_bytes(bytes(raw[:cut]))
    rec = read_recording(damaged)
    assert set(rec.seq.tolist()) <= set(range(10))
    assert rec.frames.shape == (rec.seq.size, 3, 2)


def test_unknown_record_types_are_skipped_with_a_warning(tmp_path):
    path = write_small(tmp_path / "r.wsrec")
    data = path.read_bytes()
    footer_at = parse_records(data)[-1][0]
    payload = b"from the future"
    head = struct.pack("<4sBI", SYNC, 99, len(payload))
    record = head + payload + struct.pack("<I", zlib.crc32(head[4:] + payload))
    path.write_bytes(data[:footer_at] + record + data[footer_at:])
    rec = read_recording(path)
    assert rec.clean_close and rec.seq.size == 10
    assert len(rec.warnings) == 1 and "unknown type" in rec.warnings[0]


@pytest.mark.parametrize(
    ("content", "words"),
    [
        # what a file is, is decided in one place (formats.identify) for every reader:
        (b"", "empty file"),
        (MAGIC[:7], "cut off inside its header"),
        (b"PK\x03\x04 a zip file, not a recording", "damaged .npz"),
        (b"random bytes, not a recording", "not a wovenskin data file"),
        (b"wovenskin.wsrec 7\n", "version 7 is newer"),
        (b"wovenskin.wsrec x\n", "bad version line"),
        (MAGIC + b"\x00" * 40, "not a valid HEADER"),
    ],
)
def test_not_a_recording(tmp_path, content, words):
    path = tmp_path / "x.wsrec"
    path.write_bytes(content)
    with pytest.raises(FormatError, match=words) as excinfo:
        read_recording(path)
    assert str(path) in str(excinfo.value) and "\n" not in str(excinfo.value)


def test_missing_recording(tmp_path):
    with pytest.raises(FormatError, match="no such file"):
        read_recording(tmp_path / "nope.wsrec")


# ----------------------------------------------------------------------------- durability


def test_frames_reach_the_file_every_quarter_second_of_stream_time(tmp_path):
    path = tmp_path / "r.wsrec"
    writer = RecordingWriter(path, INFO, flush_interval_s=0.25)
    for i in range(7):  # t = 0 .. 0.30 s, appended at once
        writer.append_frames(i, 0.05 * i, frame_values(i))
    assert read_recording(path).seq.size >= 6  # all frames up to t = 0.25 s are on disk
    writer.close()
    assert read_recording(path).seq.size == 7


def test_frames_reach_the_file_after_a_quarter_second_of_wall_time(tmp_path):
    path = tmp_path / "r.wsrec"
    writer = RecordingWriter(path, INFO, flush_interval_s=0.05)
    writer.append_frames(0, 0.0, frame_values(0))
    time.sleep(0.1)
    writer.append_frames(1, 0.001, frame_values(1))
    assert read_recording(path).seq.tolist() == [0, 1]
    writer.close()


def test_writer_fsyncs_on_a_wall_clock_schedule(tmp_path, monkeypatch):
    synced: list[int] = []
    real_fsync = os.fsync
    monkeypatch.setattr(native.os, "fsync", lambda fd: (synced.append(fd), real_fsync(fd)))
    writer = RecordingWriter(
        tmp_path / "r.wsrec", INFO, flush_interval_s=0.01, fsync_interval_s=0.05
    )
    at_creation = len(synced)
    assert at_creation >= 1  # the header is durable at once
    writer.append_frames(0, 0.0, frame_values(0))
    time.sleep(0.1)
    writer.append_frames(1, 0.001, frame_values(1))
    assert len(synced) > at_creation
    writer.close()


def test_concurrent_writers_of_one_recording(tmp_path):
    path = tmp_path / "r.wsrec"
    with RecordingWriter(path, INFO, flush_interval_s=0.001) as writer:

        def annotate(name: str) -> None:
            for i in range(200):
                writer.add_annotation(name, i * 0.005, {"i": i})

        threads = [threading.Thread(target=annotate, args=(f"s{k}",)) for k in range(3)]
        for thread in threads:
            thread.start()
        for i in range(300):
            writer.append_frames(i, i * 0.005, frame_values(i))
        for thread in threads:
            thread.join()
    rec = read_recording(path)
    assert rec.warnings == [] and rec.seq.tolist() == list(range(300))
    assert [len(rec.annotations_of(f"s{k}")) for k in range(3)] == [200, 200, 200]


CHILD = """
import sys, time
import numpy as np
from wovenskin.recording.native import RecordingWriter
from wovenskin.skin.frames import SkinInfo

writer = RecordingWriter(sys.argv[1], SkinInfo(rows=4, cols=5), {"participant": "crash-test"})
start = time.monotonic()
i = 0
while True:
    delay = start + i / 200 - time.monotonic()
    if delay > 0:
        time.sleep(delay)
    writer.append_frames(i, i / 200, np.full((4, 5), i, np.float32))
    sys.stdout.write(f"{i}\\n")
    sys.stdout.flush()
    i += 1
"""


@pytest.mark.skipif(not hasattr(signal, "SIGKILL"), reason="needs POSIX kill -9")
def test_kill_9_loses_at_most_the_last_quarter_second(tmp_path):
    path = tmp_path / "crash.wsrec"
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    child = subprocess.Popen(
        [sys.executable, "-c", CHILD, str(path)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        cwd=REPO,
    )
    guard = threading.Timer(60, child.kill)  # only against hangs
    guard.start()
    try:
        last_reported = -1
        for line in child.stdout:
            last_reported = int(line)
            if last_reported >= 300:  # 1.5 s at 200 Hz
                break
        child.send_signal(signal.SIGKILL)
        for line in child.stdout:  # what it reported before it died
            last_reported = int(line)
        child.wait()
    finally:
        guard.cancel()
    assert child.returncode == -signal.SIGKILL, child.stderr.read()
    appended = last_reported + 1
    assert appended >= 301
    rec = read_recording(path)
    n = rec.seq.size
    assert not rec.clean_close and rec.warnings
    assert appended - 200 <= n <= appended + 1  # the contract: at most the last second lost
    assert appended - 51 <= n  # the design: at most 0.25 s of stream time is buffered
    np.testing.assert_array_equal(rec.seq, np.arange(n))
    np.testing.assert_array_equal(rec.frames[:, 3, 4], np.arange(n, dtype=np.float32))
    np.testing.assert_allclose(rec.t, np.arange(n) / 200)
    assert rec.provenance["participant"] == "crash-test"


# ----------------------------------------------------------------------------- export/import


def test_export_to_a_labelled_stream_and_back(tmp_path):
    rec = read_recording(write_small(tmp_path / "r.wsrec"))
    rec.labels.append(native.RecordedLabel("push", 1.0, 1.2, kind="prompt"))
    stream = rec.to_labelled_stream()
    assert stream.event_labels.tolist() == ["swipe_up"]  # prompts are not events
    write_labelled_stream(tmp_path / "s.npz", stream)
    loaded = read_labelled_stream(tmp_path / "s.npz")
    assert loaded.metadata["info"]["device_id"] == "skin-7"
    assert loaded.metadata["provenance"]["participant"] == "p1"

    imported = recording_from_labelled_stream(loaded)
    assert isinstance(imported, Recording)
    assert imported.info == INFO
    write_recording(tmp_path / "again.wsrec", imported)
    again = read_recording(tmp_path / "again.wsrec")
    np.testing.assert_array_equal(again.frames, rec.frames)
    np.testing.assert_array_equal(again.t, rec.t)
    assert [(x.label, x.start_s, x.end_s) for x in again.labels] == [("swipe_up", 0.3, 0.9)]
    assert again.settings == {"alpha": 0.5}
    assert again.provenance["participant"] == "p1"


def test_import_of_a_plain_stream_with_integer_frames(tmp_path):
    frames = np.arange(3000 * 4, dtype=np.uint16).reshape(3000, 2, 2)
    stream = LabelledStream(
        frames, np.arange(3000) / 100.0, 100.0, np.array([1.0]), np.array([2.0]), np.array(["push"])
    )
    rec = recording_from_labelled_stream(stream)
    assert rec.info.rows == 2 and rec.info.sample_rate_hz == 100.0
    write_recording(tmp_path / "i.wsrec", rec)
    back = read_recording(tmp_path / "i.wsrec")
    np.testing.assert_array_equal(back.frames, frames.astype(np.float32))
    assert back.labels[0].label == "push" and back.clean_close


def test_tick_makes_buffered_frames_durable_while_the_stream_is_silent(tmp_path):
    import time as _time

    path = tmp_path / "quiet.wsrec"
    writer = RecordingWriter(path, SkinInfo(rows=2, cols=2), flush_interval_s=1.0)
    writer.append_frames(np.arange(3), np.arange(3) / 200.0, np.ones((3, 2, 2), np.float32))
    assert len(read_recording(path).frames) == 0  # still buffered: the flush is not due yet
    _time.sleep(1.05)
    writer.tick()  # no new data, but the flush is due
    assert len(read_recording(path).frames) == 3
    writer.close()
