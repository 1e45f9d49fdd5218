"""The ``tm:HOST[:PORT]`` robot spec: its port options, and the :class:`TechmanRobot` it builds."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Annotated

from pydantic import BeforeValidator

from wovenskin.robots.spec import Backend, Port, RobotOptions, RobotSpec, port_number
from wovenskin.robots.techman.client import TechmanRobot
from wovenskin.robots.techman.protocol import ETHERNET_SLAVE_PORT, LISTEN_NODE_PORT


@dataclass(frozen=True)
class TechmanOptions(RobotOptions):
    """``listen_port`` (default: ``HOST:PORT``'s port, else 5890) and ``state_port`` (5891)."""

    listen_port: Annotated[int | None, BeforeValidator(port_number)] = None
    state_port: Port = ETHERNET_SLAVE_PORT


def build_techman(spec: RobotSpec) -> TechmanRobot:
    """The Techman arm at the spec's host: the Listen Node's port from ``HOST:PORT`` or
    ``listen_port=`` (not both), the Ethernet Slave's from ``state_port=``."""
    assert spec.host is not None and isinstance(spec.settings, TechmanOptions)
    options = spec.settings
    if spec.port is not None and options.listen_port is not None:
        raise ValueError("gives the Listen Node port twice (HOST:PORT and listen_port=)")
    listen = options.listen_port or spec.port or LISTEN_NODE_PORT
    if listen == options.state_port:
        raise ValueError(f"uses port {listen} for both the Listen Node and the Ethernet Slave")
    return TechmanRobot(spec.host, listen, options.state_port)


TECHMAN = Backend("tm:HOST[:PORT][?listen_port=N&state_port=N]", build_techman, TechmanOptions)
