"""The robot registry: one line per backend, and robot specs read and built from it.

A spec names a backend and its address: ``sim``, ``tm:HOST[:PORT]`` (ports also as
``tm:HOST?listen_port=5890&state_port=5891``) or ``ur:HOST[?model=ur5e]`` (the UR model:
``ur3e``, ``ur5e``, ``ur10e``, ``ur16e``) or ``ros2[:]?twist=/topic&...`` (an arm driven
through MoveIt Servo over ROS 2). Options follow a ``?``, joined by ``&``. Every
kind also takes ``safety=degraded``: the user's opt-in to run an arm whose declaration
lacks what the safety layer's full checks need (see
:class:`wovenskin.control.safety.SafetyLayer` and ``docs/safety.md``).

:func:`parse_robot_spec` checks a spec without building anything; every problem is one
:class:`SpecError` line that lists the valid forms. A new backend is a folder beside
``sim``, ``techman`` and ``ur`` whose ``config.py`` declares its options dataclass and its
:class:`~wovenskin.robots.spec.Backend`, plus one line in :data:`BACKENDS`.
"""

from __future__ import annotations

from dataclasses import fields

from wovenskin import specs
from wovenskin.robots.base import Robot
from wovenskin.robots.ros2.config import ROS2
from wovenskin.robots.sim.config import SIM
from wovenskin.robots.spec import Backend, RobotOptions, RobotSpec, port_number
from wovenskin.robots.techman.config import TECHMAN
from wovenskin.robots.ur.config import UR

BACKENDS: dict[str, Backend] = {
    "sim": SIM,
    "tm": TECHMAN,
    "ur": UR,
    "ros2": ROS2,
}


def valid_forms() -> str:
    """The registered backends' spec forms, for messages."""
    return ", ".join(backend.form for backend in BACKENDS.values())


class SpecError(specs.SpecError):
    """A robot spec that cannot be used; the message is one line and lists the valid forms."""

    def __init__(self, spec: str, why: str) -> None:
        super().__init__(spec, why)
        self.args = (f"robot {self}; valid forms: {valid_forms()}",)


def _host_and_port(spec: str, address: str) -> tuple[str, int | None]:
    host, sep, port_text = address.rpartition(":") if address.count(":") == 1 else ("", "", "")
    if not sep:
        host = address
    if not host or any(c.isspace() for c in host) or any(c in host for c in ":?&=/"):
        raise SpecError(spec, "has no valid host")
    if not sep:
        return host, None
    try:
        return host, port_number(port_text)
    except ValueError as exc:
        raise SpecError(spec, f"has a {exc}") from None


def _read_options(spec: str, parsed: specs.Spec, cls: type[RobotOptions]) -> RobotOptions:
    known = [item.name for item in fields(cls)]
    for key, value in parsed.options.items():
        if key not in known:
            listing = ", ".join(f"{name}=..." for name in known)
            raise SpecError(spec, f"has an unknown option {f'{key}={value}'!r} (known: {listing})")
    try:
        return parsed.read_options(cls)
    except specs.SpecError as exc:
        raise SpecError(spec, exc.why) from None


def parse_robot_spec(spec: str) -> RobotSpec:
    """``spec`` parsed and validated; raises :class:`SpecError` (a one-line ValueError)."""
    if not isinstance(spec, str):
        raise SpecError(str(spec), "is not text")
    try:
        parsed = specs.parse_spec(spec)
    except specs.SpecError as exc:
        raise SpecError(spec, exc.why) from None
    backend = BACKENDS.get(parsed.kind)
    bare_with_colon = backend is not None and backend.colon_optional and not parsed.target
    if backend is None or (parsed.colon != backend.address and not bare_with_colon):
        raise SpecError(spec, "is not understood")
    host = port = None
    if backend.address:
        host, port = _host_and_port(spec, parsed.target)
        if port is not None and backend.port is not None:
            raise SpecError(spec, backend.port)
    settings = _read_options(spec, parsed, backend.options)
    given = {key: getattr(settings, key) for key in parsed.options}
    return RobotSpec(parsed.text, parsed.kind, host, port, given, settings)


def make_robot(spec: str) -> Robot:
    """The backend named by ``spec``, not yet connected; raises :class:`SpecError` (one line)
    for a bad spec. A spec with ``safety=degraded`` sets the backend's
    :attr:`~wovenskin.robots.base.Robot.degraded_safety` opt-in."""
    parsed = parse_robot_spec(spec)
    try:
        robot = BACKENDS[parsed.kind].build(parsed)
    except ValueError as exc:  # a backend's own check of its arguments
        raise SpecError(spec, " ".join(str(exc).split())) from None
    robot.degraded_safety = parsed.degraded_safety
    return robot
