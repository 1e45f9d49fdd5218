"""The robustness suite of ``bench recognition``: its conditions, their seeds, their streams.

Conditions (name: what it overrides -- why; everything else is drawn by
``SkinPhysics.sample`` and ``Person.sample`` for the stream's seed):

- ``response_x0.1``, ``response_x0.3``, ``response_x1``, ``response_x3``,
  ``response_x10``: skin ``gain_pf`` = 4 pF (the typical skin's) times the factor, on
  ``c0_pf`` = 20 pF -- skins differ in response by 10x and more (weave, cover, mounting):
  from a very dull skin on which a press changes a channel by a fraction of a percent to
  a very sensitive one on which it changes by more than 100 %.
- ``fingertip_small``: ``field_spread_mm`` 0, person ``pad_mm`` 8 and ``pad_growth_mm``
  2 -- the smallest fingertip on a skin without lateral spread: 1-2 channels.
- ``fingertip_large``: ``field_spread_mm`` 6.5, ``pad_mm`` 9.5, ``pad_growth_mm`` 4 --
  the largest fingertip on a skin whose cover spreads it: 3-4 channels.
- ``person_light``: person ``force_n`` 0.25 N -- the lightest touch people use.
- ``person_slow``: person ``pace`` 0 -- the slowest allowed gestures.
- ``person_fast``: person ``pace`` 1 -- the fastest allowed gestures.
- ``person_hesitant``: person ``settle_s`` 0.2, ``consistency`` 1.5 -- a pause after
  landing before the motion starts, and erratic trials.
- ``skin_noisy``: ``noise_pf`` 0.03, ``mains_pf`` 0.04, ``body_mains_pf`` 0.1,
  ``glitch_rate_hz`` 0.3 -- the noisiest readout within the physics ranges.
- ``skin_drifting``: ``drift_common_per_min`` 0.01, ``drift_channel_per_min`` 0.004,
  ``drift_tau_s`` 120 -- the fastest thermal drift within the ranges.
- ``invalid_heavy``: the stream's ``invalid_fraction`` 0.6 -- most touches are palms,
  forearms, taps and other contacts that must not move the robot.
- ``long_rests``: person ``rest_probability`` 0.9, ``rest_mean_s`` 1.0 -- fingers resting
  long on the skin after the motion (the arbiter must not act twice).

The ``response_x*`` conditions fix ``c0_pf`` so that the relative response, which the
conditioned signal ``(C - C0) / C0`` sees, scales by exactly the factor.

Seeds: stream ``j`` of the condition at position ``i`` of :data:`CONDITIONS` takes the seed
:func:`stream_seed` ``(base_seed, i, j)`` (a ``numpy.random.SeedSequence`` of the three), so
every stream is reproducible, a subset of conditions runs the very same streams as the full
suite, and a condition appended to the table changes no other condition's streams (append
new conditions at the end).  The default base seed 9000 keeps the streams far from the
training data's seeds.  :func:`make_stream` draws the skin and person from the seed, applies
the condition and simulates the stream; the same seed under two conditions gives the same
person, skin and events, differing only by the condition's overrides.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from wovenskin.errors import ConfigError
from wovenskin.recording.formats import LabelledStream
from wovenskin.sim.person import Person
from wovenskin.sim.skin_physics import SkinPhysics
from wovenskin.sim.stream import simulate_stream

DEFAULT_SECONDS = 60.0
TYPICAL_GAIN_PF = 4.0
"""``SkinPhysics``' default ``gain_pf``: the ``response_x1`` skin."""
TYPICAL_C0_PF = 20.0
"""``SkinPhysics``' default ``c0_pf``, fixed by the ``response_x*`` conditions."""

Recipe = Callable[
    [np.random.Generator, SkinPhysics, Person], tuple[SkinPhysics, Person, dict[str, Any]]
]
"""``(rng, physics, person) -> (physics, person, simulate_stream keyword arguments)``."""


@dataclass(frozen=True)
class Condition:
    """One condition of the suite: what it does and the recipe that does it."""

    description: str
    apply: Recipe


def _response(factor: float) -> Recipe:
    def recipe(rng, physics, person):
        physics = replace(physics, gain_pf=TYPICAL_GAIN_PF * factor, c0_pf=TYPICAL_C0_PF)
        return physics, person, {}

    return recipe


def _physics(**overrides: float) -> Recipe:
    def recipe(rng, physics, person):
        return replace(physics, **overrides), person, {}

    return recipe


def _person(**overrides: float) -> Recipe:
    def recipe(rng, physics, person):
        return physics, replace(person, **overrides), {}

    return recipe


def _fingertip(spread_mm: float, pad_mm: float, growth_mm: float) -> Recipe:
    def recipe(rng, physics, person):
        physics = replace(physics, field_spread_mm=spread_mm)
        return physics, replace(person, pad_mm=pad_mm, pad_growth_mm=growth_mm), {}

    return recipe


def _stream(**kwargs: Any) -> Recipe:
    def recipe(rng, physics, person):
        return physics, person, dict(kwargs)

    return recipe


def _response_condition(factor: float) -> Condition:
    gain = TYPICAL_GAIN_PF * factor
    return Condition(
        f"skin response x{factor:g} of a typical skin (gain_pf {gain:g} pF on c0_pf "
        f"{TYPICAL_C0_PF:g} pF)",
        _response(factor),
    )


CONDITIONS: dict[str, Condition] = {
    "response_x0.1": _response_condition(0.1),
    "response_x0.3": _response_condition(0.3),
    "response_x1": _response_condition(1.0),
    "response_x3": _response_condition(3.0),
    "response_x10": _response_condition(10.0),
    "fingertip_small": Condition(
        "a fingertip on 1-2 channels: no lateral field spread, the smallest pads "
        "(field_spread_mm 0, pad_mm 8, pad_growth_mm 2)",
        _fingertip(0.0, 8.0, 2.0),
    ),
    "fingertip_large": Condition(
        "a fingertip over 3-4 channels: wide lateral field spread, the largest pads "
        "(field_spread_mm 6.5, pad_mm 9.5, pad_growth_mm 4)",
        _fingertip(6.5, 9.5, 4.0),
    ),
    "person_light": Condition(
        "the lightest touch people use (person force_n 0.25 N)", _person(force_n=0.25)
    ),
    "person_slow": Condition("the slowest allowed gestures (person pace 0)", _person(pace=0.0)),
    "person_fast": Condition("the fastest allowed gestures (person pace 1)", _person(pace=1.0)),
    "person_hesitant": Condition(
        "a pause after landing before the motion, erratic trials "
        "(person settle_s 0.2, consistency 1.5)",
        _person(settle_s=0.2, consistency=1.5),
    ),
    "skin_noisy": Condition(
        "the noisiest readout in the physics ranges (noise_pf 0.03, mains_pf 0.04, "
        "body_mains_pf 0.1, glitch_rate_hz 0.3)",
        _physics(noise_pf=0.03, mains_pf=0.04, body_mains_pf=0.1, glitch_rate_hz=0.3),
    ),
    "skin_drifting": Condition(
        "the fastest thermal drift in the ranges (drift_common_per_min 0.01, "
        "drift_channel_per_min 0.004, drift_tau_s 120)",
        _physics(drift_common_per_min=0.01, drift_channel_per_min=0.004, drift_tau_s=120.0),
    ),
    "invalid_heavy": Condition(
        "most touches are invalid (palms, forearms, taps...): invalid_fraction 0.6",
        _stream(invalid_fraction=0.6),
    ),
    "long_rests": Condition(
        "fingers rest long on the skin after the motion (person rest_probability 0.9, "
        "rest_mean_s 1.0)",
        _person(rest_probability=0.9, rest_mean_s=1.0),
    ),
}
"""The suite's conditions in their fixed order (a stream's seed uses the position)."""


def condition_names(spec: str | Sequence[str] | None) -> list[str]:
    """Names of the conditions to run, in suite order: all for ``None``, else the given ones.

    ``spec`` may be a comma-separated string; an unknown name raises ``ValueError``.
    """
    if spec is None:
        return list(CONDITIONS)
    names = [n.strip() for n in spec.split(",")] if isinstance(spec, str) else list(spec)
    names = [n for n in names if n]
    if not names:
        raise ConfigError("no conditions given")
    unknown = [n for n in names if n not in CONDITIONS]
    if unknown:
        raise ConfigError(
            f"unknown condition(s) {', '.join(unknown)}; known: {', '.join(CONDITIONS)}"
        )
    return [n for n in CONDITIONS if n in names]


def stream_seed(base_seed: int, condition_index: int, stream_index: int) -> int:
    """The seed of stream ``stream_index`` of the condition at ``condition_index``."""
    for name, value in (
        ("base seed", base_seed),
        ("condition index", condition_index),
        ("stream index", stream_index),
    ):
        if not (isinstance(value, int | np.integer) and value >= 0):
            raise ConfigError(f"{name} must be a non-negative integer, got {value!r}")
    sequence = np.random.SeedSequence([int(base_seed), int(condition_index), int(stream_index)])
    return int(sequence.generate_state(1, dtype=np.uint32)[0])


def make_stream(condition: str, seed: int, seconds: float = DEFAULT_SECONDS) -> LabelledStream:
    """Stream ``seed`` under ``condition``: a drawn skin and person, the overrides, simulated.

    The same seed gives identical frames; under two conditions it gives the same person,
    skin and events apart from the conditions' overrides.
    """
    if condition not in CONDITIONS:
        raise ConfigError(f"unknown condition {condition!r}; known: {', '.join(CONDITIONS)}")
    rng = np.random.default_rng(seed)
    physics = SkinPhysics.sample(rng)
    person = Person.sample(rng)
    sim_seed = int(rng.integers(2**31))
    physics, person, kwargs = CONDITIONS[condition].apply(rng, physics, person)
    stream = simulate_stream(seconds, sim_seed, physics=physics, person=person, **kwargs)
    stream.metadata["bench_condition"] = condition
    stream.metadata["bench_seed"] = int(seed)
    return stream
