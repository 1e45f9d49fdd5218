"""Opening a skin source from its spec: the one place that knows every source backend.

Specs (the ``--skin`` option of every command):

- ``sim`` or ``sim:seed=3,speed=1`` -- the simulated skin with a simulated person
  performing gestures in real time (the default);
- ``serial:/dev/ttyACM0`` or ``serial:/dev/ttyACM0?format=text&order=col-major`` -- a
  real skin on a serial port (binary protocol of ``docs/protocol.md`` or text lines);
- ``replay:FILE`` -- a labelled-stream ``.npz`` or a native ``.wsrec`` recording played
  back in real time (``replay:FILE?speed=0`` plays as fast as possible).
"""

from __future__ import annotations

from urllib.parse import parse_qsl

from wovenskin.recording.replay import ReplaySource
from wovenskin.sim.live import SimulatedSkinSource
from wovenskin.skin.serial_source import SerialSkinSource
from wovenskin.skin.source import SkinSource


def parse_spec(spec: str) -> tuple[str, str, dict[str, str]]:
    """Split ``kind:target?key=value&...`` (or ``sim:key=value,...``) into its parts."""
    kind, _, rest = spec.partition(":")
    kind = kind.strip().lower()
    target, _, query = rest.partition("?")
    options: dict[str, str] = dict(parse_qsl(query, keep_blank_values=True))
    if kind == "sim" and "=" in target:
        for item in target.split(","):
            key, _, value = item.partition("=")
            options[key.strip()] = value.strip()
        target = ""
    return kind, target, options


def open_source(spec: str = "sim", **overrides) -> SkinSource:
    """Create (but do not start) the source named by ``spec``; see the module docstring."""
    kind, target, options = parse_spec(spec)
    options.update({k: str(v) for k, v in overrides.items() if v is not None})
    if kind == "sim":
        return SimulatedSkinSource.from_options(options)
    if kind == "serial":
        if not target:
            raise ValueError("serial source needs a port, e.g. serial:/dev/ttyACM0")
        return SerialSkinSource.from_options(target, options)
    if kind == "replay":
        if not target:
            raise ValueError("replay source needs a file, e.g. replay:stream.npz")
        return ReplaySource.from_options(target, options)
    raise ValueError(f"unknown skin source {spec!r}: use sim, serial:PORT or replay:FILE")
