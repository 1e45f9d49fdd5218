"""The skin on ROS 2: a running control session's frames, contacts, tracks and gestures.

:class:`SkinPublisher` is handed to a session as its ``on_tick`` (``open_session(...,
on_tick=publisher.on_tick)``) and publishes, under its namespace (default ``/wovenskin``):

- ``frames`` (``sensor_msgs/msg/Image``, ``32FC1``): the tick's conditioned frame, ``height``
  = rows, ``width`` = columns, ``step`` = 4 x columns, little-endian float32 in the
  ``[row, col]`` order of :mod:`wovenskin.skin.layout` (row 0 the top edge as the user faces
  the skin, column 0 the left edge);
- ``contacts`` (``sensor_msgs/msg/PointCloud2``): one point per contact of that frame
  (:class:`~wovenskin.signal.contacts.Contact`), float32 fields ``x``, ``y``, ``z`` in
  metres on the skin plane, then ``row``, ``col`` (channel units), ``size`` (channels),
  ``peak`` and ``strength``; ``x`` to the right and ``y`` down from the top-left corner of
  the sensing area (:meth:`~wovenskin.skin.layout.SkinLayout.rc_to_mm`), ``z`` = 0 (in a
  right-handed frame the ``z`` axis points into the skin, away from the user); an empty
  cloud when nothing touches;
- ``tracks`` (``sensor_msgs/msg/PointCloud2``): one point per contact track the recogniser
  follows after that frame (:class:`~wovenskin.tracking.tracker.Track`, the touch reader
  only), float32 ``x``, ``y``, ``z`` in metres in the frame of the contacts, uint32 ``id``,
  float32 ``vx``, ``vy`` (m/s), ``travel`` (m) and ``amplitude``, uint32 ``merged`` (1:
  sharing another track's peak); an empty cloud when nothing is tracked;
- ``gesture`` (``std_msgs/msg/String``): the active gesture, ``""`` when none, at its rate
  and on every change;
- ``probabilities`` (``std_msgs/msg/Float32MultiArray``): the recogniser's newest class
  probabilities, one dimension labelled ``class``; ``class_names`` (``std_msgs/msg/String``,
  latched): the names in that order, comma-separated, once per session and on a change.

Every message is stamped with the system clock when it is sent; the frames, contacts and
tracks carry ``header.frame_id`` ``wovenskin_skin``.  Rates count on the skin's stream clock
(the tick's time), not the wall clock, so a replay played as fast as possible publishes the
same frames as in real time (the tracks too: the recogniser reads a block of frames at once,
and :meth:`~wovenskin.recognition.pipeline.LivePipeline.tracks_at` gives those after each).
The streams are best effort (:data:`~wovenskin.ros2.node.SENSOR_DATA`).  Publishing runs in
the control thread after each tick, about 0.05-0.2 ms per tick on average at the default
rates (docs/ros2.md gives the figures; :class:`PublishStats` measures every run); it never
breaks the loop: the first DDS error is reported as one line and publishing stops.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from wovenskin.ros2 import messages
from wovenskin.ros2.clock import now_ns, split_ns
from wovenskin.ros2.node import LATCHED, SENSOR_DATA, Publisher, Ros2Node
from wovenskin.runtime.ros2_settings import FRAME_ID, RATE_KEYS, TOPICS, SkinTopics

POINT_FIELDS = ("x", "y", "z", "row", "col", "size", "peak", "strength")
POINT_DTYPE = np.dtype([(name, "<f4") for name in POINT_FIELDS])
TRACK_FIELDS = ("x", "y", "z", "id", "vx", "vy", "travel", "amplitude", "merged")
TRACK_DTYPE = np.dtype(
    [(name, "<u4" if name in ("id", "merged") else "<f4") for name in TRACK_FIELDS]
)


class RateGate:
    """When a topic is due on the stream clock: every ``1 / rate_hz`` s from the first
    tick.  A tick up to ``early_s`` before its due time counts (the publisher gives half a
    frame interval, so a 200 Hz skin published at 100 Hz gives exactly every second frame
    whatever the rounding of its times); after a gap it starts again from the tick (no
    burst), and a clock that goes back (a new session, a looped replay) starts over."""

    def __init__(self, rate_hz: float, early_s: float = 0.0) -> None:
        self.period = 1.0 / rate_hz if rate_hz > 0 else 0.0
        self.early_s = min(max(0.0, early_s), 0.5 * self.period)
        self._next: float | None = None
        self._last = -np.inf

    def due(self, t: float) -> bool:
        if not self.period:
            return False
        if self._next is None or t < self._last:
            self._next = t
        self._last = t
        if t < self._next - self.early_s:
            return False
        self._next += self.period
        if self._next <= t:
            self._next = t + self.period
        return True


@dataclass
class PublishStats:
    """What was published and what it cost (perf counter, per tick of the session)."""

    counts: dict[str, int] = field(default_factory=lambda: dict.fromkeys(TOPICS, 0))
    ticks: int = 0
    total_ns: int = 0
    max_ns: int = 0

    @property
    def mean_us(self) -> float:
        """Mean cost per tick in microseconds."""
        return self.total_ns / self.ticks / 1e3 if self.ticks else 0.0

    def summary(self, settings: SkinTopics) -> str:
        sent = ", ".join(f"{self.counts[name]} {name}" for name in TOPICS if self.counts[name])
        return (
            f"ROS 2 under {settings.ns or '/'}: {sent or 'nothing'} published; "
            f"{self.mean_us:.0f} us per tick on average (max {self.max_ns / 1e3:.0f} us, "
            f"{self.ticks} ticks)"
        )


def image_message(frame: np.ndarray, stamp: messages.Time) -> messages.Image:
    """A ``32FC1`` image of a ``[row, col]`` frame (rows are image rows, unchanged)."""
    values = np.ascontiguousarray(frame, dtype="<f4")
    rows, cols = values.shape
    return messages.Image(
        header=messages.Header(stamp, FRAME_ID),
        height=rows,
        width=cols,
        encoding="32FC1",
        is_bigendian=0,
        step=4 * cols,
        data=values.tobytes(),
    )


def contact_points(contacts: list, layout: Any) -> np.ndarray:
    """The points of a frame's contacts (:data:`POINT_DTYPE`), ``x``/``y`` in metres from
    the layout's :meth:`~wovenskin.skin.layout.SkinLayout.rc_to_mm`."""
    points = np.zeros(len(contacts), dtype=POINT_DTYPE)
    if not contacts:
        return points
    for name in ("row", "col", "size", "peak", "strength"):
        points[name] = [getattr(c, name) for c in contacts]
    x_mm, y_mm = layout.rc_to_mm(points["row"].astype(float), points["col"].astype(float))
    points["x"], points["y"] = np.asarray(x_mm) / 1000.0, np.asarray(y_mm) / 1000.0
    return points


def track_points(tracks: list, layout: Any, sample_rate_hz: float) -> np.ndarray:
    """The points of the recogniser's tracks (:data:`TRACK_DTYPE`): positions (mm from the
    centre of channel ``[0, 0]``) and velocities (mm per frame) taken to channel units
    and through the layout's :meth:`~wovenskin.skin.layout.SkinLayout.rc_to_mm`, as the
    contacts; metres and metres per second."""
    points = np.zeros(len(tracks), dtype=TRACK_DTYPE)
    if not tracks:
        return points
    row = np.array([t.y for t in tracks]) / layout.row_pitch_mm
    col = np.array([t.x for t in tracks]) / layout.col_pitch_mm
    x_mm, y_mm = layout.rc_to_mm(row, col)
    d_row = np.array([t.vy for t in tracks]) / layout.row_pitch_mm  # one frame on
    d_col = np.array([t.vx for t in tracks]) / layout.col_pitch_mm
    next_x, next_y = layout.rc_to_mm(row + d_row, col + d_col)
    per_s = float(sample_rate_hz) / 1000.0
    points["x"], points["y"] = np.asarray(x_mm) / 1000.0, np.asarray(y_mm) / 1000.0
    points["vx"], points["vy"] = (next_x - x_mm) * per_s, (next_y - y_mm) * per_s
    points["id"] = [t.id for t in tracks]
    points["travel"] = [t.travel / 1000.0 for t in tracks]
    points["amplitude"] = [t.amplitude for t in tracks]
    points["merged"] = [bool(t.merged) for t in tracks]
    return points


def _point_fields(dtype: np.dtype) -> list[messages.PointField]:
    kinds = {"<f4": messages.PointField.FLOAT32, "<u4": messages.PointField.UINT32}
    return [
        messages.PointField(name, dtype.fields[name][1], kinds[dtype[name].str], 1)
        for name in dtype.names
    ]


_FIELDS = {POINT_DTYPE: _point_fields(POINT_DTYPE), TRACK_DTYPE: _point_fields(TRACK_DTYPE)}


def cloud_message(points: np.ndarray, stamp: messages.Time) -> messages.PointCloud2:
    """An unordered cloud (``height`` 1) of :data:`POINT_DTYPE` or :data:`TRACK_DTYPE` points."""
    step = points.dtype.itemsize
    return messages.PointCloud2(
        header=messages.Header(stamp, FRAME_ID),
        height=1,
        width=len(points),
        fields=list(_FIELDS[points.dtype]),
        is_bigendian=False,
        point_step=step,
        row_step=step * len(points),
        data=np.ascontiguousarray(points).tobytes(),
        is_dense=True,
    )


def probabilities_message(probabilities: np.ndarray) -> messages.Float32MultiArray:
    """One dimension labelled ``class`` of the probabilities' size."""
    values = np.asarray(probabilities, dtype=np.float32).reshape(-1)
    n = int(values.size)
    layout = messages.MultiArrayLayout([messages.MultiArrayDimension("class", n, n)], 0)
    return messages.Float32MultiArray(layout, values.tolist())


def tick_frame(session: Any) -> tuple[np.ndarray | None, list]:
    """The conditioned frame and contacts of the session's current tick: the frame of its
    ``tick_block`` at ``state.t``; the skin's newest one where the block does not hold it."""
    block = getattr(session, "tick_block", None)
    if block is not None:
        hits = np.flatnonzero(np.asarray(block.t) == session.state.t)
        if hits.size:
            k = int(hits[0])
            return block.cond.signal[k], block.cond.contacts[k]
    live = session.live_skin.state
    return live.signal, list(live.contacts)


def tick_tracks(session: Any) -> list | None:
    """The recogniser's tracks after the frame of the session's current tick (``[]`` for a
    pipeline that tracks nothing; ``None`` where it no longer holds that frame's)."""
    tracks_at = getattr(session.pipeline, "tracks_at", None)
    return [] if tracks_at is None else tracks_at(float(session.state.t))


class SkinPublisher:
    """Publishes a session's skin on ROS 2 (see the module docstring).

    ``settings`` picks the rates, the namespace and the domain; ``node`` an existing
    :class:`~wovenskin.ros2.node.Ros2Node` (default: a new one on ``settings.domain``,
    closed by :meth:`close`); ``on_message`` hears the one line of a failure, which also
    goes to the session's messages.  Pass :meth:`on_tick` to the session; one publisher
    may serve sessions one after another (the dashboard's skin or robot switches).
    """

    def __init__(
        self,
        settings: SkinTopics | None = None,
        *,
        node: Ros2Node | None = None,
        on_message: Callable[[str], None] | None = None,
    ) -> None:
        self.settings = settings or SkinTopics()
        self._own_node = node is None
        self.node = node if node is not None else Ros2Node(self.settings.domain)
        self._on_message = on_message or (lambda _line: None)
        self.writers: dict[str, Publisher] = {}
        try:
            self._make_writers()
        except BaseException:
            self.close()
            raise
        self._gates: dict[str, RateGate] = {}
        self.stats = PublishStats()
        self.failure = ""
        self._session: Any = None
        self._gesture: str | None = None
        self._class_names: tuple[str, ...] | None = None

    def _make_writers(self) -> None:
        kinds = {
            "frames": messages.Image,
            "contacts": messages.PointCloud2,
            "tracks": messages.PointCloud2,
            "gesture": messages.String,
            "probabilities": messages.Float32MultiArray,
        }
        for name, kind in kinds.items():
            if self.settings.rate(name) > 0:
                topic = self.settings.topic(name)
                self.writers[name] = self.node.publisher(topic, kind, SENSOR_DATA)
        if "probabilities" in self.writers:
            topic = self.settings.topic("class_names")
            self.writers["class_names"] = self.node.publisher(topic, messages.String, LATCHED)

    def on_tick(self, session: Any) -> None:
        """Publish what is due at the session's tick (``open_session(on_tick=...)``)."""
        if self.failure or not self.writers:
            return
        started = time.perf_counter_ns()
        try:
            self._publish(session)
        except Exception as exc:  # noqa: BLE001 - any DDS failure stops publishing, not control
            self._fail(session, exc)
        spent = time.perf_counter_ns() - started
        stats = self.stats
        stats.ticks += 1
        stats.total_ns += spent
        stats.max_ns = max(stats.max_ns, spent)

    def _publish(self, session: Any) -> None:
        if session is not self._session:
            self._session = session
            self._gesture = None
            self._class_names = None
            early = 0.5 / float(session.live_skin.info.sample_rate_hz)  # half a frame
            self._gates = {name: RateGate(self.settings.rate(name), early) for name in RATE_KEYS}
        state = session.state
        t = float(state.t)
        due = {name: gate.due(t) for name, gate in self._gates.items()}
        gesture = state.gesture or ""
        changed = "gesture" in self.writers and gesture != self._gesture
        names = "class_names" in self.writers and self._class_names is not state.class_names
        if not (any(due.values()) or changed or names):
            return
        sec, nanosec = split_ns(now_ns())
        stamp = messages.Time(sec, nanosec)
        if due["frames"] or due["contacts"]:
            frame, contacts = tick_frame(session)
            if frame is not None and due["frames"]:
                self._send("frames", image_message(frame, stamp))
            if frame is not None and due["contacts"]:
                points = contact_points(contacts, session.live_skin.info.layout)
                self._send("contacts", cloud_message(points, stamp))
        if due["tracks"] and (tracks := tick_tracks(session)) is not None:
            info = session.live_skin.info
            points = track_points(tracks, info.layout, info.sample_rate_hz)
            self._send("tracks", cloud_message(points, stamp))
        if due["gesture"] or changed:
            self._send("gesture", messages.String(gesture))
            self._gesture = gesture
        if names:
            if self._class_names != tuple(state.class_names):
                self._send("class_names", messages.String(",".join(state.class_names)))
            self._class_names = state.class_names
        if due["probabilities"] and state.probabilities is not None:
            self._send("probabilities", probabilities_message(state.probabilities))

    def _send(self, name: str, message: Any) -> None:
        self.writers[name].publish(message)
        self.stats.counts[name] += 1

    def _fail(self, session: Any, exc: Exception) -> None:
        reason = " ".join(str(exc).split()) or type(exc).__name__
        self.failure = f"ROS 2 publishing stopped: {reason}"
        session.state.messages.append(self.failure)
        self._on_message(self.failure)

    def summary(self) -> str:
        """One line: what was published and what it cost per tick (or why it stopped)."""
        line = self.stats.summary(self.settings)
        return f"{line}; {self.failure}" if self.failure else line

    def close(self) -> None:
        """Leave the ROS 2 domain (a node given to the constructor stays open)."""
        self.writers = {}
        if self._own_node:
            self.node.close()

    def __enter__(self) -> SkinPublisher:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
