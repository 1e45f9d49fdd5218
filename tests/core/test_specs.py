"""wovenskin.specs: the one spec-string parser."""

from __future__ import annotations

from dataclasses import dataclass

import pytest

from wovenskin.errors import ConfigError
from wovenskin.specs import SpecError, parse_spec


@pytest.mark.parametrize(
    ("text", "kind", "target", "options", "colon"),
    [
        ("sim", "sim", "", {}, False),
        ("SIM:seed=3, speed=1", "sim", "", {"seed": "3", "speed": "1"}, True),
        ("sim?seed=3", "sim", "", {"seed": "3"}, False),
        ("serial:/dev/ttyACM0?format=text&order=col-major", "serial", "/dev/ttyACM0",
         {"format": "text", "order": "col-major"}, True),
        ("tm:10.0.0.1:5890?state_port=5891", "tm", "10.0.0.1:5890", {"state_port": "5891"}, True),
        ("replay:a b.npz", "replay", "a b.npz", {}, True),
    ],
)  # fmt: skip
def test_specs_split_into_kind_target_and_options(text, kind, target, options, colon) -> None:
    spec = parse_spec(text)
    assert (spec.kind, spec.target, spec.options, spec.colon) == (kind, target, options, colon)


@pytest.mark.parametrize(
    ("text", "says"),
    [
        ("", "is empty"),
        ("sim:seed=3,seed=4", "gives option 'seed' twice"),
        ("tm:host?", "empty option list"),
        ("serial:/dev/x?format", "gives no value for option 'format'"),
        (":x", "does not start with a kind"),
    ],
)
def test_bad_specs_are_one_line(text: str, says: str) -> None:
    with pytest.raises(SpecError, match=says) as info:
        parse_spec(text)
    assert isinstance(info.value, ConfigError) and "\n" not in str(info.value)


@dataclass(frozen=True)
class Options:
    seed: int = 0
    speed: float = 1.0


def test_options_read_into_a_dataclass_and_overrides_win() -> None:
    spec = parse_spec("sim:seed=3", overrides={"speed": 2, "ignored": None})
    assert spec.read_options(Options) == Options(seed=3, speed=2.0)
    with pytest.raises(SpecError, match="unknown setting 'sped'"):
        parse_spec("sim:sped=2").read_options(Options)
    with pytest.raises(SpecError, match="set elsewhere"):
        spec.read_options(Options, seed=1)
