"""Tests of labelled simulated streams (wovenskin.sim.stream)."""

from __future__ import annotations

import json
from collections import Counter
from dataclasses import replace
from functools import cache

import numpy as np
import pytest

from wovenskin.gestures import GESTURE_NAMES, INVALID
from wovenskin.sim.invalid import INVALID_KINDS
from wovenskin.sim.person import Person
from wovenskin.sim.skin_physics import SkinPhysics
from wovenskin.sim.stream import EventScheduler, parse_request, simulate_stream
from wovenskin.skin.layout import SkinLayout

FS = 200.0


@cache
def stream(seconds: float = 40.0, seed: int = 5):
    return simulate_stream(seconds, seed)


@cache
def quiet_stream(seed: int):
    """A stream whose skin has no random disturbances, creep or crosstalk."""
    physics = SkinPhysics.sample(np.random.default_rng(seed))
    physics = replace(physics.without_noise(), creep_fraction=0.0, firmware_average_s=0.0)
    return simulate_stream(60.0, seed, physics=physics, invalid_fraction=0.3)


def test_stream_shapes_and_metadata():
    s = stream()
    assert s.frames.shape == (8000, 10, 10) and s.frames.dtype == np.float32
    assert s.t.dtype == np.float64 and np.allclose(np.diff(s.t), 1 / FS)
    assert s.sample_rate_hz == FS
    k = len(s.event_labels)
    assert k >= 10 and s.event_start_s.shape == s.event_end_s.shape == (k,)
    assert set(s.event_labels) <= {*GESTURE_NAMES, INVALID}
    assert np.all(s.event_start_s < s.event_end_s)
    assert np.all(s.event_end_s[:-1] < s.event_start_s[1:])
    assert s.event_end_s[-1] <= 40.0
    md = s.metadata
    assert md["seed"] == 5
    assert SkinPhysics.from_dict(md["physics"]) is not None
    assert Person.from_dict(md["person"]).person_id
    assert len(md["invalid_kinds"]) == k == len(md["events"])
    for label, kind in zip(s.event_labels, md["invalid_kinds"], strict=True):
        assert (kind in INVALID_KINDS) if label == INVALID else kind is None
    assert json.loads(json.dumps(md))["events"][0]["label"] == s.event_labels[0]


def test_same_seed_same_stream_and_different_seeds_differ():
    a, b = simulate_stream(8.0, 21), simulate_stream(8.0, 21)
    c = simulate_stream(8.0, 22)
    assert np.array_equal(a.frames, b.frames)
    assert np.array_equal(a.event_start_s, b.event_start_s)
    assert list(a.event_labels) == list(b.event_labels)
    assert not np.array_equal(a.frames, c.frames)


def test_first_second_is_contact_free():
    for seed in (1, 2, 3):
        s = quiet_stream(seed)
        assert s.event_start_s[0] >= 1.0
        first = s.frames[: int(FS)].astype(np.float64)
        # Without noise the skin reads its baseline exactly until something happens.
        assert np.abs(first - first[0]).max() < 1e-4


def test_first_second_is_quiet_with_noise():
    s = stream()
    first = s.frames[: int(FS)].astype(np.float64)
    later = s.frames.astype(np.float64)
    base = np.median(first, axis=0)
    assert np.percentile(np.abs(first - base), 99) < 0.2 * np.abs(later - base).max()


def test_labels_match_the_rendered_contact():
    for seed in (1, 2):
        s = quiet_stream(seed)
        base = s.frames[: int(0.5 * FS)].mean(axis=0)
        activity = np.abs(s.frames - base).max(axis=(1, 2))
        for k, (start, end) in enumerate(zip(s.event_start_s, s.event_end_s, strict=True)):
            i0, i1 = int(round(start * FS)), int(round(end * FS))
            peak = activity[i0:i1].max()
            assert peak > 0.02  # something is sensed (the dullest skins read ~0.04 pF)
            # Above the floor within 60 ms of the first contact ...
            assert activity[i0 : i0 + 12].max() > 0.05 * peak
            # ... quiet shortly before it (hover and the previous event's tail excepted).
            before = i0 - int(0.15 * FS)
            previous_end = int(round(s.event_end_s[k - 1] * FS)) if k else 0
            if before - previous_end > int(0.3 * FS):
                assert activity[before] < 0.05 * peak
            # ... and the contact has faded 0.3 s after the last lift-off.
            after = i1 + int(0.3 * FS)
            nxt = int(round(s.event_start_s[k + 1] * FS)) if k + 1 < len(s.event_labels) else None
            if after < len(activity) and (nxt is None or after < nxt - int(0.15 * FS)):
                assert activity[after] < 0.1 * peak


def test_gestures_are_covered_evenly():
    s = simulate_stream(150.0, 7, invalid_fraction=0.0, idle_s=(0.3, 0.5))
    counts = Counter(s.event_labels)
    assert set(counts) == set(GESTURE_NAMES)
    assert max(counts.values()) - min(counts.values()) <= 1


def test_invalid_fraction_and_gesture_subset():
    only_invalid = simulate_stream(30.0, 8, invalid_fraction=1.0)
    assert set(only_invalid.event_labels) == {INVALID}
    subset = simulate_stream(20.0, 9, gestures=["push", "swipe_up"], invalid_fraction=0.0)
    assert set(subset.event_labels) == {"push", "swipe_up"}
    mixed = stream()
    share = np.mean(mixed.event_labels == INVALID)
    assert 0.05 < share < 0.6


def test_idle_gaps_follow_the_setting():
    s = simulate_stream(40.0, 10, idle_s=(1.0, 1.2))
    gaps = s.event_start_s[1:] - s.event_end_s[:-1]
    assert gaps.min() >= 1.0 - 1e-9 and gaps.max() <= 1.2 + 0.01


def test_given_person_and_physics_are_used_and_small_skins_work():
    person = Person(pace=1.0, person_id="fast-one")
    physics = SkinPhysics(gain_pf=3.0)
    layout = SkinLayout(rows=6, cols=8)
    s = simulate_stream(10.0, 11, layout=layout, physics=physics, person=person)
    assert s.frames.shape == (2000, 6, 8)
    assert s.metadata["person"]["person_id"] == "fast-one"
    assert s.metadata["physics"]["gain_pf"] == 3.0
    assert s.metadata["layout"] == layout.to_dict()


def test_bad_arguments_are_rejected():
    with pytest.raises(ValueError, match="positive"):
        simulate_stream(0.0, 1)
    with pytest.raises(ValueError, match="unknown gesture"):
        simulate_stream(5.0, 1, gestures=["wave"])
    with pytest.raises(ValueError, match="idle_s"):
        simulate_stream(5.0, 1, idle_s=(2.0, 1.0))
    with pytest.raises(ValueError, match="invalid_fraction"):
        simulate_stream(5.0, 1, invalid_fraction=1.5)
    with pytest.raises(ValueError, match="no gestures"):
        simulate_stream(5.0, 1, gestures=[], invalid_fraction=0.0)


def test_requests_parse_names_and_invalid_kinds():
    assert parse_request("swipe_up") == ("swipe_up", None)
    assert parse_request("invalid:palm") == (INVALID, "palm")
    assert parse_request("invalid") == (INVALID, None)
    with pytest.raises(ValueError):
        parse_request("push:hard")
    with pytest.raises(ValueError):
        parse_request("invalid:sneeze")
    scheduler = EventScheduler(np.random.default_rng(0), Person(), SkinLayout())
    perf = scheduler.next_performance("invalid:grasp")
    assert perf.label == INVALID and perf.invalid_kind == "grasp"
