"""The ROS 2 messages wovenskin sends are byte for byte what ROS 2 sends.

Each class in :mod:`wovenskin.ros2.messages` is checked against ``rosbags``' own definition
of the same interface (an independent transcription of ros2/common_interfaces, with its own
CDR serialiser): the same fields in the same order with the same types, and the same XCDR1
bytes for random values, both ways.
"""

from __future__ import annotations

import typing

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

pytest.importorskip("cyclonedds", reason="needs wovenskin[ros2]")
from rosbags.typesys import Stores, get_types_from_msg, get_typestore  # noqa: E402

from wovenskin.ros2 import messages  # noqa: E402

TYPESTORE = get_typestore(Stores.ROS2_JAZZY)
# moveit_msgs is not in rosbags' Jazzy store: its .srv, as moveit/moveit_msgs writes it
SERVO_SRV = {
    "moveit_msgs/srv/ServoCommandType_Request": (
        "int8 JOINT_JOG = 0\nint8 TWIST = 1\nint8 POSE = 2\nint8 command_type"
    ),
    "moveit_msgs/srv/ServoCommandType_Response": "bool success",
}
for _name, _definition in SERVO_SRV.items():  # rosbags names a .msg's type pkg/msg/Name
    TYPESTORE.register({_name: next(iter(get_types_from_msg(_definition, _name).values()))})

# rosbags' base type names -> the Cyclone DDS IDL annotation of the same type
IDL = {
    "int8": "int8", "uint8": "uint8", "int32": "int32", "uint32": "uint32", "int64": "int64",
    "uint64": "uint64", "float32": "float32", "float64": "float64", "string": "str",
    "bool": "bool",
}  # fmt: skip


def _rosbags_fields(ros_name: str) -> list[tuple[str, str]]:
    """(name, type) of each field as rosbags defines the message; types as IDL names."""
    out = []
    for name, (kind, detail) in TYPESTORE.fielddefs[ros_name][1]:
        if kind.name == "BASE":
            out.append((name, IDL[detail[0]]))
        elif kind.name == "NAME":
            out.append((name, detail))
        else:  # a sequence
            (inner_kind, inner), _bound = detail
            inner_name = IDL[inner[0]] if inner_kind.name == "BASE" else inner
            out.append((name, f"sequence[{inner_name}]"))
    return out


def _idl_name(hint) -> str:
    """The IDL name of a Cyclone DDS field annotation (``int32``, ``sequence[float64]``, a
    nested message's ROS name)."""
    if isinstance(hint, type) and issubclass(hint, messages.IdlStruct):
        return hint.ros_name
    if hint is bytes:  # a uint8[] field: the same bytes on the wire
        return "sequence[uint8]"
    if hint in (str, bool):
        return hint.__name__
    args = typing.get_args(hint)
    if len(args) == 2 and isinstance(args[1], str):  # Annotated[int, "int32"]
        return args[1]
    inner = typing.get_args(args[0])[0]  # Annotated[Sequence[X], sequence[X]]
    return f"sequence[{_idl_name(inner)}]"


def _our_fields(cls: type) -> list[tuple[str, str]]:
    hints = typing.get_type_hints(cls, include_extras=True)
    return [(name, _idl_name(hint)) for name, hint in hints.items()]


@pytest.mark.parametrize("cls", messages.MESSAGES, ids=lambda c: c.ros_name)
def test_every_message_has_the_fields_of_its_ros_definition(cls):
    assert cls.ros_name in TYPESTORE.fielddefs
    assert _our_fields(cls) == _rosbags_fields(cls.ros_name)
    package, kind, name = cls.ros_name.split("/")
    assert cls.__idl_typename__ == f"{package}::{kind}::dds_::{name}_"


@pytest.mark.parametrize(
    "cls", [messages.ServoCommandTypeRequest, messages.ServoCommandTypeResponse], ids=str
)
def test_service_types_are_the_rmw_header_then_the_ros_fields(cls):
    ours = _our_fields(cls)
    assert ours[:2] == [("client_guid", "uint64"), ("sequence_number", "int64")]
    assert ours[2:] == _rosbags_fields(cls.ros_name)
    package, _, name = cls.ros_name.split("/")
    assert cls.__idl_typename__ == f"{package}::srv::dds_::{name}_"


def _rosbags_message(value, ros_name: str):
    """The rosbags message with the same values as our message ``value``."""
    fields = []
    for name, (kind, detail) in TYPESTORE.fielddefs[ros_name][1]:
        field_value = getattr(value, name)
        if kind.name == "NAME":
            field_value = _rosbags_message(field_value, detail)
        elif kind.name == "SEQUENCE":
            (inner_kind, inner), _ = detail
            if inner_kind.name == "NAME":
                field_value = [_rosbags_message(v, inner) for v in field_value]
            elif inner[0] == "uint8":
                field_value = np.frombuffer(field_value, dtype=np.uint8)
            elif inner[0] != "string":
                field_value = np.array(
                    field_value, dtype={"float32": np.float32}.get(inner[0], np.float64)
                )
        fields.append(field_value)
    return TYPESTORE.types[ros_name](*fields)


finite64 = st.floats(allow_nan=False, width=64)
finite32 = st.floats(allow_nan=False, width=32)
text = st.text(max_size=12)
stamp = st.builds(messages.Time, st.integers(-(2**31), 2**31 - 1), st.integers(0, 2**32 - 1))
header = st.builds(messages.Header, stamp, text)
vector = st.builds(messages.Vector3, finite64, finite64, finite64)
twist = st.builds(messages.Twist, vector, vector)
floats = st.lists(finite64, max_size=7)
dimension = st.builds(messages.MultiArrayDimension, text, st.integers(0, 2**32 - 1),
                      st.integers(0, 2**32 - 1))  # fmt: skip
point_field = st.builds(messages.PointField, text, st.integers(0, 2**32 - 1),
                        st.integers(0, 255), st.integers(0, 2**32 - 1))  # fmt: skip

SAMPLES = {
    messages.Time: stamp,
    messages.Header: header,
    messages.String: st.builds(messages.String, text),
    messages.MultiArrayDimension: dimension,
    messages.MultiArrayLayout: st.builds(messages.MultiArrayLayout, st.lists(dimension, max_size=3),
                                         st.integers(0, 2**32 - 1)),
    messages.Float32MultiArray: st.builds(
        messages.Float32MultiArray,
        st.builds(messages.MultiArrayLayout, st.lists(dimension, max_size=2)),
        st.lists(finite32, max_size=15),
    ),
    messages.Vector3: vector,
    messages.Twist: twist,
    messages.TwistStamped: st.builds(messages.TwistStamped, header, twist),
    messages.JointState: st.builds(messages.JointState, header, st.lists(text, max_size=7),
                                   floats, floats, floats),
    messages.Image: st.builds(messages.Image, header, st.integers(0, 2**32 - 1),
                              st.integers(0, 2**32 - 1), text, st.integers(0, 255),
                              st.integers(0, 2**32 - 1), st.binary(max_size=64)),
    messages.PointField: point_field,
    messages.PointCloud2: st.builds(messages.PointCloud2, header, st.integers(0, 2**32 - 1),
                                    st.integers(0, 2**32 - 1), st.lists(point_field, max_size=3),
                                    st.booleans(), st.integers(0, 2**32 - 1),
                                    st.integers(0, 2**32 - 1), st.binary(max_size=64),
                                    st.booleans()),
}  # fmt: skip


def test_every_message_has_samples():
    assert set(SAMPLES) == set(messages.MESSAGES)


@pytest.mark.parametrize("cls", messages.MESSAGES, ids=lambda c: c.ros_name)
@given(data=st.data())
def test_xcdr1_bytes_equal_rosbags_both_ways(cls, data):
    value = data.draw(SAMPLES[cls])
    ours = value.serialize(use_version_2=False)
    theirs = bytes(TYPESTORE.serialize_cdr(_rosbags_message(value, cls.ros_name), cls.ros_name))
    assert ours == theirs
    assert cls.deserialize(theirs).serialize(use_version_2=False) == ours
    back = TYPESTORE.deserialize_cdr(ours, cls.ros_name)
    assert bytes(TYPESTORE.serialize_cdr(back, cls.ros_name)) == ours


@given(st.integers(0, 2**64 - 1), st.integers(-(2**63), 2**63 - 1), st.sampled_from([0, 1, 2]))
def test_a_servo_request_is_the_cyclone_header_then_the_ros_request(guid, seq, command):
    ours = messages.ServoCommandTypeRequest(guid, seq, command).serialize(use_version_2=False)
    request = TYPESTORE.types["moveit_msgs/srv/ServoCommandType_Request"](command)
    body = bytes(TYPESTORE.serialize_cdr(request, "moveit_msgs/srv/ServoCommandType_Request"))
    header = guid.to_bytes(8, "little") + seq.to_bytes(8, "little", signed=True)
    # rmw_cyclonedds: encapsulation, then guid and sequence number, then the request; the
    # request's own alignment restarts nowhere (16 bytes keep every alignment)
    assert ours == body[:4] + header + body[4:]
