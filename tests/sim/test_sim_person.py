"""Tests of simulated people and their trial-to-trial variation (wovenskin.sim.person)."""

from __future__ import annotations

import numpy as np
import pytest

from wovenskin.sim import spec
from wovenskin.sim.person import Pad, Person, Trial


def people(count: int, seed: int = 0) -> list[Person]:
    rng = np.random.default_rng(seed)
    return [Person.sample(rng) for _ in range(count)]


def test_sample_is_deterministic_and_round_trips():
    a = Person.sample(np.random.default_rng(3))
    b = Person.sample(np.random.default_rng(3))
    assert a == b
    assert Person.from_dict(a.to_dict()) == a
    with pytest.raises(ValueError, match="person traits: unknown setting 'speed'"):
        Person.from_dict({"speed": 1})


def test_bad_traits_are_rejected():
    with pytest.raises(ValueError, match="handedness"):
        Person(handedness="both")
    with pytest.raises(ValueError, match="pace"):
        Person(pace=1.5)
    with pytest.raises(ValueError, match="force"):
        Person(force_n=0.0)


def test_sampled_people_are_diverse():
    crowd = people(300)
    pace = np.array([p.pace for p in crowd])
    reach = np.array([p.reach for p in crowd])
    angle = np.array([p.hand_angle_deg for p in crowd])
    force = np.array([p.force_n for p in crowd])
    assert pace.min() < 0.1 and pace.max() > 0.9
    assert reach.min() < 0.1 and reach.max() > 0.9
    assert angle.min() < -80 and angle.max() > 80
    assert force.max() / force.min() > 5
    assert abs(np.corrcoef(pace, reach)[0, 1]) < 0.2  # traits are independent
    lefties = sum(p.handedness == "left" for p in crowd)
    assert 10 < lefties < 70
    assert len({p.person_id for p in crowd}) > 290


def test_trial_values_stay_in_the_gesture_ranges():
    for person in people(40, seed=1):
        rng = np.random.default_rng(2)
        for _ in range(20):
            trial = Trial(person, rng)
            speed = trial.paced(spec.SWIPE_MEAN_SPEED_MM_S)
            assert spec.SWIPE_MEAN_SPEED_MM_S[0] <= speed <= spec.SWIPE_MEAN_SPEED_MM_S[1]
            travel = trial.sized(spec.SWIPE_TRAVEL_MM)
            assert spec.SWIPE_TRAVEL_MM[0] <= travel <= spec.SWIPE_TRAVEL_MM[1]
            ramp = trial.paced_duration(spec.PUSH_RAMP_S)
            assert spec.PUSH_RAMP_S[0] <= ramp <= spec.PUSH_RAMP_S[1]
            assert spec.CONTACT_RAMP_S[0] <= trial.landing_ramp_s() <= spec.CONTACT_RAMP_S[1]
            assert spec.CONTACT_RAMP_S[0] <= trial.lift_ramp_s() <= spec.CONTACT_RAMP_S[1]
            assert spec.REST_S[0] <= trial.rest_s() <= spec.REST_S[1]
            assert abs(trial.aim_deg()) < spec.SWIPE_MAX_OFF_AXIS_DEG
            assert abs(trial.bow()) < spec.SWIPE_MAX_BOW
            spacing = trial.spacing(spec.PAIR_SPACING_MM)
            assert spec.PAIR_SPACING_MM[0] <= spacing <= spec.PAIR_SPACING_MM[1]
            delays = trial.finger_delays_s(5)
            assert delays.min() == 0.0 and delays.max() <= 0.12
            direction = trial.finger_direction()
            assert np.linalg.norm(direction) == pytest.approx(1.0)


def test_trials_vary_around_the_person():
    fast = Person(pace=0.95, consistency=1.0)
    slow = Person(pace=0.05, consistency=1.0)
    rng = np.random.default_rng(4)
    fast_speeds = [Trial(fast, rng).paced(spec.SWIPE_MEAN_SPEED_MM_S) for _ in range(200)]
    slow_speeds = [Trial(slow, rng).paced(spec.SWIPE_MEAN_SPEED_MM_S) for _ in range(200)]
    assert np.median(fast_speeds) > 2 * np.median(slow_speeds)
    assert np.std(fast_speeds) > 5  # not the same every trial
    steady = [Trial(Person(consistency=0.5), rng).paced((0.0, 1.0), log=False) for _ in range(300)]
    erratic = [Trial(Person(consistency=1.5), rng).paced((0.0, 1.0), log=False) for _ in range(300)]
    assert np.std(erratic) > 1.8 * np.std(steady)


def test_rest_habit_and_hand_orientation():
    rng = np.random.default_rng(5)
    rester = Person(rest_probability=0.9, rest_mean_s=1.0)
    lifter = Person(rest_probability=0.2, rest_mean_s=0.2)
    rests = np.array([Trial(rester, rng).rest_s() for _ in range(300)])
    lifts = np.array([Trial(lifter, rng).rest_s() for _ in range(300)])
    assert rests.mean() > 3 * lifts.mean()
    assert (rests > 1.0).any() and (lifts < 0.05).mean() > 0.6
    angles = np.array([Trial(Person(hand_angle_deg=30.0), rng).hand_angle_deg for _ in range(300)])
    assert np.median(angles) == pytest.approx(30.0, abs=5.0)
    assert (np.abs(angles - 30.0) > 60).any()  # sometimes an unusual posture


def test_pad_grows_with_force_within_the_fingertip_range():
    pad = Pad(width_mm=8.5, growth_mm=3.5, aspect=1.15)
    forces = np.linspace(0.0, 8.0, 50)
    major, minor = pad.axes_mm(forces)
    low, high = spec.FINGERTIP_PATCH_MM
    assert (2 * minor >= low).all() and (2 * major <= high).all()
    assert (np.diff(minor) >= 0).all() and minor[-1] > minor[0] + 1.0
    assert (major >= minor).all()


def test_a_typical_person_keeps_every_bounded_trait_within_its_bounds():
    from wovenskin.sim.person import TYPICAL_TRAITS

    for seed in range(50):
        person = Person.sample_typical(np.random.default_rng(seed))
        for name, (low, high) in TYPICAL_TRAITS.items():
            assert low <= getattr(person, name) <= high, (seed, name)
    # the other traits keep the full range's draw
    full, typical = (
        draw(np.random.default_rng(7)) for draw in (Person.sample, Person.sample_typical)
    )
    assert typical.pad_mm == full.pad_mm and typical.handedness == full.handedness


def test_the_live_skin_draws_a_typical_person_unless_told_any():
    from wovenskin.errors import ConfigError
    from wovenskin.sim.live import SimulatedSkinSource
    from wovenskin.sim.live_options import SimOptions

    assert SimOptions.read({}).source_kwargs()["typical_person"] is True
    assert SimOptions.read({"person": "any"}).source_kwargs()["typical_person"] is False
    with pytest.raises(ConfigError, match="sim person must be one of typical, any"):
        SimOptions.read({"person": "median"})
    from wovenskin.sim.person import TYPICAL_TRAITS

    for seed in range(5):
        person = SimulatedSkinSource(seed=seed, autonomous=False).person
        assert all(low <= getattr(person, n) <= high for n, (low, high) in TYPICAL_TRAITS.items())
