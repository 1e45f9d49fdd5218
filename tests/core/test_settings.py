"""wovenskin.settings: dataclasses read from dicts with one validation path and one-line errors."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Annotated

import pytest
from annotated_types import Gt

from wovenskin.errors import ConfigError, WovenskinError
from wovenskin.settings import from_dict, to_dict


@dataclass(frozen=True)
class Inner:
    gain: float = 1.0


@dataclass(frozen=True)
class Example:
    rate_hz: Annotated[float, Gt(0)] = 200.0
    frames: int = 30
    name: str = "default"
    pitch_mm: tuple[float, float] = (4.0, 4.0)
    inner: Inner = field(default_factory=Inner)

    def __post_init__(self) -> None:
        if self.frames > 1000:
            raise ValueError("frames must be at most 1000")


def test_missing_keys_take_defaults_and_text_numbers_convert() -> None:
    value = from_dict(Example, {"frames": "12", "pitch_mm": [3, 5], "inner": {"gain": 2}})
    assert value == Example(frames=12, pitch_mm=(3.0, 5.0), inner=Inner(2.0))
    assert from_dict(Example, to_dict(value)) == value


@pytest.mark.parametrize(
    ("data", "says"),
    [
        ({"rate": 1}, "unknown setting 'rate'"),
        ({"inner": {"gian": 1}}, "unknown setting 'inner.gian'"),
        ({"rate_hz": -1}, "rate_hz: Input should be greater than 0"),
        ({"frames": 2.5}, "frames:"),
        ({"frames": 5000}, "frames must be at most 1000"),
        ({"name": None}, "name:"),
    ],
)
def test_every_problem_is_one_config_error_line(data: dict, says: str) -> None:
    with pytest.raises(ConfigError) as info:
        from_dict(Example, data, "example settings")
    message = str(info.value)
    assert message.startswith("bad example settings: ") and says in message and "\n" not in message
    assert isinstance(info.value, WovenskinError) and isinstance(info.value, ValueError)


def test_a_non_table_is_refused() -> None:
    with pytest.raises(ConfigError, match="expected a table"):
        from_dict(Example, [1, 2])  # type: ignore[arg-type]
