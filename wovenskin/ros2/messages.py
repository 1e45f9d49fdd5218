"""The ROS 2 messages wovenskin speaks, defined once, as Cyclone DDS types with ROS names.

Each class transcribes one ROS 2 interface (the ``.msg``/``.srv`` files of
ros2/rcl_interfaces ``builtin_interfaces``, ros2/common_interfaces ``std_msgs``,
``geometry_msgs`` and ``sensor_msgs``, and moveit/moveit_msgs) field for field, in order,
with the IDL types rosidl generates for them; its ``typename`` is the DDS type name ROS 2
gives it (``pkg::msg::dds_::Name_``). The CDR bytes they make (XCDR1, the only encoding
ROS 2 matches) are checked against the independent serialiser of ``rosbags`` in the tests,
message by message and field by field.

Class attributes without annotations (``ros_name``, a message's constants) are not fields.
``uint8[]`` fields are ``sequence[uint8]``, as rosidl declares them (Cyclone's type builder
has no type object for a plain ``bytes`` field, so a topic of such a type cannot be made);
they take :class:`bytes` when sent and come back as lists of ints when received.

Services on ``rmw_cyclonedds`` put a request header (the client's 8-byte GUID prefix hash
and a sequence number) before the request's fields and before the reply's: the service
types here carry those two fields first, as the RMW writes them.
"""

# No ``from __future__ import annotations``: Cyclone DDS reads the field types at run time.
from dataclasses import dataclass, field

import cyclonedds.idl.annotations as annotate
from cyclonedds.idl import IdlStruct
from cyclonedds.idl.types import (
    float32,
    float64,
    int8,
    int32,
    int64,
    sequence,
    uint8,
    uint32,
    uint64,
)

# -- builtin_interfaces, std_msgs --------------------------------------------------------


@dataclass
@annotate.final
class Time(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    """``builtin_interfaces/msg/Time``: seconds and nanoseconds since the epoch."""

    ros_name = "builtin_interfaces/msg/Time"
    sec: int32 = 0
    nanosec: uint32 = 0


@dataclass
@annotate.final
class Header(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
    """``std_msgs/msg/Header``: a stamp and the frame the data is expressed in."""

    ros_name = "std_msgs/msg/Header"
    stamp: Time = field(default_factory=Time)
    frame_id: str = ""


@dataclass
@annotate.final
class String(IdlStruct, typename="std_msgs::msg::dds_::String_"):
    """``std_msgs/msg/String``."""

    ros_name = "std_msgs/msg/String"
    data: str = ""


@dataclass
@annotate.final
class MultiArrayDimension(IdlStruct, typename="std_msgs::msg::dds_::MultiArrayDimension_"):
    """``std_msgs/msg/MultiArrayDimension``: one dimension's label, size and stride."""

    ros_name = "std_msgs/msg/MultiArrayDimension"
    label: str = ""
    size: uint32 = 0
    stride: uint32 = 0


@dataclass
@annotate.final
class MultiArrayLayout(IdlStruct, typename="std_msgs::msg::dds_::MultiArrayLayout_"):
    """``std_msgs/msg/MultiArrayLayout``."""

    ros_name = "std_msgs/msg/MultiArrayLayout"
    dim: sequence[MultiArrayDimension] = field(default_factory=list)
    data_offset: uint32 = 0


@dataclass
@annotate.final
class Float32MultiArray(IdlStruct, typename="std_msgs::msg::dds_::Float32MultiArray_"):
    """``std_msgs/msg/Float32MultiArray``."""

    ros_name = "std_msgs/msg/Float32MultiArray"
    layout: MultiArrayLayout = field(default_factory=MultiArrayLayout)
    data: sequence[float32] = field(default_factory=list)


# -- geometry_msgs -----------------------------------------------------------------------


@dataclass
@annotate.final
class Vector3(IdlStruct, typename="geometry_msgs::msg::dds_::Vector3_"):
    """``geometry_msgs/msg/Vector3``."""

    ros_name = "geometry_msgs/msg/Vector3"
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0


@dataclass
@annotate.final
class Twist(IdlStruct, typename="geometry_msgs::msg::dds_::Twist_"):
    """``geometry_msgs/msg/Twist``: linear (m/s) and angular (rad/s) velocity."""

    ros_name = "geometry_msgs/msg/Twist"
    linear: Vector3 = field(default_factory=Vector3)
    angular: Vector3 = field(default_factory=Vector3)


@dataclass
@annotate.final
class TwistStamped(IdlStruct, typename="geometry_msgs::msg::dds_::TwistStamped_"):
    """``geometry_msgs/msg/TwistStamped``: MoveIt Servo's Cartesian command."""

    ros_name = "geometry_msgs/msg/TwistStamped"
    header: Header = field(default_factory=Header)
    twist: Twist = field(default_factory=Twist)


# -- sensor_msgs -------------------------------------------------------------------------


@dataclass
@annotate.final
class JointState(IdlStruct, typename="sensor_msgs::msg::dds_::JointState_"):
    """``sensor_msgs/msg/JointState``: joints by name; empty arrays where not measured."""

    ros_name = "sensor_msgs/msg/JointState"
    header: Header = field(default_factory=Header)
    name: sequence[str] = field(default_factory=list)
    position: sequence[float64] = field(default_factory=list)
    velocity: sequence[float64] = field(default_factory=list)
    effort: sequence[float64] = field(default_factory=list)


@dataclass
@annotate.final
class Image(IdlStruct, typename="sensor_msgs::msg::dds_::Image_"):
    """``sensor_msgs/msg/Image``: ``height`` rows of ``step`` bytes in ``encoding``."""

    ros_name = "sensor_msgs/msg/Image"
    header: Header = field(default_factory=Header)
    height: uint32 = 0
    width: uint32 = 0
    encoding: str = ""
    is_bigendian: uint8 = 0
    step: uint32 = 0
    data: sequence[uint8] = b""


@dataclass
@annotate.final
class PointField(IdlStruct, typename="sensor_msgs::msg::dds_::PointField_"):
    """``sensor_msgs/msg/PointField``: one named field of a point cloud's points."""

    ros_name = "sensor_msgs/msg/PointField"
    UINT32 = 6  # the datatype constant of a 32-bit unsigned integer
    FLOAT32 = 7  # the datatype constant of a 32-bit float
    name: str = ""
    offset: uint32 = 0
    datatype: uint8 = 0
    count: uint32 = 0


@dataclass
@annotate.final
class PointCloud2(IdlStruct, typename="sensor_msgs::msg::dds_::PointCloud2_"):
    """``sensor_msgs/msg/PointCloud2``: ``width`` points of ``point_step`` bytes each."""

    ros_name = "sensor_msgs/msg/PointCloud2"
    header: Header = field(default_factory=Header)
    height: uint32 = 0
    width: uint32 = 0
    fields: sequence[PointField] = field(default_factory=list)
    is_bigendian: bool = False
    point_step: uint32 = 0
    row_step: uint32 = 0
    data: sequence[uint8] = b""
    is_dense: bool = False


# -- moveit_msgs/srv/ServoCommandType (MoveIt Servo's ~/switch_command_type) --------------


@dataclass
@annotate.final
class ServoCommandTypeRequest(
    IdlStruct, typename="moveit_msgs::srv::dds_::ServoCommandType_Request_"
):
    """``moveit_msgs/srv/ServoCommandType`` request, after rmw_cyclonedds' request header."""

    ros_name = "moveit_msgs/srv/ServoCommandType_Request"
    JOINT_JOG = 0
    TWIST = 1
    POSE = 2
    client_guid: uint64 = 0  # rmw_cyclonedds' request header
    sequence_number: int64 = 0
    command_type: int8 = 0


@dataclass
@annotate.final
class ServoCommandTypeResponse(
    IdlStruct, typename="moveit_msgs::srv::dds_::ServoCommandType_Response_"
):
    """``moveit_msgs/srv/ServoCommandType`` response, after rmw_cyclonedds' request header."""

    ros_name = "moveit_msgs/srv/ServoCommandType_Response"
    client_guid: uint64 = 0  # the request's header, echoed: the client matches on it
    sequence_number: int64 = 0
    success: bool = False


MESSAGES: tuple[type[IdlStruct], ...] = (
    Time, Header, String, MultiArrayDimension, MultiArrayLayout, Float32MultiArray, Vector3,
    Twist, TwistStamped, JointState, Image, PointField, PointCloud2,
)  # fmt: skip
"""Every topic message above (the service types carry the RMW's header, not plain fields)."""
