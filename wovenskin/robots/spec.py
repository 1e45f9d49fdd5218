"""Robot specs: the parsed form a backend is built from, and the option types they share.

A robot spec (``sim``, ``tm:HOST:PORT?state_port=N``, ``ur:HOST?model=ur5e``) is split by
:func:`wovenskin.specs.parse_spec` and read by :mod:`wovenskin.robots.registry` into a
:class:`RobotSpec`: host, port and the kind's options dataclass (a subclass of
:class:`RobotOptions`, declared beside the backend). A :class:`Backend` says what a kind
accepts and how its robot is built; the registry holds one per kind.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Annotated, Any

from pydantic import BeforeValidator

from wovenskin.robots.base import Robot

SAFETY_MODES = ("full", "degraded")


def port_number(value: object) -> int:
    """A TCP port, 1-65535, from its text (or an int); else ``ValueError("bad port ...")``."""
    text = str(value).strip()
    if not text.isdigit() or not 0 < int(text) < 65536:
        raise ValueError(f"bad port {text!r}")
    return int(text)


def safety_mode(value: object) -> str:
    """``full`` (the default) or ``degraded``, in any case."""
    mode = str(value).strip().lower()
    if mode not in SAFETY_MODES:
        raise ValueError(f"unknown safety mode {value!r} (full or degraded)")
    return mode


Port = Annotated[int, BeforeValidator(port_number)]
SafetyMode = Annotated[str, BeforeValidator(safety_mode)]


@dataclass(frozen=True)
class RobotOptions:
    """The options every robot spec takes; a backend's options dataclass derives from it.

    ``safety=degraded`` is the user's opt-in to run an arm whose declaration lacks what the
    safety layer's full checks need (see :class:`wovenskin.control.safety.SafetyLayer`).
    """

    safety: SafetyMode = "full"


@dataclass(frozen=True)
class RobotSpec:
    """A parsed, validated robot spec."""

    text: str  # as given, stripped
    kind: str  # a key of the registry: "sim", "tm", "ur"
    host: str | None = None
    port: int | None = None
    options: Mapping[str, Any] = field(default_factory=dict)  # the options given, parsed
    settings: RobotOptions = field(default_factory=RobotOptions)  # all options, defaults too

    @property
    def degraded_safety(self) -> bool:
        """Whether the spec opts into the safety layer's degraded mode (``safety=degraded``)."""
        return self.settings.safety == "degraded"


@dataclass(frozen=True)
class Backend:
    """One kind of robot spec: its form, its options and how its robot is built.

    ``build`` gets the parsed spec (its ``settings`` an instance of ``options``) and
    returns the robot, not yet connected; a ``ValueError`` it raises becomes one line
    completing "robot spec 'X' ...".  ``port`` says why ``HOST:PORT`` is refused, or is
    ``None`` when the kind takes one.
    """

    form: str  # the spec's form for messages: "tm:HOST[:PORT][?listen_port=N&state_port=N]"
    build: Callable[[RobotSpec], Robot]
    options: type[RobotOptions] = RobotOptions
    address: bool = True  # "kind:HOST..." (True) or the bare kind (False)
    colon_optional: bool = False  # the bare kind also as "kind:?options" (ros2:?twist=/x)
    port: str | None = None
