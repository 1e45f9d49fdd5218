"""Tests for wovenskin.recording.bag: recordings as ROS 2 bags (.mcap), losslessly."""

from __future__ import annotations

import json
import sys
from datetime import datetime
from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag2 import Reader, StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore
from typer.testing import CliRunner

from wovenskin.cli import app
from wovenskin.errors import MissingExtraError
from wovenskin.recording import bag
from wovenskin.recording.bag import (
    ANNOTATIONS_TOPIC,
    CALIBRATIONS_TOPIC,
    FRAMES_TOPIC,
    HEADER_TOPIC,
    LABELS_TOPIC,
    TIMES_TOPIC,
    TOPIC_TYPES,
    read_bag,
    write_bag,
)
from wovenskin.recording.bag_documents import dumps_document, loads_document
from wovenskin.recording.formats import read_labelled_stream
from wovenskin.recording.native import (
    Annotation,
    RecordedLabel,
    Recording,
    read_recording,
    write_recording,
)
from wovenskin.recording.untrusted import FormatError
from wovenskin.recording.writer import RecordingWriter
from wovenskin.skin.frames import SkinInfo

INFO = SkinInfo(rows=3, cols=2, sample_rate_hz=199.7, device_id="skin-7", source="test")
STARTED = "2026-01-31T14:02:11.250+00:00"
TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
cli = CliRunner()


def odd_frames(n: int, rows: int = 3, cols: int = 2) -> np.ndarray:
    """Frames with NaNs of unusual bit patterns, infinities, -0.0 and subnormals."""
    frames = np.random.default_rng(7).normal(size=(n, rows, cols)).astype(np.float32)
    if n < 5:
        return frames
    bits = frames.view(np.uint32)
    bits[0, 0, 0] = 0x7FC0_0001  # a quiet NaN with a payload
    bits[1, 0, 1] = 0xFFA0_0002  # a negative signalling-NaN pattern
    frames[2, 1, 0], frames[3, 2, 1], frames[4, 0, 0] = np.inf, -0.0, 1e-45
    return frames


def recording(n: int = 40, t0: float = 1234.000123456789, **changes) -> Recording:
    """An in-memory recording with times that are not whole nanoseconds."""
    fields = dict(
        info=INFO,
        provenance={"participant": "p07", "started_utc": STARTED, "notes": "ü ✓"},
        settings={"conditioning": {"alpha": 0.25, "window": [1, 2]}},
        frames=odd_frames(n),
        seq=np.arange(n, dtype=np.int64) + 2**40,
        t=t0 + np.arange(n) / 199.7,
        device_t_us=np.where(np.arange(n) % 3, np.arange(n) * 5007 - 2**52, -1).astype(np.int64),
        calibrations=[
            {"baseline": np.full((3, 2), 1.5, np.float32), "noise": np.array([np.nan, np.inf])},
            {"settings": {"k": 3}, "mask": np.eye(2, dtype=bool), "big": np.arange(3, dtype=">f8")},
        ],
        labels=[
            RecordedLabel("swipe_up", t0 + 0.05, t0 + 0.1, extra={"attempt": 1}),
            RecordedLabel("push", t0 + 0.01, t0 + 0.02, kind="prompt"),
            RecordedLabel("push", t0 + 0.01, t0 + 0.02, extra={"x": float("nan")}),
        ],
        annotations=[
            Annotation("prediction", t0 + 0.07, {"p": np.linspace(0, 1, 15, dtype=np.float32)}),
            Annotation("command", t0 - 5.0, {"gesture": "push", "v": [1, None, True]}),
            Annotation("stop", t0 + 0.07, "plain text"),
        ],
        clean_close=True,
        footer={"frames": n, "ended_utc": "2026-01-31T14:03:00.000+00:00"},
    )
    return Recording(**{**fields, **changes})


def assert_same(a: Recording, b: Recording, footer: bool = True) -> None:
    """Everything equal; frames, times and arrays bit for bit."""
    assert a.info == b.info and a.provenance == b.provenance and a.settings == b.settings
    assert a.frames.dtype == b.frames.dtype == np.float32
    np.testing.assert_array_equal(a.frames.view(np.uint32), b.frames.view(np.uint32))
    for name in ("seq", "t", "device_t_us"):
        x, y = getattr(a, name), getattr(b, name)
        assert x.dtype == y.dtype and np.array_equal(x.view(np.uint64), y.view(np.uint64)), name
    assert canonical(a.calibrations) == canonical(b.calibrations)
    assert canonical([vars(x) for x in a.labels]) == canonical([vars(x) for x in b.labels])
    assert canonical([vars(x) for x in a.annotations]) == canonical(
        [vars(x) for x in b.annotations]
    )
    if footer:
        assert a.footer == b.footer and a.clean_close == b.clean_close


def canonical(value):
    """A comparable form: arrays as (dtype, shape, bytes), NaN as a string."""
    if isinstance(value, np.ndarray):
        return ("array", value.dtype.str, value.shape, value.tobytes())
    if isinstance(value, dict):
        return {k: canonical(v) for k, v in value.items()}
    if isinstance(value, list):
        return [canonical(v) for v in value]
    if isinstance(value, float) and value != value:
        return "NaN"
    return (type(value).__name__, value)


def messages(path: Path) -> list[tuple[str, str, int, object]]:
    """(topic, type, bag time, message) of every message, each decoded as its type."""
    with Reader(path) as reader:
        return [
            (c.topic, c.msgtype, ns, TYPESTORE.deserialize_cdr(data, c.msgtype))
            for c, ns, data in reader.messages()
        ]


# ----------------------------------------------------------------------------- round trips


def test_wsrec_to_mcap_to_wsrec_is_lossless(tmp_path):
    original = recording()
    src = tmp_path / "a.wsrec"
    write_recording(src, original)
    stored = read_recording(src)
    write_bag(tmp_path / "a.mcap", stored)
    write_recording(tmp_path / "b.wsrec", read_bag(tmp_path / "a.mcap"))
    back = read_recording(tmp_path / "b.wsrec")
    assert_same(stored, back, footer=False)  # a written .wsrec gets its own FOOTER
    np.testing.assert_array_equal(original.frames.view(np.uint32), back.frames.view(np.uint32))
    assert np.array_equal(original.t, back.t) and np.array_equal(original.seq, back.seq)
    assert back.clean_close and back.warnings == []


def test_recording_to_bag_and_back_keeps_everything(tmp_path):
    original = recording(warnings=["a skipped record at byte 99"], clean_close=False)
    write_bag(tmp_path / "r.mcap", original)
    back = read_bag(tmp_path / "r.mcap")
    assert_same(original, back)
    assert back.warnings == original.warnings and back.format_version == 1


def test_bag_times_are_real_dates_and_frame_times_are_exact(tmp_path):
    rec = recording(n=25, t0=0.000123456789)
    write_bag(tmp_path / "r.mcap", rec)
    started = datetime.fromisoformat(STARTED)
    offset = round(started.timestamp() * 1000) * 10**6  # a whole number of milliseconds
    assert offset == 1_769_868_131_250_000_000
    expected = [offset + round(t * 1e9) for t in rec.t]
    found = messages(tmp_path / "r.mcap")
    images = [(ns, m) for topic, _, ns, m in found if topic == FRAMES_TOPIC]
    times = [m.data for topic, _, ns, m in found if topic == TIMES_TOPIC]
    assert [ns for ns, _ in images] == expected
    assert [m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for _, m in images] == expected
    assert np.array_equal(np.array(times)[:, 1], rec.t)  # bit-exact, not from stamps
    header = json.loads(next(m.data for topic, _, _, m in found if topic == HEADER_TOPIC))
    assert header["clock_offset_ns"] == offset
    labels = [(ns, json.loads(m.data)) for topic, _, ns, m in found if topic == LABELS_TOPIC]
    assert {ns for ns, item in labels} == {offset + round(x.start_s * 1e9) for x in rec.labels}


def test_every_message_decodes_as_its_declared_standard_type(tmp_path):
    rec = recording(n=12)
    write_bag(tmp_path / "r.mcap", rec)
    found = messages(tmp_path / "r.mcap")
    counts = {topic: 0 for topic in TOPIC_TYPES}
    for topic, msgtype, _, message in found:
        assert msgtype == TOPIC_TYPES[topic]
        assert type(message).__msgtype__ == msgtype
        counts[topic] += 1
    assert counts == {
        HEADER_TOPIC: 1, FRAMES_TOPIC: 12, TIMES_TOPIC: 12,
        CALIBRATIONS_TOPIC: 2, LABELS_TOPIC: 3, ANNOTATIONS_TOPIC: 3,
    }  # fmt: skip
    image = next(m for topic, _, _, m in found if topic == FRAMES_TOPIC)
    assert (image.height, image.width, image.step, image.encoding) == (3, 2, 8, "32FC1")
    assert image.is_bigendian == 0 and image.header.frame_id == "skin"
    np.testing.assert_array_equal(image.data.view("<u4"), rec.frames[0].view(np.uint32).ravel())
    row = next(m for topic, _, _, m in found if topic == TIMES_TOPIC)
    assert row.data.tolist() == [2**40, rec.t[0], -1]
    raw = (tmp_path / "r.mcap").read_bytes()  # rosbag2 metadata for `ros2 bag info`
    for line in (b"format: wovenskin.bag", b"rows: '3'", b"cols: '2'", b"sample_rate_hz: '199.7'"):
        assert line in raw


def test_frames_out_of_time_order_keep_their_order(tmp_path):
    rec = recording(n=30)
    order = np.random.default_rng(3).permutation(30)
    rec.t, rec.seq = rec.t[order], rec.seq[order]
    write_bag(tmp_path / "r.mcap", rec)
    assert_same(rec, read_bag(tmp_path / "r.mcap"))


def test_empty_recording_and_one_without_a_start_time(tmp_path):
    empty = recording(n=0, calibrations=[], labels=[], annotations=[], provenance={})
    write_bag(tmp_path / "e.mcap", empty)
    assert_same(empty, read_bag(tmp_path / "e.mcap"))
    early = recording(n=5, t0=-3.5, provenance={"started_utc": "yesterday"})
    write_bag(tmp_path / "n.mcap", early)  # negative times, no start date: shifted to >= 0
    assert_same(early, read_bag(tmp_path / "n.mcap"))
    assert min(ns for _, _, ns, _ in messages(tmp_path / "n.mcap")) >= 0


def test_a_rosbag2_directory_is_read_too(tmp_path):
    write_bag(tmp_path / "r.mcap", recording(n=6))
    directory = tmp_path / "bagdir"
    with Reader(tmp_path / "r.mcap") as reader, Writer(directory, version=9) as writer:
        conns = {
            c.id: writer.add_connection(c.topic, c.msgtype, typestore=TYPESTORE)
            for c in reader.connections
        }
        for c, ns, data in reader.messages():
            writer.write(conns[c.id], ns, data)
    assert (directory / "metadata.yaml").is_file()  # a sqlite3 rosbag2 directory
    assert_same(recording(n=6), read_bag(directory))


INT8 = np.ones(1, np.int8)


@pytest.mark.parametrize(
    "value, expected",
    [
        (np.arange(6, dtype="<i8").reshape(2, 3), None),
        (np.array([1.5, np.nan], dtype=">f8"), None),
        (np.zeros((0, 4), np.uint16), None),
        (np.array(True), None),
        (
            [np.float32(2.5), float("inf"), -0.0, {"b": INT8}],
            [2.5, float("inf"), -0.0, {"b": INT8}],
        ),
    ],
)
def test_documents_keep_arrays_exactly(value, expected):
    back = loads_document(dumps_document(value), "doc")
    assert canonical(back) == canonical(value if expected is None else expected)


# ----------------------------------------------------------------------------- refusals


def test_refuses_to_overwrite_and_leaves_nothing_behind_on_error(tmp_path):
    out = tmp_path / "r.mcap"
    out.write_bytes(b"precious")
    with pytest.raises(FileExistsError, match="overwrite=True"):
        write_bag(out, recording(n=3))
    assert out.read_bytes() == b"precious"
    write_bag(out, recording(n=3), overwrite=True)
    assert len(read_bag(out).t) == 3
    bad = tmp_path / "bad.mcap"
    for rec, words in (
        (recording(n=3, seq=np.array([0, 1, 2**53 + 1])), "beyond 2\\*\\*53"),
        (recording(n=3, t=np.array([0.0, np.nan, 1.0])), "must be finite"),
        (recording(n=3, annotations=[Annotation("x", 0.0, {1, 2})]), "type set"),
        (recording(n=3, labels=[RecordedLabel("x", 0, 1, extra={"kind": "y"})]), "reserved"),
        (recording(n=3, frames=np.zeros((3, 2, 2), np.float32)), "must be float32"),
    ):
        with pytest.raises(FormatError, match=words):
            write_bag(bad, rec)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.mcap"]  # no partial, no temp dir


def test_without_rosbags_one_line_says_what_to_install(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "rosbags.rosbag2", None)
    with pytest.raises(MissingExtraError, match=r"install wovenskin\[ros2\]"):
        write_bag(tmp_path / "r.mcap", recording(n=2))
    assert not (tmp_path / "r.mcap").exists()


def craft(path: Path, header: dict | None, images=(), times=(), strings=None) -> Path:
    """A bag written with rosbags directly: a header, images ``(h, w, step, encoding,
    data)``, frame-time rows, and ``{topic: [json text]}``."""
    t = TYPESTORE.types
    stamp = t["builtin_interfaces/msg/Time"](sec=1, nanosec=0)
    head = t["std_msgs/msg/Header"](stamp=stamp, frame_id="skin")
    layout = t["std_msgs/msg/MultiArrayLayout"](dim=[], data_offset=0)
    directory = path.parent / (path.name + ".dir")
    with Writer(directory, version=9, storage_plugin=StoragePlugin.MCAP) as writer:
        conns = {}

        def put(topic, message):
            if topic not in conns:
                conns[topic] = writer.add_connection(
                    topic, message.__msgtype__, typestore=TYPESTORE
                )
            writer.write(conns[topic], 10**9, TYPESTORE.serialize_cdr(message, message.__msgtype__))

        if header is not None:
            put(HEADER_TOPIC, t["std_msgs/msg/String"](data=json.dumps(header)))
        for h, w, step, encoding, data in images:
            image = t["sensor_msgs/msg/Image"](
                header=head, height=h, width=w, encoding=encoding, is_bigendian=0,
                step=step, data=np.frombuffer(data, np.uint8),
            )  # fmt: skip
            put(FRAMES_TOPIC, image)
        for row in times:
            put(TIMES_TOPIC, t["std_msgs/msg/Float64MultiArray"](layout=layout, data=np.array(row)))
        for topic, texts in (strings or {}).items():
            for text in texts:
                put(topic, t["std_msgs/msg/String"](data=text))
    next(directory.glob("*.mcap")).rename(path)
    return path


def good_header(**changes) -> dict:
    header = json.loads(dumps_document({
        "format": "wovenskin.bag", "bag_format_version": 1, "info": INFO.to_dict(),
        "provenance": {}, "settings": {}, "footer": {}, "format_version": 1,
        "clean_close": True, "warnings": [], "clock_offset_ns": 0, "frames": 1,
        "calibrations": 0, "labels": 0, "annotations": 0, "frame_read_order": None,
    }))  # fmt: skip
    return {**header, **changes}


GOOD_IMAGE = (3, 2, 8, "32FC1", bytes(24))


def written(path: Path, data: bytes) -> Path:
    path.write_bytes(data)
    return path


@pytest.mark.parametrize(
    "make, words",
    [
        (lambda p: p, "no such file"),
        (lambda p: written(p, b""), "empty file"),
        (lambda p: written(p, b"hello, not a bag at all"), "not a ROS 2 bag"),
        (lambda p: written(p, bag.MCAP_MAGIC + bytes(100)), "damaged or unreadable"),
        (lambda p: craft(p, None, [GOOD_IMAGE], [[0, 0.0, -1]]), "no /wovenskin/header"),
        (lambda p: craft(p, good_header(), [(2, 2, 8, "32FC1", bytes(16))], [[0, 0.0, -1]]),
         "image 0 .* is 2x2"),
        (lambda p: craft(p, good_header(), [(3, 2, 8, "mono8", bytes(24))], [[0, 0.0, -1]]),
         "'mono8'"),
        (lambda p: craft(p, good_header(), [(3, 2, 8, "32FC1", bytes(20))], [[0, 0.0, -1]]),
         "20 bytes"),
        (lambda p: craft(p, good_header(), [GOOD_IMAGE], [[0, float("nan"), -1]]), "NaN"),
        (lambda p: craft(p, good_header(), [GOOD_IMAGE], [[0.5, 0.0, -1]]), "integers"),
        (lambda p: craft(p, good_header(), [GOOD_IMAGE], []), "1 images and 0 frame times"),
        (lambda p: craft(p, good_header(info={"rows": 0}), [], []), "impossible skin"),
        (lambda p: craft(p, good_header(bag_format_version=9), [], []), "newer"),
        (lambda p: craft(p, {"format": "other"}, [], []), "not a wovenskin.bag header"),
        (lambda p: craft(p, good_header(frames=0, labels=1), strings={LABELS_TOPIC: ["[" * 999]}),
         "nested deeper"),
        (lambda p: craft(p, good_header(frames=0, labels=2), strings={LABELS_TOPIC: [
            json.dumps({"index": 0, "label": "a", "start_s": 1, "end_s": 2, "kind": "trial",
                        "extra": {}})]}), "holds 1 items; the header says 2"),
        (lambda p: craft(p, good_header(frames=0, annotations=1), strings={ANNOTATIONS_TOPIC: [
            json.dumps({"index": 0, "stream": "s", "t": 1, "payload": {"__ndarray__": {
                "dtype": "<f8", "shape": [10**12], "base64": "AAAA"}}})]}), "does not match"),
        (lambda p: craft(p, good_header(frames=0), strings={FRAMES_TOPIC: ["x"]}),
         "holds std_msgs/msg/String, not sensor_msgs/msg/Image"),
    ],
)  # fmt: skip
def test_hostile_bags_are_one_line(tmp_path, make, words):
    path = make(tmp_path / "x.mcap")
    with pytest.raises(FormatError, match=words) as excinfo:
        read_bag(path)
    assert "\n" not in str(excinfo.value) and str(tmp_path / "x.mcap") in str(excinfo.value)


def test_a_cut_off_bag_is_one_line(tmp_path):
    write_bag(tmp_path / "r.mcap", recording(n=20))
    data = (tmp_path / "r.mcap").read_bytes()
    for cut in (len(data) // 2, len(data) - 30, 20):
        (tmp_path / "cut.mcap").write_bytes(data[:cut])
        try:
            back = read_bag(tmp_path / "cut.mcap")
        except FormatError as exc:
            assert "\n" not in str(exc)
        else:  # rosbags may recover a cut file by scanning: then it must be whole
            assert_same(recording(n=20), back)


def test_a_directory_without_metadata_is_refused(tmp_path):
    with pytest.raises(FormatError, match="no metadata.yaml"):
        read_bag(tmp_path)


# ----------------------------------------------------------------------------- command line


def test_convert_and_info_end_to_end(tmp_path):
    src = tmp_path / "r.wsrec"
    with RecordingWriter(src, INFO, {"participant": "p1"}, {"alpha": 0.5}) as writer:
        writer.add_calibration({"baseline": np.ones((3, 2), np.float32)})
        frames = np.nan_to_num(odd_frames(50))  # a labelled-stream .npz holds finite values
        writer.append_frames(np.arange(50), 5.0 + np.arange(50) / 199.7, frames)
        writer.add_label("swipe_up", 5.05, 5.1)
        writer.add_annotation("command", 5.07, {"gesture": "swipe_up"})
    mcap, back, npz = tmp_path / "r.mcap", tmp_path / "back.wsrec", tmp_path / "r.npz"
    result = cli.invoke(app, ["convert", str(src), str(mcap)])
    assert result.exit_code == 0, result.output
    assert "50 frames, 1 labels, 1 calibrations, 1 annotations" in " ".join(result.output.split())
    assert cli.invoke(app, ["convert", str(mcap), str(back)]).exit_code == 0
    assert_same(read_recording(src), read_recording(back), footer=False)
    assert cli.invoke(app, ["convert", str(mcap), str(npz)]).exit_code == 0
    assert read_labelled_stream(npz).event_labels.tolist() == ["swipe_up"]
    result = cli.invoke(app, ["info", str(mcap)])
    text = " ".join(result.output.split())
    assert result.exit_code == 0 and "ROS 2 bag" in text and "50 (0.25 s)" in text, text
    assert "p1" in text and "swipe_up 1" in text
    again = cli.invoke(app, ["convert", str(src), str(mcap)])
    assert again.exit_code == 2 and "pass --overwrite" in again.output
    assert cli.invoke(app, ["convert", str(src), str(mcap), "--overwrite"]).exit_code == 0


@pytest.mark.parametrize(
    "content, dst, words",
    [
        (None, "o.wsrec", "no such file"),
        (b"garbage bytes", "o.wsrec", "not a ROS 2 bag"),
        (bag.MCAP_MAGIC + b"\x00" * 64, "o.wsrec", "damaged or unreadable bag"),
        (b"ok", "o.txt", "output must end in .npz, .wsrec or .mcap"),
    ],
)
def test_convert_of_bad_bags_is_one_line(tmp_path, content, dst, words):
    src = tmp_path / "in.mcap"
    if content is not None:
        src.write_bytes(content)
    result = cli.invoke(app, ["convert", str(src), str(tmp_path / dst)])
    text = " ".join(result.output.split())
    assert result.exit_code == 2 and words in text and "Traceback" not in result.output, text
    assert not (tmp_path / dst).exists()
