"""Robot specs: parsed and validated here, and nowhere else, then built by :func:`make_robot`.

A spec names a backend and its address: ``sim``, ``tm:HOST[:PORT]`` (ports also as
``tm:HOST?listen_port=5890&state_port=5891``) or
``ur:HOST[?model=ur5e]`` (the UR model: ``ur3e``, ``ur5e``, ``ur10e``, ``ur16e``). Options
follow a ``?``, joined by ``&``. Every kind also takes ``safety=degraded``: the user's
opt-in to run an arm whose declaration lacks what the safety layer's full checks need (see
:class:`wovenskin.control.safety.SafetyLayer` and ``docs/safety.md``).

:func:`parse_robot_spec` checks a spec without building anything; every problem is one
``ValueError`` line that lists the valid forms. To give a kind a new option, add its
parser to that kind's :class:`SpecForm` in :data:`SPEC_FORMS` and read it in the kind's
builder (``spec.options[name]`` holds the parsed value).

Backends are imported only when their spec is used, so a missing optional package or an
unfinished backend never breaks the others.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

from wovenskin.robots.base import Robot

VALID_SPECS = "sim, tm:HOST[:PORT][?listen_port=N&state_port=N], ur:HOST[?model=ur5e]"
SAFETY_MODES = ("full", "degraded")


@dataclass(frozen=True)
class RobotSpec:
    """A parsed, validated robot spec."""

    text: str  # as given
    kind: str  # "sim", "tm" or "ur"
    host: str | None = None
    port: int | None = None
    options: Mapping[str, Any] = field(default_factory=dict)  # parsed option values

    @property
    def degraded_safety(self) -> bool:
        """Whether the spec opts into the safety layer's degraded mode (``safety=degraded``)."""
        return self.options.get("safety") == "degraded"


class SpecError(ValueError):
    """A robot spec that cannot be used; the message is one line and lists the valid forms."""

    def __init__(self, spec: str, why: str) -> None:
        super().__init__(f"robot spec {spec!r} {why}; valid forms: {VALID_SPECS}")


# -- option parsers: text -> value, or a ValueError that completes "robot spec 'X' ..."


def port_option(text: str) -> int:
    """A TCP port, 1-65535."""
    if not text.isdigit() or not 0 < int(text) < 65536:
        raise ValueError(f"has a bad port {text!r}")
    return int(text)


def safety_option(text: str) -> str:
    """``full`` (the default) or ``degraded``."""
    mode = text.lower()
    if mode not in SAFETY_MODES:
        raise ValueError(f"has an unknown safety mode {text!r} (full or degraded)")
    return mode


def ur_model_option(text: str) -> str:
    """A known UR model name (checked against :mod:`wovenskin.robots.ur.models`)."""
    from wovenskin.robots.ur.models import ur_model

    try:
        return ur_model(text.lower()).name
    except ValueError as exc:
        raise ValueError(f"names {exc}") from None


COMMON_OPTIONS: dict[str, Callable[[str], Any]] = {"safety": safety_option}


@dataclass(frozen=True)
class SpecForm:
    """What one kind of spec takes, and how its backend is built."""

    build: Callable[[RobotSpec], Robot]
    address: bool  # "kind:HOST..." (True) or the bare kind (False)
    port: str | None = None  # why a port is refused, or None when ``HOST:PORT`` is allowed
    options: Mapping[str, Callable[[str], Any]] = field(default_factory=dict)


def _build_sim(spec: RobotSpec) -> Robot:
    from wovenskin.robots.sim import SimRobot

    return SimRobot()


def _build_tm(spec: RobotSpec) -> Robot:
    """``tm:HOST``: Listen Node 5890, Ethernet Slave 5891; ``tm:HOST:PORT`` sets the Listen
    Node's port; ``?listen_port=N&state_port=N`` set either or both."""
    from wovenskin.robots.techman import TechmanRobot
    from wovenskin.robots.techman.protocol import ETHERNET_SLAVE_PORT, LISTEN_NODE_PORT

    assert spec.host is not None
    if spec.port is not None and "listen_port" in spec.options:
        raise ValueError("gives the Listen Node port twice (HOST:PORT and listen_port=)")
    listen = spec.options.get("listen_port", spec.port or LISTEN_NODE_PORT)
    state = spec.options.get("state_port", ETHERNET_SLAVE_PORT)
    if listen == state:
        raise ValueError(f"uses port {listen} for both the Listen Node and the Ethernet Slave")
    return TechmanRobot(spec.host, listen, state)


def _build_ur(spec: RobotSpec) -> Robot:
    from wovenskin.robots.ur import URRobot

    assert spec.host is not None
    return URRobot(spec.host, model=spec.options.get("model"))


SPEC_FORMS: dict[str, SpecForm] = {
    "sim": SpecForm(_build_sim, address=False),
    "tm": SpecForm(
        _build_tm,
        address=True,
        options={"listen_port": port_option, "state_port": port_option},
    ),
    "ur": SpecForm(
        _build_ur,
        address=True,
        port="gives a port, but ur_rtde uses the robot's fixed RTDE port",
        options={"model": ur_model_option},
    ),
}


def _host_and_port(spec: str, address: str) -> tuple[str, int | None]:
    host, sep, port_text = address.rpartition(":") if address.count(":") == 1 else ("", "", "")
    if not sep:
        host = address
    if not host or any(c.isspace() for c in host) or any(c in host for c in ":?&=/"):
        raise SpecError(spec, "has no valid host")
    if not sep:
        return host, None
    try:
        return host, port_option(port_text)
    except ValueError as exc:
        raise SpecError(spec, str(exc)) from None


def _options(spec: str, query: str, form: SpecForm) -> dict[str, Any]:
    allowed = {**COMMON_OPTIONS, **form.options}
    values: dict[str, Any] = {}
    for item in query.split("&"):
        key, eq, text = item.partition("=")
        key = key.strip().lower()
        if key not in allowed:
            known = ", ".join(f"{name}=..." for name in allowed)
            raise SpecError(spec, f"has an unknown option {item!r} (known: {known})")
        if not eq or not text.strip():
            raise SpecError(spec, f"gives no value for option {key!r}")
        if key in values:
            raise SpecError(spec, f"gives option {key!r} twice")
        try:
            values[key] = allowed[key](text.strip())
        except ValueError as exc:
            raise SpecError(spec, str(exc)) from None
    return values


def parse_robot_spec(spec: str) -> RobotSpec:
    """``spec`` parsed and validated; raises :class:`SpecError` (a one-line ValueError)."""
    if not isinstance(spec, str):
        raise SpecError(str(spec), "is not text")
    text = spec.strip()
    head, qmark, query = text.partition("?")
    kind, colon, address = head.partition(":")
    kind = kind.strip().lower()
    form = SPEC_FORMS.get(kind)
    if form is None or colon != ("" if not form.address else ":"):
        raise SpecError(spec, "is not understood")
    if qmark and not query:
        raise SpecError(spec, "has an empty option list after '?'")
    host = port = None
    if form.address:
        host, port = _host_and_port(spec, address)
        if port is not None and form.port is not None:
            raise SpecError(spec, form.port)
    options = _options(spec, query, form) if qmark else {}
    return RobotSpec(text, kind, host, port, options)


def make_robot(spec: str) -> Robot:
    """The backend named by ``spec``, not yet connected; raises :class:`SpecError` (one line)
    for a bad spec. A spec with ``safety=degraded`` sets the backend's
    :attr:`~wovenskin.robots.base.Robot.degraded_safety` opt-in."""
    parsed = parse_robot_spec(spec)
    try:
        robot = SPEC_FORMS[parsed.kind].build(parsed)
    except ValueError as exc:  # a backend's own check of its arguments
        raise SpecError(spec, " ".join(str(exc).split())) from None
    robot.degraded_safety = parsed.degraded_safety
    return robot
