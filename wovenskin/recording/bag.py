"""A recording as a ROS 2 bag (``.mcap``): :func:`write_bag` and :func:`read_bag`, lossless.

Standard message types only, so any ROS 2 tool (``ros2 bag play``, Foxglove, PlotJuggler)
reads the bag; the layout is documented in ``docs/recording-format.md`` ("ROS 2 bags"):

- ``/wovenskin/raw_frames``: ``sensor_msgs/msg/Image``, one per frame (``32FC1``, rows x
  cols, the frame's float32 little-endian bytes as stored);
- ``/wovenskin/frame_times``: ``std_msgs/msg/Float64MultiArray``, one per frame,
  ``[seq, t, device_t_us]``;
- ``/wovenskin/header``: ``std_msgs/msg/String``, one: info, provenance, settings, footer,
  counts, the clock offset (JSON);
- ``/wovenskin/calibrations``, ``/wovenskin/labels``, ``/wovenskin/annotations``:
  ``std_msgs/msg/String``, one JSON item (with its ``index``) each
  (:mod:`~wovenskin.recording.bag_documents`).

A message's bag time is ``clock_offset_ns + round(t * 1e9)`` (``t``: a frame's time, a
label's start, an annotation's time; the first frame's for the header and calibrations),
where the offset is the recording's ``started_utc`` in epoch nanoseconds when it has one,
so ROS tools show real dates.  Reading takes ``t`` from ``frame_times`` (bit-exact), never
from stamps, and frame values from the images' bytes, so a recording survives
``.wsrec -> .mcap -> .wsrec`` bit for bit.

Bags are read and written with ``rosbags`` (the optional ``wovenskin[ros2]`` extra),
imported only when a bag is touched.
"""

from __future__ import annotations

import math
import os
import shutil
import tempfile
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

import numpy as np

from wovenskin.errors import MissingExtraError
from wovenskin.outputs import check_new_output
from wovenskin.recording.bag_documents import (
    annotation_from_item,
    annotation_item,
    calibration_from_item,
    dumps_document,
    indexed_items,
    label_from_item,
    label_item,
    loads_document,
)
from wovenskin.recording.native import Recording, skin_info_from_document
from wovenskin.recording.untrusted import FormatError, one_line

FRAMES_TOPIC = "/wovenskin/raw_frames"
TIMES_TOPIC = "/wovenskin/frame_times"
HEADER_TOPIC = "/wovenskin/header"
CALIBRATIONS_TOPIC = "/wovenskin/calibrations"
LABELS_TOPIC = "/wovenskin/labels"
ANNOTATIONS_TOPIC = "/wovenskin/annotations"
IMAGE = "sensor_msgs/msg/Image"
FLOATS = "std_msgs/msg/Float64MultiArray"
STRING = "std_msgs/msg/String"
TOPIC_TYPES = {
    HEADER_TOPIC: STRING,
    FRAMES_TOPIC: IMAGE,
    TIMES_TOPIC: FLOATS,
    CALIBRATIONS_TOPIC: STRING,
    LABELS_TOPIC: STRING,
    ANNOTATIONS_TOPIC: STRING,
}
"""Every topic of a wovenskin bag and its message type."""
BAG_FORMAT = "wovenskin.bag"
BAG_FORMAT_VERSION = 1
FRAME_ID = "skin"
ENCODING = "32FC1"
MCAP_MAGIC = b"\x89MCAP0\r\n"
MAX_EXACT = 2**53
"""Largest integer magnitude a float64 holds exactly (``seq`` and ``device_t_us``)."""
_MAX_NS = 2**63 - 1


def is_bag(path: str | os.PathLike) -> bool:
    """Whether ``path`` is meant as a ROS 2 bag: a file named ``*.mcap`` or starting with
    the MCAP magic, or a directory with a ``metadata.yaml`` (a rosbag2 directory)."""
    path = Path(path)
    if path.is_dir():
        return (path / "metadata.yaml").is_file()
    if path.suffix == ".mcap":
        return True
    try:
        with open(path, "rb") as f:
            return f.read(len(MCAP_MAGIC)) == MCAP_MAGIC
    except OSError:
        return False


def _rosbags() -> tuple[Any, Any]:
    """``(rosbags.rosbag2 module, the ROS 2 Jazzy typestore)``, or one line saying what to
    install."""
    try:
        import rosbags.rosbag2 as rosbag2
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        raise MissingExtraError(
            "ROS 2 bags need the rosbags package: install wovenskin[ros2]"
        ) from None
    return rosbag2, get_typestore(Stores.ROS2_JAZZY)


# ----------------------------------------------------------------------------- writing


@dataclass(frozen=True)
class _Clock:
    """Bag times of a recording: ``offset_ns + round(t * 1e9)``."""

    offset_ns: int
    frame_ns: np.ndarray  # int64, one per frame

    def at(self, t: float) -> int:
        """The bag time of a document at stream time ``t`` (clamped into the bag's range)."""
        if not math.isfinite(t):
            return self.first_ns
        return min(max(self.offset_ns + round(t * 1e9), 0), _MAX_NS)

    @property
    def first_ns(self) -> int:
        return int(self.frame_ns[0]) if len(self.frame_ns) else self.offset_ns


def _started_ns(provenance: dict) -> int | None:
    """The recording's ``started_utc`` as nanoseconds since the epoch, None if unusable."""
    text = provenance.get("started_utc")
    if not isinstance(text, str):
        return None
    try:
        started = datetime.fromisoformat(text)
    except ValueError:
        return None
    if started.tzinfo is None:
        started = started.replace(tzinfo=UTC)
    micros = (started - datetime(1970, 1, 1, tzinfo=UTC)) // timedelta(microseconds=1)
    return micros * 1000 if micros >= 0 else None


def _clock(where: str, recording: Recording) -> _Clock:
    """The bag clock: offset from ``started_utc`` when every frame then lands in the bag's
    unsigned 63-bit range, else 0, else a shift that makes the earliest frame time 0."""
    t = np.asarray(recording.t, dtype=np.float64)
    if not np.isfinite(t).all():
        raise FormatError(f"{where}: frame times must be finite to be stored in a bag")
    relative = np.round(t * 1e9)
    if len(t) and np.abs(relative).max() >= 2**62:
        raise FormatError(f"{where}: frame times beyond +-146 years cannot be bag times")
    relative = relative.astype(np.int64)
    low, high = (int(relative.min()), int(relative.max())) if len(t) else (0, 0)
    started = _started_ns(recording.provenance)
    for offset in (started, 0, -low):
        if offset is not None and offset + low >= 0 and offset + high <= _MAX_NS:
            return _Clock(offset, relative + offset)
    raise FormatError(f"{where}: frame times span more than a bag can hold")  # pragma: no cover


def _frame_columns(where: str, recording: Recording) -> tuple[np.ndarray, np.ndarray]:
    """``(frames as little-endian float32 (T, R, C), [seq, t, device_t_us] float64 (T, 3))``,
    every check made before anything is written."""
    info = recording.info
    frames = np.asarray(recording.frames)
    n = len(recording.t)
    if (
        frames.dtype.kind != "f"
        or frames.dtype.itemsize != 4
        or frames.shape != (n, info.rows, info.cols)
    ):
        raise FormatError(
            f"{where}: frames must be float32 ({n}, {info.rows}, {info.cols}), got "
            f"{frames.dtype} {frames.shape}"
        )
    seq, device_t_us = (np.asarray(a) for a in (recording.seq, recording.device_t_us))
    if seq.shape != (n,) or device_t_us.shape != (n,):
        raise FormatError(f"{where}: seq and device_t_us need one entry per frame")
    for name, values in (("seq", seq), ("device_t_us", device_t_us)):
        if values.dtype.kind not in "iu":
            raise FormatError(f"{where}: {name} must be integers, got {values.dtype}")
        if ((values > MAX_EXACT) | (values < -MAX_EXACT)).any():
            raise FormatError(
                f"{where}: {name} values beyond 2**53 cannot be stored exactly as float64"
            )
    times = np.stack([seq, recording.t, device_t_us], axis=1).astype(np.float64)
    return np.ascontiguousarray(frames, dtype="<f4"), times


def _documents(where: str, recording: Recording, clock: _Clock) -> dict[str, list]:
    """``{topic: [(bag time, JSON text)]}`` for the header and every document, each
    checked with the reader's checks first."""
    frame_ns = clock.frame_ns
    read_order = np.argsort(frame_ns, kind="stable")  # the order a reader yields frames in
    in_order = bool((read_order == np.arange(len(frame_ns))).all())
    header = {
        "format": BAG_FORMAT,
        "bag_format_version": BAG_FORMAT_VERSION,
        "info": recording.info.to_dict(),
        "provenance": recording.provenance,
        "settings": recording.settings,
        "footer": recording.footer,
        "format_version": recording.format_version,
        "clean_close": bool(recording.clean_close),
        "warnings": [str(w) for w in recording.warnings],
        "clock_offset_ns": clock.offset_ns,
        "frames": len(frame_ns),
        "calibrations": len(recording.calibrations),
        "labels": len(recording.labels),
        "annotations": len(recording.annotations),
        "frame_read_order": None if in_order else read_order.astype(np.int64),
    }
    items = {
        CALIBRATIONS_TOPIC: [
            (clock.first_ns, {"index": i, "calibration": c})
            for i, c in enumerate(recording.calibrations)
        ],
        LABELS_TOPIC: [
            (clock.at(x.start_s), label_item(i, x)) for i, x in enumerate(recording.labels)
        ],
        ANNOTATIONS_TOPIC: [
            (clock.at(x.t), annotation_item(i, x)) for i, x in enumerate(recording.annotations)
        ],
    }
    checks = {
        CALIBRATIONS_TOPIC: calibration_from_item,
        LABELS_TOPIC: label_from_item,
        ANNOTATIONS_TOPIC: annotation_from_item,
    }
    try:
        out: dict[str, list] = {HEADER_TOPIC: [(clock.first_ns, dumps_document(header))]}
    except ValueError as exc:
        raise FormatError(f"{where}: the header (info, provenance, settings): {exc}") from None
    for topic, pairs in items.items():
        out[topic] = []
        for ns, item in pairs:
            try:
                checks[topic](item)
                out[topic].append((ns, dumps_document(item)))
            except ValueError as exc:
                raise FormatError(f"{where}: item {item['index']} of {topic}: {exc}") from None
    return out


def write_bag(path: str | os.PathLike, recording: Recording, *, overwrite: bool = False) -> None:
    """Write ``recording`` as a ROS 2 bag: one ``.mcap`` file at ``path``.

    The bag is written into a temporary directory beside ``path`` and its ``.mcap`` moved
    into place at the end, so an error never leaves a partial output.  An existing ``path``
    is refused unless ``overwrite`` (:class:`~wovenskin.outputs.OutputExistsError`); data a
    bag cannot hold exactly is refused in one line before anything is written.
    """
    target = check_new_output(path, overwrite)
    where = str(target)
    rosbag2, typestore = _rosbags()
    frames, times = _frame_columns(where, recording)
    clock = _clock(where, recording)
    documents = _documents(where, recording, clock)
    workdir = Path(tempfile.mkdtemp(prefix=f".{target.name}.", dir=target.parent))
    try:
        bag_dir = workdir / "bag"
        with rosbag2.Writer(
            bag_dir, version=9, storage_plugin=rosbag2.StoragePlugin.MCAP
        ) as writer:
            info = recording.info
            for key, value in (
                ("format", BAG_FORMAT),
                ("rows", info.rows),
                ("cols", info.cols),
                ("sample_rate_hz", info.sample_rate_hz),
                ("frames", len(times)),
                ("started_utc", recording.provenance.get("started_utc", "")),
            ):
                writer.set_custom_data(key, str(value))
            connections = {
                topic: writer.add_connection(topic, msgtype, typestore=typestore)
                for topic, msgtype in TOPIC_TYPES.items()
            }
            header = documents.pop(HEADER_TOPIC)
            _write_strings(writer, connections[HEADER_TOPIC], typestore, header)
            _write_frames(writer, connections, typestore, frames, times, clock.frame_ns)
            for topic, messages in documents.items():
                _write_strings(writer, connections[topic], typestore, messages)
        written = list(bag_dir.glob("*.mcap"))
        if len(written) != 1:  # pragma: no cover - rosbags writes one file per bag
            raise FormatError(f"{where}: rosbags wrote {len(written)} .mcap files, not one")
        check_new_output(target, overwrite)
        os.replace(written[0], target)
    finally:
        shutil.rmtree(workdir, ignore_errors=True)


def _write_strings(writer, connection, typestore, messages: list[tuple[int, str]]) -> None:
    string = typestore.types[STRING]
    for ns, text in messages:
        writer.write(connection, ns, typestore.serialize_cdr(string(data=text), STRING))


def _write_frames(writer, connections, typestore, frames, times, frame_ns) -> None:
    types = typestore.types
    image, header, stamp = (types[name] for name in (
        IMAGE, "std_msgs/msg/Header", "builtin_interfaces/msg/Time"))  # fmt: skip
    floats, layout = types[FLOATS], types["std_msgs/msg/MultiArrayLayout"]
    dims = [types["std_msgs/msg/MultiArrayDimension"](label="seq_t_device_t_us", size=3, stride=3)]
    _, rows, cols = frames.shape
    raw, times_at = connections[FRAMES_TOPIC], connections[TIMES_TOPIC]
    for k in range(len(times)):
        ns = int(frame_ns[k])
        message = image(
            header=header(stamp=stamp(sec=ns // 10**9, nanosec=ns % 10**9), frame_id=FRAME_ID),
            height=rows,
            width=cols,
            encoding=ENCODING,
            is_bigendian=0,
            step=4 * cols,
            data=frames[k].reshape(-1).view(np.uint8),
        )
        writer.write(raw, ns, typestore.serialize_cdr(message, IMAGE))
        row = floats(layout=layout(dim=dims, data_offset=0), data=times[k])
        writer.write(times_at, ns, typestore.serialize_cdr(row, FLOATS))


# ----------------------------------------------------------------------------- reading


def read_bag(path: str | os.PathLike) -> Recording:
    """The :class:`Recording` a wovenskin bag holds (a ``.mcap`` file or a rosbag2
    directory); :class:`FormatError` (one line) for anything else or anything damaged."""
    where = str(path)
    path = Path(path)
    if not path.exists():
        raise FormatError(f"{where}: no such file")
    if path.is_dir():
        if not (path / "metadata.yaml").is_file():
            raise FormatError(f"{where}: not a rosbag2 directory (no metadata.yaml)")
    else:
        _check_mcap_file(where, path)
    _, typestore = _rosbags()
    messages = _read_messages(where, path, typestore)
    try:
        return _recording(messages)
    except ValueError as exc:
        raise FormatError(f"{where}: {exc}") from None


def _check_mcap_file(where: str, path: Path) -> None:
    try:
        with open(path, "rb") as f:
            head = f.read(len(MCAP_MAGIC))
    except OSError as exc:
        raise FormatError(f"{where}: cannot read ({exc.strerror or exc})") from None
    if not head:
        raise FormatError(f"{where}: empty file (0 bytes)")
    if head != MCAP_MAGIC:
        raise FormatError(f"{where}: not a ROS 2 bag (no MCAP magic at the start)")
    if path.suffix != ".mcap":
        raise FormatError(f"{where}: an MCAP bag must be named *.mcap to be read")


def _read_messages(where: str, path: Path, typestore) -> dict[str, list[tuple[int, Any]]]:
    """``{topic: [(bag time, decoded message)]}`` of wovenskin's topics, in the order the
    bag yields them (bag time, then write order); other topics are ignored."""
    from rosbags.rosbag2 import Reader

    found: dict[str, list[tuple[int, Any]]] = {topic: [] for topic in TOPIC_TYPES}
    try:
        with Reader(path) as reader:
            ours = []
            for connection in reader.connections:
                wanted = TOPIC_TYPES.get(connection.topic)
                if wanted is None:
                    continue
                if connection.msgtype != wanted:
                    raise FormatError(
                        f"{where}: topic {connection.topic} holds {connection.msgtype}, "
                        f"not {wanted}"
                    )
                ours.append(connection)
            if not any(c.topic == HEADER_TOPIC for c in ours):
                raise FormatError(
                    f"{where}: not a wovenskin bag (no {HEADER_TOPIC} topic); bags of other "
                    "tools are not converted"
                )
            for connection, ns, data in reader.messages(connections=ours):
                message = typestore.deserialize_cdr(data, connection.msgtype)
                found[connection.topic].append((ns, message))
    except FormatError:
        raise
    except Exception as exc:  # noqa: BLE001 - rosbags parsing arbitrary bytes raises anything
        raise FormatError(f"{where}: damaged or unreadable bag ({one_line(exc)[:160]})") from None
    return found


def _recording(messages: dict[str, list[tuple[int, Any]]]) -> Recording:
    """The recording from decoded messages; ``ValueError`` (one line) for any problem."""
    headers = messages[HEADER_TOPIC]
    if len(headers) != 1:
        raise ValueError(f"{HEADER_TOPIC} holds {len(headers)} messages, not one")
    header = loads_document(headers[0][1].data, HEADER_TOPIC)
    if not isinstance(header, dict) or header.get("format") != BAG_FORMAT:
        raise ValueError(f"{HEADER_TOPIC} is not a {BAG_FORMAT} header")
    version = header.get("bag_format_version")
    if type(version) is not int or version > BAG_FORMAT_VERSION:
        raise ValueError(f"bag format version {str(version)[:20]} is newer than this wovenskin's")
    info = skin_info_from_document(header.get("info"))
    provenance, settings, footer = (
        _object(header, k) for k in ("provenance", "settings", "footer")
    )
    warnings = header.get("warnings")
    format_version, clean_close = header.get("format_version"), header.get("clean_close")
    if not isinstance(warnings, list) or not all(isinstance(w, str) for w in warnings):
        raise ValueError("header 'warnings' is not a list of text")
    if type(format_version) is not int or type(clean_close) is not bool:
        raise ValueError("header 'format_version' or 'clean_close' has the wrong type")
    frames, seq, t, device_t_us = _frames(messages, header, info.rows, info.cols)

    def items(topic: str, check) -> list:
        decoded = [(ns, loads_document(m.data, topic)) for ns, m in messages[topic]]
        count = header.get(topic.rsplit("/", 1)[1])
        try:
            return [check(item) for item in indexed_items(decoded, count, topic)]
        except ValueError as exc:
            raise ValueError(f"{topic}: {exc}") from None

    return Recording(
        info=info,
        provenance=provenance,
        settings=settings,
        frames=frames,
        seq=seq,
        t=t,
        device_t_us=device_t_us,
        calibrations=items(CALIBRATIONS_TOPIC, calibration_from_item),
        labels=items(LABELS_TOPIC, label_from_item),
        annotations=items(ANNOTATIONS_TOPIC, annotation_from_item),
        clean_close=clean_close,
        warnings=list(warnings),
        footer=footer,
        format_version=format_version,
    )


def _object(header: dict, key: str) -> dict:
    value = header.get(key)
    if not isinstance(value, dict):
        raise ValueError(f"header '{key}' is not an object")
    return value


def _frames(messages, header: dict, rows: int, cols: int) -> tuple[np.ndarray, ...]:
    """``(frames, seq, t, device_t_us)`` from the image and frame-time messages, each
    checked, in the recording's original order."""
    images, times = messages[FRAMES_TOPIC], messages[TIMES_TOPIC]
    count = header.get("frames")
    if type(count) is not int or not len(images) == len(times) == count:
        raise ValueError(
            f"the bag holds {len(images)} images and {len(times)} frame times; the header "
            f"says {str(count)[:20]} frames"
        )
    size = 4 * rows * cols
    values = np.empty((count, size), np.uint8)
    columns = np.empty((count, 3), np.float64)
    for k, ((ns, image), (times_ns, row)) in enumerate(zip(images, times, strict=True)):
        shape = (image.height, image.width, image.step, image.encoding, image.is_bigendian)
        if shape != (rows, cols, 4 * cols, ENCODING, 0) or len(image.data) != size:
            raise ValueError(
                f"image {k} of {FRAMES_TOPIC} is {image.height}x{image.width} "
                f"{image.encoding!r} (step {image.step}, {len(image.data)} bytes, big-endian "
                f"{image.is_bigendian}); the skin is {rows}x{cols} {ENCODING}, little-endian"
            )
        if ns != times_ns or len(row.data) != 3:
            raise ValueError(f"frame time {k} does not match its image (3 values, same bag time)")
        values[k] = image.data
        columns[k] = row.data
    if not np.isfinite(columns).all():
        raise ValueError(f"{TIMES_TOPIC} holds NaN or infinite values")
    exact = np.abs(columns[:, [0, 2]]) <= MAX_EXACT
    if not exact.all() or not (columns[:, [0, 2]] == np.round(columns[:, [0, 2]])).all():
        raise ValueError(f"{TIMES_TOPIC}: seq and device_t_us must be integers within 2**53")
    order = header.get("frame_read_order")
    if order is not None:  # frames were not in time order: undo the bag's sorting
        if (
            not isinstance(order, np.ndarray)
            or order.dtype.kind not in "iu"
            or not np.array_equal(np.sort(order), np.arange(count))
        ):
            raise ValueError("header 'frame_read_order' is not an ordering of the frames")
        restored_values, restored_columns = np.empty_like(values), np.empty_like(columns)
        restored_values[order], restored_columns[order] = values, columns
        values, columns = restored_values, restored_columns
    frames = values.view("<f4").reshape(count, rows, cols).astype(np.float32)
    seq, device_t_us = (columns[:, i].astype(np.int64) for i in (0, 2))
    return frames, seq, columns[:, 1].copy(), device_t_us
