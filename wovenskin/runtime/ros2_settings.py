"""What ``wovenskin run --ros2-publish`` publishes, and how often: settings without DDS.

:class:`SkinTopics` holds the per-topic rates (Hz on the skin's stream clock, 0 = off), the
namespace and the ROS domain id; :func:`parse_ros2_publish` reads the command line's value
(``on`` for the defaults, or ``frames=50,contacts=20,ns=/wovenskin,domain=0``), every bad
value one :class:`~wovenskin.errors.ConfigError` line that lists the valid keys.  Nothing
here needs ``cyclonedds``; :func:`require_cyclonedds` is the one-line check before the
publisher (:mod:`wovenskin.runtime.ros2_publish`, which does need it) is imported.
"""

from __future__ import annotations

import importlib.util
import math
from dataclasses import dataclass, field, fields

from wovenskin.errors import ConfigError, MissingExtraError
from wovenskin.ros2.node import dds_topic_name, domain_id
from wovenskin.specs import parse_spec

MAX_RATE_HZ = 1000.0  # a rate above the skin's own (200 Hz) publishes every frame
RATE_KEYS = ("frames", "contacts", "tracks", "gesture", "probabilities")
TOPICS = (*RATE_KEYS, "class_names")
FRAME_ID = "wovenskin_skin"  # header.frame_id of the frames, the contacts and the tracks


@dataclass(frozen=True)
class SkinTopics:
    """Rates in Hz of each topic on the skin's stream clock (0: not published), the
    namespace the topics live under and the ROS domain id (``None``: ``ROS_DOMAIN_ID``,
    else 0).  ``class_names`` goes with ``probabilities``: latched, once per change."""

    frames: float = 100.0
    contacts: float = 50.0
    tracks: float = field(default=50.0, kw_only=True)  # keyword only: the positions hold
    gesture: float = 20.0
    probabilities: float = 20.0
    ns: str = "/wovenskin"
    domain: int | None = None

    def __post_init__(self) -> None:
        for key in RATE_KEYS:
            rate = getattr(self, key)
            if not (math.isfinite(rate) and 0.0 <= rate <= MAX_RATE_HZ):
                raise ConfigError(f"{key} must be a rate of 0-{MAX_RATE_HZ:g} Hz, got {rate!r}")
        ns = "/" + self.ns.strip().strip("/") if self.ns.strip("/ ") else ""
        if ns:
            dds_topic_name(ns)  # a bad namespace is one ConfigError line naming it
        object.__setattr__(self, "ns", ns)
        if self.domain is not None:
            object.__setattr__(self, "domain", domain_id(self.domain))

    def topic(self, name: str) -> str:
        """The fully qualified ROS 2 name of topic ``name`` (``/wovenskin/frames``)."""
        return f"{self.ns}/{name}"

    def rate(self, name: str) -> float:
        """The rate of topic ``name`` in Hz (0: off)."""
        return float(getattr(self, name))

    def describe(self) -> str:
        """One line: the topics published and their rates."""
        on = [f"{key} {self.rate(key):g} Hz" for key in RATE_KEYS if self.rate(key) > 0]
        where = self.ns or "/"
        domain = "ROS_DOMAIN_ID" if self.domain is None else str(self.domain)
        return f"ROS 2 (domain {domain}) under {where}: {', '.join(on) or 'nothing'}"


KEYS_HELP = (
    "use 'on' (the defaults) or key=value pairs separated by commas, keys "
    + ", ".join(f.name for f in fields(SkinTopics))
    + f" (rates in Hz, 0-{MAX_RATE_HZ:g}, 0 = off; ns a ROS name; domain 0-232), e.g. "
    "frames=50,contacts=20,probabilities=0"
)


def parse_ros2_publish(value: str | None) -> SkinTopics | None:
    """The settings ``--ros2-publish VALUE`` asks for (``None``: no publishing)."""
    if value is None:
        return None
    text = value.strip()
    if text.lower() == "on":
        return SkinTopics()
    try:
        spec = parse_spec(f"ros2-publish:{text}")
        if spec.target or not spec.options:  # "frames", "50": no key=value pair
            raise ConfigError(f"{text!r} is not a list of key=value pairs")
        return spec.read_options(SkinTopics)
    except ConfigError as exc:
        why = getattr(exc, "why", None) or str(exc)
        why = why.removeprefix("has ").removeprefix("bad ros2-publish options: ")
        raise ConfigError(f"--ros2-publish {text!r}: {why}; {KEYS_HELP}") from None


def require_cyclonedds() -> None:
    """Raise one :class:`~wovenskin.errors.MissingExtraError` line unless ``cyclonedds`` is
    installed (the ``wovenskin[ros2]`` extra)."""
    if importlib.util.find_spec("cyclonedds") is None:
        raise MissingExtraError(
            "--ros2-publish needs the cyclonedds package: install wovenskin[ros2]"
        )
