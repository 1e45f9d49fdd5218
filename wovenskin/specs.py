"""Spec strings: how a person names a skin or a robot on the command line, parsed once.

A spec is ``kind``, ``kind:target`` or either with options: ``kind:target?key=value&...``
(``serial:/dev/ttyACM0?format=text``, ``tm:192.168.1.10?state_port=5891``).  A kind
without a target also takes its options after the colon, comma-separated
(``sim:seed=3,speed=1``).  :func:`parse_spec` only splits the text and refuses what no
spec may hold (a repeated key, a key with no value, an empty option list); what each kind
accepts is read with :func:`wovenskin.settings.from_dict` into that kind's options
dataclass, and every problem is one :class:`SpecError` line that quotes the spec.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, TypeVar

from wovenskin.errors import ConfigError
from wovenskin.settings import from_dict

T = TypeVar("T")


class SpecError(ConfigError):
    """A spec string that cannot be used; the message quotes it and says why."""

    def __init__(self, spec: str, why: str) -> None:
        self.spec = spec
        self.why = why
        super().__init__(f"spec {spec!r} {why}")


@dataclass(frozen=True)
class Spec:
    """A parsed spec: ``kind`` in lower case, ``target`` (a port, file or host; may be
    empty), the options as text in the order given, and whether a colon followed the kind
    (``colon``: ``tm:HOST`` and ``sim:seed=3`` have one, ``sim`` and ``sim?seed=3`` not)."""

    text: str
    kind: str
    target: str = ""
    options: dict[str, str] = field(default_factory=dict)
    colon: bool = False

    def read_options(self, cls: type[T], **extra: Any) -> T:
        """The options (and ``extra``, which they may not repeat) as the dataclass ``cls``."""
        values: dict[str, Any] = dict(self.options)
        for key, value in extra.items():
            if key in values:
                raise SpecError(self.text, f"gives {key!r}, which is set elsewhere")
            values[key] = value
        try:
            return from_dict(cls, values, f"{self.kind} options")
        except ConfigError as exc:
            raise SpecError(self.text, f"has {exc}") from None


def _split_options(spec: str, text: str, separator: str) -> dict[str, str]:
    options: dict[str, str] = {}
    for item in text.split(separator):
        key, eq, value = item.partition("=")
        key = key.strip().lower()
        if not key:
            raise SpecError(spec, f"has an empty option in {text!r}")
        if not eq or not value.strip():
            raise SpecError(spec, f"gives no value for option {key!r}")
        if key in options:
            raise SpecError(spec, f"gives option {key!r} twice")
        options[key] = value.strip()
    return options


def parse_spec(spec: str, overrides: Mapping[str, Any] | None = None) -> Spec:
    """Split ``spec`` into kind, target and options (see the module docstring).

    ``overrides`` (e.g. command-line switches) replace options of the same name; ``None``
    values are left out.
    """
    if not isinstance(spec, str) or not spec.strip():
        raise SpecError(str(spec), "is empty")
    text = spec.strip()
    head, qmark, query = text.partition("?")
    kind, colon, target = head.partition(":")
    kind = kind.strip().lower()
    if not kind or not kind.replace("_", "").replace("-", "").isalnum():
        raise SpecError(text, "does not start with a kind (e.g. sim, serial:PORT)")
    if qmark and not query.strip():
        raise SpecError(text, "has an empty option list after '?'")
    options = _split_options(text, query, "&") if qmark else {}
    if not qmark and "=" in target:  # kind:key=value,key=value
        options = _split_options(text, target, ",")
        target = ""
    for key, value in (overrides or {}).items():
        if value is not None:
            options[key.lower()] = str(value)
    return Spec(text, kind, target.strip(), options, colon=bool(colon))
