"""Calling MoveIt Servo's ``~/switch_command_type`` service over Cyclone DDS.

MoveIt Servo (from MoveIt 2.10, ROS 2 Jazzy) takes one kind of command at a time and is
told which by ``moveit_msgs/srv/ServoCommandType`` on ``<servo node>/switch_command_type``.
On ``rmw_cyclonedds`` a service is a pair of topics, ``rq/<service>Request`` and
``rr/<service>Reply``, whose samples start with a request header (a 64-bit client id and a
64-bit sequence number, any unique pair) that the server copies into its reply; the client
keeps the replies that carry its own id and number (rmw_cyclonedds' ``rmw_send_request``,
``rmw_send_response``, ``rmw_take_response``). Servo answers ``success`` when the type it
now takes is the one asked for. Fast DDS's RMW carries that identity elsewhere, so the call
only reaches a Servo running on ``rmw_cyclonedds_cpp`` (topics interoperate either way).
"""

from __future__ import annotations

import secrets
import time
from typing import Any

from wovenskin.ros2 import messages
from wovenskin.ros2.node import Ros2Error

SERVICE = "switch_command_type"
DISCOVERY_POLL_S = 0.02


class ServiceError(Ros2Error):
    """The service did not answer, or refused; the message is one line."""


def switch_to_twist(node: Any, servo: str, timeout_s: float) -> None:
    """Ask the Servo node ``servo`` (``/servo_node``) to take twist commands; raises
    :class:`ServiceError` when it does not answer within ``timeout_s`` or says no."""
    service = f"{servo.rstrip('/')}/{SERVICE}"
    requests, replies = node.service_endpoints(
        service, messages.ServoCommandTypeRequest, messages.ServoCommandTypeResponse, server=False
    )
    client = secrets.randbits(63)
    deadline = time.monotonic() + timeout_s
    # rmw_cyclonedds' server answers at once when the request carries no client id in its
    # user data (as here): a reply sent before our reply reader is matched would be lost,
    # so both halves must be matched before the request goes out.
    while requests.matched() == 0 or replies.matched() == 0:
        if time.monotonic() > deadline:
            raise ServiceError(
                f"MoveIt Servo's {service} service is not there (waited {timeout_s:g} s): is "
                "Servo running, on rmw_cyclonedds_cpp? (servo= names the node; servo=none "
                "skips the call)"
            )
        time.sleep(DISCOVERY_POLL_S)
    requests.publish(
        messages.ServoCommandTypeRequest(
            client_guid=client,
            sequence_number=1,
            command_type=messages.ServoCommandTypeRequest.TWIST,
        )
    )
    while time.monotonic() < deadline:
        for reply in replies.take():
            if reply.client_guid == client and reply.sequence_number == 1:
                if not reply.success:
                    raise ServiceError(f"MoveIt Servo refused twist commands ({service})")
                return
        time.sleep(DISCOVERY_POLL_S)
    raise ServiceError(f"MoveIt Servo did not answer {service} within {timeout_s:g} s")


def serve_requests(requests: Any, replies: Any, accept: Any) -> int:
    """Answer every pending request on a server's endpoints: ``accept(command_type)``
    says whether to succeed. Returns how many were answered (for the stand-in Servo)."""
    answered = 0
    for request in requests.take():
        ok = bool(accept(int(request.command_type)))
        replies.publish(
            messages.ServoCommandTypeResponse(
                client_guid=request.client_guid,
                sequence_number=request.sequence_number,
                success=ok,
            )
        )
        answered += 1
    return answered
