"""ROS 2 without a ROS install: message types, DDS entities and topic names.

ROS 2 speaks DDS on the wire. :mod:`.messages` defines the ROS 2 messages wovenskin sends
and receives, once, as Cyclone DDS types with their ROS names; :mod:`.node` opens a DDS
participant that behaves like a ROS 2 node on ``rmw_cyclonedds`` (topic names, type names,
QoS, XCDR1 encoding, the domain id); :mod:`.clock` stamps messages. Everything here needs the
optional ``wovenskin[ros2]`` extra (``cyclonedds``); importing this package does not.
"""
