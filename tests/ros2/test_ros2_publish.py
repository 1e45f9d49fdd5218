"""Tests of ``wovenskin run --ros2-publish``: the skin on ROS 2 (wovenskin.runtime.ros2_publish).

A replayed simulated stream runs through a session as fast as possible with the publisher
attached, while an in-process Cyclone DDS participant on loopback (a random domain per
test) subscribes to every topic.  What arrives is checked against the session's own
conditioned frames (collected independently, from the live skin's blocks; the tracks from a
touch reader of its own run over them), against ``rosbags``' serialiser byte for byte, and
against the configured rates on stream time.
"""

from __future__ import annotations

import os
import random
import time
import types

import numpy as np
import pytest
from stand_ins import ContactMeans, wait_until

pytest.importorskip("cyclonedds", reason="the ROS 2 publisher needs wovenskin[ros2]")
pytest.importorskip("rosbags", reason="the wire format is checked against rosbags")

from cli_helpers import invoke  # noqa: E402
from rosbags.typesys import Stores, get_typestore  # noqa: E402

from wovenskin.gestures import CLASS_NAMES  # noqa: E402
from wovenskin.recognition.pipeline import PipelineSettings  # noqa: E402
from wovenskin.recording.formats import write_labelled_stream  # noqa: E402
from wovenskin.ros2 import messages  # noqa: E402
from wovenskin.ros2.node import LATCHED, QosProfile, Ros2Error, Ros2Node, loopback_config  # noqa: E402
from wovenskin.runtime import ros2_settings  # noqa: E402
from wovenskin.runtime.ros2_publish import (  # noqa: E402
    POINT_FIELDS,
    TRACK_FIELDS,
    RateGate,
    SkinPublisher,
)
from wovenskin.runtime.ros2_settings import SkinTopics, parse_ros2_publish  # noqa: E402
from wovenskin.runtime.session import open_session  # noqa: E402
from wovenskin.sim.stream import simulate_stream  # noqa: E402
from wovenskin.skin.layout import SkinLayout  # noqa: E402
from wovenskin.tracking.touch import TouchReader  # noqa: E402

TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
T = TYPESTORE.types
ROS_TYPES = {
    "frames": "sensor_msgs/msg/Image",
    "contacts": "sensor_msgs/msg/PointCloud2",
    "tracks": "sensor_msgs/msg/PointCloud2",
    "gesture": "std_msgs/msg/String",
    "probabilities": "std_msgs/msg/Float32MultiArray",
    "class_names": "std_msgs/msg/String",
}
KINDS = {
    "frames": messages.Image,
    "contacts": messages.PointCloud2,
    "tracks": messages.PointCloud2,
    "gesture": messages.String,
    "probabilities": messages.Float32MultiArray,
    "class_names": messages.String,
}
DEEP = QosProfile(depth=100_000, reliable=False)  # keeps every sample until taken
RATES = {"frames": 100.0, "contacts": 50.0, "tracks": 50.0, "gesture": 20.0, "probabilities": 20.0}
TRACK_POINT = np.dtype(  # what a subscriber reads, written out here on its own
    {"names": list(TRACK_FIELDS), "formats": ["<f4"] * 3 + ["<u4"] + ["<f4"] * 4 + ["<u4"]}
)


@pytest.fixture(scope="module")
def cyclone_loopback(tmp_path_factory):
    path = loopback_config(tmp_path_factory.mktemp("dds") / "cyclonedds.xml")
    before = os.environ.get("CYCLONEDDS_URI")
    os.environ["CYCLONEDDS_URI"] = f"file://{path}"
    yield
    if before is None:
        os.environ.pop("CYCLONEDDS_URI", None)
    else:
        os.environ["CYCLONEDDS_URI"] = before


@pytest.fixture(scope="module")
def stream_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("stream") / "swipes.npz"
    stream = simulate_stream(3.0, seed=3, gestures=["swipe_up"], invalid_fraction=0.0)
    write_labelled_stream(path, stream)
    return path


def random_domain() -> int:
    return random.randint(100, 230)


def replay(stream_file, tmp_path, publisher, **kwargs):
    return open_session(
        f"replay:{stream_file}", "sim", recognizer=ContactMeans("swipe_up"), fast_replay=True,
        poses=tmp_path / "poses.toml", on_tick=publisher.on_tick,
        pipeline_settings=PipelineSettings(reader="touch"), **kwargs,
    )  # fmt: skip


def tracks_of(blocks, info) -> list[list]:
    """The tracks after each conditioned frame, from a touch reader of the test's own."""
    reader = TouchReader(
        info.rows, info.cols, info.row_pitch_mm, info.col_pitch_mm, info.sample_rate_hz
    )
    out = []
    for block in blocks:
        cond = block.cond
        for fast, active, touched in zip(cond.fast, cond.active, cond.touched, strict=True):
            state = reader.step(fast, active, bool(touched))
            out.append([] if state is None else [vars(t).copy() for t in state.tracks])
    return out


@pytest.fixture(scope="module")
def published(cyclone_loopback, stream_file, tmp_path_factory):
    """A whole replay published at the RATES, what the subscriber got (CDR bytes per
    topic, in order) and the session's conditioned frames, contacts and times per tick."""
    domain = random_domain()
    publisher = SkinPublisher(SkinTopics(**RATES, domain=domain))
    listener = Ros2Node(domain)
    readers = {
        name: listener.subscription(f"/wovenskin/{name}", KINDS[name], DEEP)
        for name in publisher.writers
    }
    assert wait_until(lambda: all(w.matched() for w in publisher.writers.values()))
    session = replay(stream_file, tmp_path_factory.mktemp("session"), publisher)
    blocks = []
    session.live_skin.on_block = blocks.append  # the session's conditioned frames, all of them
    result = session.run()
    session.close()
    received: dict[str, list[bytes]] = {name: [] for name in readers}

    def all_arrived() -> bool:
        for name, reader in readers.items():
            received[name] += [data for data, _ in reader.take_serialized(10_000)]
        return all(len(received[n]) == publisher.stats.counts[n] for n in readers)

    arrived = wait_until(all_arrived, timeout=10.0)
    ticks = {
        "t": np.concatenate([b.t for b in blocks]),
        "frames": np.concatenate([b.cond.signal for b in blocks]),
        "contacts": [c for b in blocks for c in b.cond.contacts],
        "tracks": tracks_of(blocks, session.live_skin.info),
    }
    yield types.SimpleNamespace(
        publisher=publisher, session=session, result=result, received=received,
        arrived=arrived, ticks=ticks, domain=domain,
    )  # fmt: skip
    listener.close()
    publisher.close()


def same_cdr(data: bytes, message, ros_type: str) -> None:
    """The wire bytes are rosbags' CDR of ``message`` (XCDR1, little-endian), padded with
    zeros to a multiple of 4 as Cyclone DDS sends every sample."""
    expected = bytes(TYPESTORE.serialize_cdr(message, ros_type))
    assert data[: len(expected)] == expected
    assert len(data) % 4 == 0 and data[len(expected) :] == bytes(len(data) - len(expected))


def decoded(data: bytes, ros_type: str):
    return TYPESTORE.deserialize_cdr(data, ros_type)


def ros_header(stamp, frame_id: str):
    time = T["builtin_interfaces/msg/Time"](sec=stamp.sec, nanosec=stamp.nanosec)
    return T["std_msgs/msg/Header"](stamp=time, frame_id=frame_id)


def test_every_topic_arrives_as_often_as_published(published) -> None:
    run = published
    assert run.result.ended == "the skin stream ended" and run.result.errors == 0
    assert run.arrived, {
        n: (len(v), run.publisher.stats.counts[n]) for n, v in run.received.items()
    }
    assert set(run.received) == set(ROS_TYPES)
    assert all(run.received[name] for name in ROS_TYPES)
    assert run.publisher.failure == ""
    assert run.publisher.stats.ticks == run.result.ticks == len(run.ticks["t"]) > 300


def test_frames_are_the_conditioned_frames_at_the_rate_on_stream_time(published) -> None:
    run = published
    times, frames = run.ticks["t"], run.ticks["frames"]
    assert np.diff(times) == pytest.approx(1 / 200, abs=1e-6)
    expected = frames[::2]  # 100 Hz of a 200 Hz skin: every second tick, from the first
    assert len(run.received["frames"]) == len(expected)
    rows, cols = frames.shape[1:]
    for data, frame in zip(run.received["frames"], expected, strict=True):
        image = decoded(data, ROS_TYPES["frames"])
        assert (image.height, image.width, image.step) == (rows, cols, 4 * cols)
        assert image.encoding == "32FC1" and image.is_bigendian == 0
        assert image.header.frame_id == "wovenskin_skin"
        values = np.frombuffer(image.data.tobytes(), dtype="<f4").reshape(rows, cols)
        np.testing.assert_array_equal(values, frame)  # [row, col], nothing flipped
        message = T[ROS_TYPES["frames"]](
            header=ros_header(image.header.stamp, "wovenskin_skin"), height=rows, width=cols,
            encoding="32FC1", is_bigendian=0, step=4 * cols,
            data=np.frombuffer(frame.astype("<f4").tobytes(), dtype=np.uint8),
        )  # fmt: skip
        same_cdr(data, message, ROS_TYPES["frames"])
    stamps = [decoded(d, ROS_TYPES["frames"]).header.stamp for d in run.received["frames"]]
    ns = [s.sec * 10**9 + s.nanosec for s in stamps]
    assert np.all(np.diff(ns) >= 0)  # the system clock when sent
    assert abs(ns[-1] / 1e9 - time.time()) < 60


def test_contacts_are_points_on_the_skin_plane_in_metres(published) -> None:
    run = published
    expected = run.ticks["contacts"][::4]  # 50 Hz of a 200 Hz skin
    assert len(run.received["contacts"]) == len(expected)
    layout = SkinLayout()
    touched = 0
    for data, contacts in zip(run.received["contacts"], expected, strict=True):
        cloud = decoded(data, ROS_TYPES["contacts"])
        assert [f.name for f in cloud.fields] == list(POINT_FIELDS)
        assert [f.offset for f in cloud.fields] == [4 * k for k in range(len(POINT_FIELDS))]
        assert all(f.datatype == 7 and f.count == 1 for f in cloud.fields)  # FLOAT32
        assert (cloud.height, cloud.width, cloud.point_step) == (1, len(contacts), 32)
        assert cloud.row_step == 32 * len(contacts) and cloud.header.frame_id == "wovenskin_skin"
        points = np.frombuffer(cloud.data.tobytes(), dtype="<f4").reshape(len(contacts), 8)
        for point, contact in zip(points, contacts, strict=True):
            x_mm, y_mm = layout.rc_to_mm(contact.row, contact.col)
            np.testing.assert_allclose(point[:3], [x_mm / 1000, y_mm / 1000, 0.0], rtol=1e-6)
            want = [contact.row, contact.col, contact.size, contact.peak, contact.strength]
            np.testing.assert_allclose(point[3:], want, rtol=1e-6)
        touched += bool(contacts)
        fields = [
            T["sensor_msgs/msg/PointField"](name=n, offset=4 * k, datatype=7, count=1)
            for k, n in enumerate(POINT_FIELDS)
        ]
        message = T[ROS_TYPES["contacts"]](
            header=ros_header(cloud.header.stamp, "wovenskin_skin"), height=1,
            width=len(contacts), fields=fields, is_bigendian=False, point_step=32,
            row_step=32 * len(contacts), data=np.frombuffer(points.tobytes(), dtype=np.uint8),
            is_dense=True,
        )  # fmt: skip
        same_cdr(data, message, ROS_TYPES["contacts"])
    assert 0 < touched < len(expected)  # swipes and empty clouds between them


def test_tracks_are_the_recognisers_in_the_frame_of_the_contacts(published) -> None:
    run = published
    expected = run.ticks["tracks"][::4]  # 50 Hz of a 200 Hz skin, the frames of the contacts
    assert len(run.received["tracks"]) == len(expected)
    layout, rate = SkinLayout(), 200.0
    kinds = [7, 7, 7, 6, 7, 7, 7, 7, 6]  # FLOAT32 x, y, z; UINT32 id; ...; UINT32 merged
    seen: set[int] = set()
    for data, tracks in zip(run.received["tracks"], expected, strict=True):
        cloud = decoded(data, ROS_TYPES["tracks"])
        assert [f.name for f in cloud.fields] == list(TRACK_FIELDS)
        assert [f.offset for f in cloud.fields] == [4 * k for k in range(len(TRACK_FIELDS))]
        assert [f.datatype for f in cloud.fields] == kinds and {f.count for f in cloud.fields} == {
            1
        }
        assert (cloud.height, cloud.width, cloud.point_step) == (1, len(tracks), 36)
        assert cloud.row_step == 36 * len(tracks) and cloud.header.frame_id == "wovenskin_skin"
        points = np.frombuffer(cloud.data.tobytes(), dtype=TRACK_POINT)
        for point, track in zip(points, tracks, strict=True):
            row, col = track["y"] / layout.row_pitch_mm, track["x"] / layout.col_pitch_mm
            x_mm, y_mm = layout.rc_to_mm(row, col)  # the contacts' frame: corner origin, metres
            np.testing.assert_allclose(
                [point["x"], point["y"], point["z"]], [x_mm / 1000, y_mm / 1000, 0.0], rtol=1e-6
            )
            velocity = [track["vx"] * rate / 1000, track["vy"] * rate / 1000]  # mm/frame -> m/s
            np.testing.assert_allclose([point["vx"], point["vy"]], velocity, rtol=1e-5, atol=1e-7)
            assert point["id"] == track["id"] and point["merged"] == int(track["merged"])
            assert point["travel"] == pytest.approx(track["travel"] / 1000, rel=1e-6)
            assert point["amplitude"] == pytest.approx(track["amplitude"], rel=1e-6)
            assert 0 <= point["x"] <= layout.width_mm / 1000
            assert 0 <= point["y"] <= layout.height_mm / 1000
            seen.add(int(point["id"]))
        fields = [
            T["sensor_msgs/msg/PointField"](name=n, offset=4 * k, datatype=kind, count=1)
            for k, (n, kind) in enumerate(zip(TRACK_FIELDS, kinds, strict=True))
        ]
        message = T[ROS_TYPES["tracks"]](
            header=ros_header(cloud.header.stamp, "wovenskin_skin"), height=1,
            width=len(tracks), fields=fields, is_bigendian=False, point_step=36,
            row_step=36 * len(tracks), data=np.frombuffer(points.tobytes(), dtype=np.uint8),
            is_dense=True,
        )  # fmt: skip
        same_cdr(data, message, ROS_TYPES["tracks"])
    assert seen and min(seen) >= 1  # identities count up from 1
    assert 0 < sum(bool(t) for t in expected) < len(expected)  # swipes, empty clouds between


def test_gesture_goes_at_its_rate_and_on_every_change(published) -> None:
    run = published
    times = run.ticks["t"]
    changes = [(c.t, c.gesture or "") for c in run.session.pipeline.changes]
    assert len(changes) >= 2
    expected, last = [], None
    for i, t in enumerate(times):
        now = ([g for when, g in changes if when <= t] or [""])[-1]
        if i % 10 == 0 or now != last:  # 20 Hz of a 200 Hz skin, and each change
            expected.append(now)
            last = now
    got = [decoded(d, ROS_TYPES["gesture"]).data for d in run.received["gesture"]]
    assert got == expected and "swipe_up" in got
    for data, text in zip(run.received["gesture"], got, strict=True):
        same_cdr(data, T[ROS_TYPES["gesture"]](data=text), ROS_TYPES["gesture"])


def test_probabilities_and_their_latched_class_names(published) -> None:
    run = published
    n = len(CLASS_NAMES)
    assert len(run.received["probabilities"]) == (len(run.ticks["t"]) + 9) // 10
    ros_type = ROS_TYPES["probabilities"]
    for data in run.received["probabilities"]:
        array = decoded(data, ros_type)
        (dim,) = array.layout.dim
        assert (dim.label, dim.size, dim.stride, array.layout.data_offset) == ("class", n, n, 0)
        assert len(array.data) == n and array.data.sum() == pytest.approx(1.0)
        layout = T["std_msgs/msg/MultiArrayLayout"](dim=[dim], data_offset=0)
        same_cdr(data, T[ros_type](layout=layout, data=array.data), ros_type)
    names = [decoded(d, ROS_TYPES["class_names"]).data for d in run.received["class_names"]]
    assert names == [",".join(CLASS_NAMES)]  # once: the names did not change
    # A subscriber that joins after the run still gets them (transient local, as latched).
    with Ros2Node(run.domain) as late:
        reader = late.subscription("/wovenskin/class_names", messages.String, LATCHED)
        got: list[bytes] = []
        assert wait_until(lambda: bool(got.extend(d for d, _ in reader.take_serialized()) or got))
    assert decoded(got[0], ROS_TYPES["class_names"]).data == ",".join(CLASS_NAMES)
    same_cdr(got[0], T["std_msgs/msg/String"](data=",".join(CLASS_NAMES)), "std_msgs/msg/String")


def test_the_cost_per_tick_is_measured(published) -> None:
    stats = published.publisher.stats
    assert stats.ticks > 0 and stats.mean_us > 0 and stats.max_ns >= stats.total_ns / stats.ticks
    line = published.publisher.summary()
    assert "us per tick" in line and f"{stats.counts['frames']} frames" in line


def test_a_dds_error_is_one_line_and_the_session_goes_on(
    cyclone_loopback, stream_file, tmp_path
) -> None:
    heard: list[str] = []
    publisher = SkinPublisher(SkinTopics(domain=random_domain()), on_message=heard.append)

    class Broken:
        def publish(self, message) -> None:
            raise Ros2Error("DDS write failed (error -1)\nsecond line")

    publisher.writers["frames"] = Broken()
    session = replay(stream_file, tmp_path, publisher)
    result = session.run(1.0)
    session.close()
    publisher.close()
    assert result.ticks > 90 and result.errors == 0  # 1 s of skin time, less calibration
    assert heard == ["ROS 2 publishing stopped: DDS write failed (error -1) second line"]
    assert heard[0] in session.state.messages
    assert sum(publisher.stats.counts.values()) == 0 and publisher.stats.ticks == 1


def test_rates_count_on_stream_time() -> None:
    times = 0.5 + np.arange(2000) / 200.0  # 10 s of a 200 Hz skin
    for rate, every in ((100.0, 2), (50.0, 4), (20.0, 10), (200.0, 1), (1000.0, 1)):
        gate = RateGate(rate, early_s=0.0025)  # half a frame, as the publisher gives
        assert [i for i, t in enumerate(times) if gate.due(t)] == list(range(0, 2000, every))
    gate = RateGate(30.0, early_s=0.0025)
    published = [t for t in times if gate.due(t)]
    assert len(published) == 300  # 30 Hz, whatever the frames' spacing
    assert np.diff(published).min() >= 1 / 30 - 1 / 200  # the frames nearest the due times
    assert not any(RateGate(0.0).due(t) for t in times)  # 0: off
    gate = RateGate(20.0)
    assert gate.due(5.0) and not gate.due(5.02) and gate.due(5.05)
    assert gate.due(9.0) and not gate.due(9.01)  # a gap: again from there, no burst
    assert gate.due(1.0)  # the clock went back (a new session): starts over


def test_settings_from_the_command_line_value() -> None:
    assert parse_ros2_publish(None) is None
    assert parse_ros2_publish("on") == SkinTopics()
    chosen = parse_ros2_publish("frames=50,contacts=20,probabilities=0,ns=/skin/left,domain=7")
    assert chosen == SkinTopics(50, 20, 20, 0, "/skin/left", 7)
    assert chosen.tracks == 50.0 and parse_ros2_publish("tracks=0").rate("tracks") == 0.0
    assert chosen.topic("frames") == "/skin/left/frames"
    assert SkinTopics(ns="wovenskin/").topic("gesture") == "/wovenskin/gesture"


@pytest.mark.parametrize(
    "value, says",
    [
        ("frames=fast", "frames"),
        ("frames=-5", "frames must be a rate of 0-1000 Hz"),
        ("colour=1", "unknown setting 'colour'"),
        ("frames", "not a list of key=value pairs"),
        ("off", "not a list of key=value pairs"),
        ("ns=/1st", "not a fully qualified ROS 2 name"),
        ("domain=999", "domain id must be 0-232"),
        ("frames=1,frames=2", "twice"),
    ],
)
def test_a_bad_ros2_publish_value_is_one_line(value: str, says: str) -> None:
    result = invoke("run", "--headless", "--ros2-publish", value)
    assert result.exit_code == 2, result.output
    keys = "frames, contacts, tracks, gesture, probabilities, ns, domain"
    assert says in result.stderr and keys in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1 and "Traceback" not in result.output


def test_without_cyclonedds_it_is_one_line(monkeypatch) -> None:
    no_module = types.SimpleNamespace(util=types.SimpleNamespace(find_spec=lambda name: None))
    monkeypatch.setattr(ros2_settings, "importlib", no_module)
    result = invoke("run", "--headless", "--ros2-publish", "on")
    assert result.exit_code == 2, result.output
    assert "install wovenskin[ros2]" in result.stderr
    assert len(result.stderr.strip().splitlines()) == 1


def test_wovenskin_run_publishes_headless(cyclone_loopback, stream_file, tmp_path) -> None:
    domain = random_domain()
    result = invoke(
        "run", "--skin", f"replay:{stream_file}", "--headless", "--seconds", "1",
        "--poses", tmp_path / "p.toml",
        "--ros2-publish", f"frames=50,contacts=0,tracks=0,domain={domain}",
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    assert f"ROS 2 (domain {domain}) under /wovenskin: frames 50 Hz, gesture 20 Hz" in result.stderr
    summary = [line for line in result.stderr.splitlines() if line.startswith("ROS 2 under")]
    assert len(summary) == 1 and " frames" in summary[0] and "contacts" not in summary[0]
    assert "tracks" not in summary[0]  # turned off like the others
    assert "us per tick" in summary[0]
