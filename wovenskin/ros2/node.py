"""A DDS participant that talks to ROS 2 nodes as ``rmw_cyclonedds`` does.

ROS 2 maps its graph onto DDS: a topic ``/a/b`` is the DDS topic ``rt/a/b``, a message
``pkg/msg/Name`` the DDS type ``pkg::msg::dds_::Name_`` (the ``typename`` of each class in
:mod:`.messages`), the ROS domain id (``ROS_DOMAIN_ID``) the DDS domain id, and samples are
XCDR1-encoded: a reader or writer that offers only XCDR2 matches no ROS 2 endpoint, so every
endpoint here declares XCDR1 in its data-representation QoS. A service ``/a/srv`` is the
request topic ``rq/a/srvRequest`` and the reply topic ``rr/a/srvReply``.

Cyclone DDS reads its own configuration from ``CYCLONEDDS_URI`` (an XML file or inline XML):
that is where a user confines discovery to one interface or to loopback; nothing here
overrides it. :func:`loopback_config` writes such a file for tests and benchmarks.

:class:`Ros2Node` owns one participant and the endpoints made from it; :class:`Publisher`
and :class:`Subscription` are thin, typed wrappers. ``cyclonedds`` is imported when a node
is made, so a user without the ``wovenskin[ros2]`` extra gets one line, not a traceback.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from wovenskin.errors import ConfigError, DeviceError, MissingExtraError

DOMAIN_ENV = "ROS_DOMAIN_ID"
MAX_DOMAIN_ID = 232  # DDS's port mapping: domain ids 0-232 (ROS 2 recommends 0-101)


class Ros2Error(DeviceError):
    """The DDS layer failed (no ``cyclonedds``, a bad Cyclone configuration, a bad topic
    name); the message is one line."""


@dataclass(frozen=True)
class QosProfile:
    """The QoS of one endpoint, in ROS 2's terms (``rclcpp::QoS``): history depth,
    reliability and durability. Every profile declares XCDR1 only."""

    depth: int = 10
    reliable: bool = True
    transient_local: bool = False


COMMANDS = QosProfile(depth=10, reliable=True)
"""Commands to a controller (MoveIt Servo's twist subscription): reliable, volatile,
keep last 10, rclcpp's default; a reliable writer also matches best-effort readers."""

SENSOR_DATA = QosProfile(depth=5, reliable=False)
"""Sensor streams read or published here (joint states, skin frames): best effort, so a
reader matches both reliable and best-effort publishers and never stalls a writer."""

LATCHED = QosProfile(depth=1, reliable=True, transient_local=True)
"""Rarely changing facts (the class names of the probabilities): a late joiner gets the
last one, as ``rclcpp``'s transient-local QoS gives it."""


def domain_id(value: int | str | None = None) -> int:
    """The DDS domain id: ``value``, else ``ROS_DOMAIN_ID``, else 0; a bad one is one line."""
    if value is None or value == "":
        value = os.environ.get(DOMAIN_ENV, "").strip() or 0
    text = str(value).strip()
    if not text.isdigit() or int(text) > MAX_DOMAIN_ID:
        raise ConfigError(f"ROS 2 domain id must be 0-{MAX_DOMAIN_ID}, got {value!r}")
    return int(text)


def dds_topic_name(ros_name: str, kind: str = "rt") -> str:
    """The DDS topic of a fully qualified ROS 2 topic name (``/a/b`` -> ``rt/a/b``);
    ``kind`` ``rq``/``rr`` for a service's request/reply (their suffix is the caller's)."""
    name = ros_name.strip()
    parts = name.split("/")
    valid = (
        name.startswith("/")
        and len(name) > 1
        and not name.endswith("/")
        and all(part and (part[0].isalpha() or part[0] == "_") for part in parts[1:])
        and all(c.isalnum() or c in "_/" for c in name)
    )
    if not valid:
        raise ConfigError(
            f"{ros_name!r} is not a fully qualified ROS 2 name (/name/of/topic: letters, "
            "digits and _, each part starting with a letter or _)"
        )
    return kind + name


def _cyclonedds() -> Any:
    try:
        import cyclonedds.domain
        import cyclonedds.pub
        import cyclonedds.qos
        import cyclonedds.sub
        import cyclonedds.topic
        import cyclonedds.util
    except ImportError:
        raise MissingExtraError(
            "ROS 2 needs the cyclonedds package: install wovenskin[ros2]"
        ) from None
    return cyclonedds


def _qos(profile: QosProfile) -> Any:
    dds = _cyclonedds()
    policy = dds.qos.Policy
    reliability = (
        policy.Reliability.Reliable(dds.util.duration(milliseconds=100))
        if profile.reliable
        else policy.Reliability.BestEffort
    )
    durability = (
        policy.Durability.TransientLocal if profile.transient_local else policy.Durability.Volatile
    )
    return dds.qos.Qos(
        reliability,
        durability,
        policy.History.KeepLast(profile.depth),
        policy.DataRepresentation(use_cdrv0_representation=True),
    )


class Publisher:
    """A typed DDS writer on one ROS 2 topic."""

    def __init__(self, writer: Any, message_type: type, ros_name: str) -> None:
        self._writer = writer
        self.message_type = message_type
        self.ros_name = ros_name

    def publish(self, message: Any) -> None:
        """Send one message (never blocks longer than the reliable QoS's 100 ms)."""
        if not isinstance(message, self.message_type):
            raise TypeError(f"{self.ros_name} carries {self.message_type.__name__}")
        self._writer.write(message)

    def matched(self) -> int:
        """How many readers (ROS 2 subscriptions) this writer has matched."""
        return len(self._writer.get_matched_subscriptions())


class Subscription:
    """A typed DDS reader on one ROS 2 topic; :meth:`take` polls without blocking."""

    def __init__(self, reader: Any, message_type: type, ros_name: str) -> None:
        self._reader = reader
        self.message_type = message_type
        self.ros_name = ros_name
        self._waitset: Any = None

    def wait(self, timeout_s: float) -> bool:
        """Block until a message not yet taken is there (True) or ``timeout_s`` passes."""
        if self._waitset is None:
            from cyclonedds.core import (
                InstanceState,
                ReadCondition,
                SampleState,
                ViewState,
                WaitSet,
            )

            self._waitset = WaitSet(self._reader.participant)
            mask = ViewState.Any | InstanceState.Any | SampleState.NotRead
            self._waitset.attach(ReadCondition(self._reader, mask))
        return self._waitset.wait(max(1, int(timeout_s * 1e9))) > 0

    def matched(self) -> int:
        """How many writers (ROS 2 publishers) this reader has matched."""
        return len(self._reader.get_matched_publications())

    def take(self, limit: int = 256) -> list[Any]:
        """The messages received since the last call, oldest first (at most ``limit``)."""
        return [s for s in self._reader.take(N=limit) if s.sample_info.valid_data]

    def take_serialized(self, limit: int = 256) -> list[tuple[bytes, int]]:
        """The messages received since the last call as their CDR bytes, encapsulation
        header included, each with its source timestamp (ns, the writer's clock)."""
        from cyclonedds._clayer import ddspy_take
        from cyclonedds.core import InstanceState, SampleState, ViewState

        mask = SampleState.Any | ViewState.Any | InstanceState.Any
        taken = ddspy_take(self._reader._ref, mask, limit)
        if isinstance(taken, int):
            raise Ros2Error(f"reading {self.ros_name} failed (DDS error {taken})")
        return [
            (bytes(data), int(info.source_timestamp)) for data, info in taken if info.valid_data
        ]


class Ros2Node:
    """One DDS participant in a ROS 2 domain, and the endpoints it makes.

    ``domain`` is the ROS domain id (default: ``ROS_DOMAIN_ID``, else 0). Cyclone's own
    configuration comes from ``CYCLONEDDS_URI`` when set, as for any ROS 2 process on
    ``rmw_cyclonedds``. Close it (or use it as a context manager) to leave the domain.
    """

    def __init__(self, domain: int | str | None = None) -> None:
        dds = _cyclonedds()
        self.domain_id = domain_id(domain)
        try:
            self._participant = dds.domain.DomainParticipant(self.domain_id)
        except Exception as exc:  # a bad CYCLONEDDS_URI, no usable interface
            reason = " ".join(str(exc).split()) or type(exc).__name__
            uri = os.environ.get("CYCLONEDDS_URI")
            where = f" (CYCLONEDDS_URI={uri})" if uri else ""
            raise Ros2Error(f"cannot join ROS 2 domain {self.domain_id}{where}: {reason}") from None
        self._topics: dict[str, Any] = {}
        self._entities: list[Any] = []

    def _topic(self, dds_name: str, message_type: type) -> Any:
        dds = _cyclonedds()
        topic = self._topics.get(dds_name)
        if topic is None:
            topic = dds.topic.Topic(self._participant, dds_name, message_type)
            self._topics[dds_name] = topic
        elif topic.data_type is not message_type:
            raise Ros2Error(f"{dds_name} is already used with another message type")
        return topic

    def _endpoint(
        self, writes: bool, dds_name: str, message_type: type, qos: QosProfile, ros_name: str
    ) -> Any:
        """A :class:`Publisher` (``writes``) or :class:`Subscription` on a DDS topic."""
        dds = _cyclonedds()
        topic = self._topic(dds_name, message_type)
        make, wrap = (
            (dds.pub.DataWriter, Publisher) if writes else (dds.sub.DataReader, Subscription)
        )
        entity = make(self._participant, topic, qos=_qos(qos))
        self._entities.append(entity)
        return wrap(entity, message_type, ros_name)

    def publisher(self, ros_name: str, message_type: type, qos: QosProfile = COMMANDS) -> Publisher:
        """A writer of ``message_type`` on the ROS 2 topic ``ros_name`` (``/a/b``)."""
        return self._endpoint(True, dds_topic_name(ros_name), message_type, qos, ros_name)

    def subscription(
        self, ros_name: str, message_type: type, qos: QosProfile = SENSOR_DATA
    ) -> Subscription:
        """A reader of ``message_type`` on the ROS 2 topic ``ros_name`` (``/a/b``)."""
        return self._endpoint(False, dds_topic_name(ros_name), message_type, qos, ros_name)

    def service_endpoints(
        self, service: str, request_type: type, response_type: type, *, server: bool
    ) -> tuple[Any, Any]:
        """The request and reply endpoints of the ROS 2 service ``service``: a client gets
        (request :class:`Publisher`, reply :class:`Subscription`), a server the reverse.
        QoS: ROS 2's services default, reliable, volatile, keep last 10."""
        request = (dds_topic_name(service, "rq") + "Request", request_type, COMMANDS, service)
        reply = (dds_topic_name(service, "rr") + "Reply", response_type, COMMANDS, service)
        return self._endpoint(not server, *request), self._endpoint(server, *reply)

    @property
    def guid_prefix(self) -> bytes:
        """The participant's GUID (16 bytes), which ROS 2 clients derive request ids from."""
        return bytes(self._participant.guid.bytes)

    def close(self) -> None:
        """Leave the domain: every endpoint made here goes with the participant."""
        participant, self._participant = self._participant, None
        self._entities.clear()
        self._topics.clear()
        if participant is not None:
            del participant

    def __enter__(self) -> Ros2Node:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def loopback_config(path: str | os.PathLike, max_participants: int = 32) -> Path:
    """Write a Cyclone DDS configuration that keeps discovery on this machine: the
    loopback interface, no multicast, unicast discovery to 127.0.0.1 on the first
    ``max_participants`` participant indices. Point ``CYCLONEDDS_URI`` at the file
    (``file://`` + its path)."""
    target = Path(path)
    target.write_text(
        '<?xml version="1.0" encoding="UTF-8" ?>\n'
        '<CycloneDDS xmlns="https://cdds.io/config">\n'
        '  <Domain Id="any">\n'
        "    <General>\n"
        '      <Interfaces><NetworkInterface name="lo" /></Interfaces>\n'
        "      <AllowMulticast>false</AllowMulticast>\n"
        "    </General>\n"
        "    <Discovery>\n"
        "      <ParticipantIndex>auto</ParticipantIndex>\n"
        f"      <MaxAutoParticipantIndex>{int(max_participants)}</MaxAutoParticipantIndex>\n"
        '      <Peers><Peer address="127.0.0.1" /></Peers>\n'
        "    </Discovery>\n"
        "  </Domain>\n"
        "</CycloneDDS>\n",
        encoding="utf-8",
    )
    return target
