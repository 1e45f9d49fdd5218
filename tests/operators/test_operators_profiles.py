"""Simulated operators' profiles: drawn within their documented ranges, novices slower."""

import pytest

from wovenskin.errors import ConfigError
from wovenskin.operators.profiles import RANGES, sample_profile


@pytest.mark.parametrize("expertise", ["novice", "expert"])
def test_every_field_lies_in_its_range(expertise):
    for seed in range(20):
        profile = sample_profile("S01", expertise, seed)
        for field, by_level in RANGES.items():
            low, high = by_level[expertise]
            assert low <= getattr(profile, field) <= high, (field, seed)


def test_the_same_seed_draws_the_same_person_and_others_differ():
    assert sample_profile("a", "novice", 3) == sample_profile("a", "novice", 3)
    assert sample_profile("a", "novice", 3).think_s != sample_profile("a", "novice", 4).think_s


def test_novices_think_and_react_slower_than_experts():
    novices = [sample_profile("n", "novice", s) for s in range(10)]
    experts = [sample_profile("e", "expert", s) for s in range(10)]
    assert min(p.think_s for p in novices) > max(p.think_s for p in experts)
    assert min(p.key_s for p in novices) > max(p.key_s for p in experts)


def test_practice_shortens_thinking_over_trials():
    profile = sample_profile("n", "novice", 1)
    times = [profile.thinking(n) for n in range(1, 11)]
    assert times == sorted(times, reverse=True) and times[-1] < times[0]


def test_unknown_expertise_is_one_line_error():
    with pytest.raises(ConfigError, match="novice or expert"):
        sample_profile("x", "intermediate", 0)
