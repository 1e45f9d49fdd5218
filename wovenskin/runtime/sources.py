"""Opening a skin source from its spec: the one place that knows every source backend.

Specs (the ``--skin`` option of every command; parsed by :func:`wovenskin.specs.parse_spec`):

- ``sim`` or ``sim:seed=3,speed=1`` -- the simulated skin with a simulated person
  performing gestures in real time (the default);
- ``serial:/dev/ttyACM0`` or ``serial:/dev/ttyACM0?format=text&order=col-major`` -- a
  real skin on a serial port (binary protocol of ``docs/protocol.md`` or text lines);
- ``replay:FILE`` -- a labelled-stream ``.npz`` or a native ``.wsrec`` recording played
  back in real time (``replay:FILE?speed=0`` plays as fast as possible);
- ``none`` or ``none:speed=0`` -- no skin: contact-free frames at 200 Hz that keep the
  session's clock for keyboard- or pendant-only sessions (:mod:`wovenskin.runtime.idle`).
"""

from __future__ import annotations

from typing import Any

from wovenskin.recording.replay import ReplaySource
from wovenskin.runtime.idle import IdleSkinSource
from wovenskin.sim.live import SimulatedSkinSource
from wovenskin.skin.serial_source import SerialSkinSource
from wovenskin.skin.source import SkinSource
from wovenskin.specs import Spec, SpecError, parse_spec

SOURCE_KINDS = "use sim, serial:PORT, replay:FILE or none"
SOURCE_NAMES = ("sim", "serial", "replay", "none")


def skin_spec(spec: str | Spec, **overrides: Any) -> Spec:
    """``spec`` parsed (a :class:`Spec` as it is), with ``overrides`` replacing its options
    (``None`` values left out); a :class:`SpecError` for a kind that is no skin source."""
    if isinstance(spec, Spec):
        given = {key: value for key, value in overrides.items() if value is not None}
        parsed = parse_spec(spec.text, {**spec.options, **given}) if given else spec
    else:
        parsed = parse_spec(spec, overrides)
    if parsed.kind not in SOURCE_NAMES:
        raise SpecError(parsed.text, f"is an unknown skin source: {SOURCE_KINDS}")
    return parsed


def open_source(spec: str | Spec = "sim", **overrides: Any) -> SkinSource:
    """Create (but do not start) the source named by ``spec``; see the module docstring.

    ``overrides`` replace the spec's options of the same name (``None`` values are left
    out).  A bad spec or option is one :class:`~wovenskin.errors.ConfigError` line."""
    parsed = skin_spec(spec, **overrides)
    options = dict(parsed.options)
    if parsed.kind in ("sim", "none"):
        if parsed.target:
            name = "the simulated skin" if parsed.kind == "sim" else "no skin"
            example = f"{parsed.kind}:KEY=VALUE,..."
            raise SpecError(parsed.text, f"gives {name} a target: use {example}")
        if parsed.kind == "none":
            return IdleSkinSource.from_options(options)
        return SimulatedSkinSource.from_options(options)
    if not parsed.target:
        example = "serial:/dev/ttyACM0" if parsed.kind == "serial" else "replay:stream.npz"
        what = "port" if parsed.kind == "serial" else "file"
        raise SpecError(parsed.text, f"names no {what}: e.g. {example}")
    if parsed.kind == "serial":
        return SerialSkinSource.from_options(parsed.target, options)
    return ReplaySource.from_options(parsed.target, options)
