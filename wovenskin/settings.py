"""One way to read settings: a plain dataclass, validated by pydantic from a dict.

Every settings dataclass (conditioning, simulated skins and people, training, robot and
source options) is read from TOML, JSON or a spec string's ``key=value`` options with
:func:`from_dict`: unknown keys, wrong types and values that fail the dataclass's
:class:`typing.Annotated` constraints (``Annotated[float, Gt(0)]``) or its
``__post_init__`` are one :class:`~wovenskin.errors.ConfigError` naming the key.
Missing keys take the dataclass's defaults.  :func:`to_dict` is the way back, JSON-ready.
"""

from __future__ import annotations

import dataclasses
import typing
from collections.abc import Mapping
from functools import cache
from typing import Any, TypeVar

from pydantic import ConfigDict, TypeAdapter, ValidationError

from wovenskin.errors import ConfigError
from wovenskin.io import to_jsonable

T = TypeVar("T")

_CONFIG = ConfigDict(extra="forbid", arbitrary_types_allowed=True)


def _forbid_extra(cls: type) -> None:
    """Give ``cls`` and the dataclasses in its fields pydantic's ``extra="forbid"``."""
    if "__pydantic_config__" in cls.__dict__:
        return
    cls.__pydantic_config__ = _CONFIG  # read by pydantic when it validates a stdlib dataclass
    for hint in typing.get_type_hints(cls).values():
        for inner in (hint, *typing.get_args(hint)):
            if isinstance(inner, type) and dataclasses.is_dataclass(inner):
                _forbid_extra(inner)


@cache
def _adapter(cls: type) -> TypeAdapter:
    _forbid_extra(cls)
    return TypeAdapter(cls)


def _one_line(error: ValidationError, what: str) -> str:
    problems = []
    for item in error.errors(include_url=False):
        where = ".".join(str(part) for part in item["loc"])
        if item["type"] in ("extra_forbidden", "unexpected_keyword_argument"):
            problems.append(f"unknown setting {where!r}")
            continue
        message = item["msg"].removeprefix("Value error, ")
        problems.append(f"{where}: {message}" if where else message)
    return f"bad {what}: " + "; ".join(problems)


def from_dict(cls: type[T], data: Mapping[str, Any], what: str = "") -> T:
    """Build the dataclass ``cls`` from ``data``, validated; one :class:`ConfigError` if not.

    ``what`` names the settings in the message (default: the class name).  Values are
    converted where nothing is lost (pydantic's lax mode: ``"3"`` -> ``3``, ``"true"`` ->
    ``True``, a list -> a tuple), so spec strings and form fields read as TOML does.
    """
    if not dataclasses.is_dataclass(cls):
        raise TypeError(f"{cls!r} is not a dataclass")
    if not isinstance(data, Mapping):
        kind = type(data).__name__
        raise ConfigError(f"bad {what or cls.__name__}: expected a table of settings, got {kind}")
    try:
        return _adapter(cls).validate_python(dict(data))
    except ValidationError as exc:
        raise ConfigError(_one_line(exc, what or cls.__name__)) from None
    except (TypeError, ValueError) as exc:  # raised by a __post_init__ pydantic did not wrap
        if isinstance(exc, ConfigError):
            raise
        raise ConfigError(f"bad {what or cls.__name__}: {exc}") from None


def to_dict(settings: Any) -> dict[str, Any]:
    """The dataclass ``settings`` as a JSON-ready dict (the inverse of :func:`from_dict`)."""
    return to_jsonable(dataclasses.asdict(settings))
