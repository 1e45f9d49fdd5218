"""make_robot: a robot backend from a spec: ``sim``, ``tm:HOST[:PORT]`` or
``ur:HOST[?model=ur5e]`` (the UR model: ``ur3e``, ``ur5e``, ``ur10e``, ``ur16e``).

Backends are imported only when their spec is used, so a missing optional package or an
unfinished backend never breaks the others.
"""

from __future__ import annotations

from wovenskin.robots.base import Robot

VALID_SPECS = "sim, tm:HOST[:PORT], ur:HOST[?model=ur5e]"


def _bad(spec: str, why: str) -> ValueError:
    return ValueError(f"robot spec {spec!r} {why}; valid forms: {VALID_SPECS}")


def _host_and_port(spec: str, rest: str) -> tuple[str, int | None]:
    host, sep, port_text = rest.rpartition(":") if rest.count(":") == 1 else (rest, "", "")
    if not sep:
        host = rest
    if not host or any(c.isspace() for c in host) or ":" in host:
        raise _bad(spec, "has no valid host")
    if not sep:
        return host, None
    if not port_text.isdigit() or not 0 < int(port_text) < 65536:
        raise _bad(spec, f"has a bad port {port_text!r}")
    return host, int(port_text)


def make_robot(spec: str) -> Robot:
    """The backend named by ``spec``; raises :class:`ValueError` (one line) for a bad spec."""
    text = spec.strip()
    kind, sep, rest = text.partition(":")
    kind = kind.lower()
    if kind == "sim" and not sep:
        from wovenskin.robots.sim import SimRobot

        return SimRobot()
    if kind == "tm" and sep:
        from wovenskin.robots.techman import TechmanRobot

        host, port = _host_and_port(spec, rest)
        return TechmanRobot(host) if port is None else TechmanRobot(host, port)
    if kind == "ur" and sep:
        from wovenskin.robots.ur import URRobot

        address, _, query = rest.partition("?")
        host, port = _host_and_port(spec, address)
        if port is not None:
            raise _bad(spec, "gives a port, but ur_rtde uses the robot's fixed RTDE port")
        model = None
        for item in filter(None, query.split("&")):
            key, eq, value = item.partition("=")
            if key != "model" or not eq:
                raise _bad(spec, f"has an unknown option {item!r} (only model=...)")
            model = value
        try:
            return URRobot(host, model=model)
        except ValueError as exc:
            raise _bad(spec, f"names {exc}") from None
    raise _bad(spec, "is not understood")
