"""Tests of the simulated invalid touches (wovenskin.sim.invalid)."""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest

from wovenskin.gestures import GESTURE_NAMES, INVALID
from wovenskin.sim import spec
from wovenskin.sim.invalid import INVALID_KINDS
from wovenskin.sim.performances import perform
from wovenskin.sim.person import Person
from wovenskin.sim.physics import SkinModel
from wovenskin.sim.skin_physics import SkinPhysics
from wovenskin.skin.layout import SkinLayout

LAYOUT = SkinLayout()
FS = 200.0


SEED = 0  # robustness sweeps may change it


@cache
def examples(kind: str, count: int = 16):
    rng = np.random.default_rng([INVALID_KINDS.index(kind), SEED])
    people = [Person.sample(rng) for _ in range(count)]
    return tuple(perform(INVALID, p, rng, LAYOUT, invalid_kind=kind) for p in people)


def runs(mask: np.ndarray) -> list[int]:
    """Lengths of the runs of True in ``mask``."""
    edges = np.diff(np.concatenate([[0], mask.astype(int), [0]]))
    return list(np.flatnonzero(edges == -1) - np.flatnonzero(edges == 1))


@pytest.mark.parametrize("kind", INVALID_KINDS)
def test_every_kind_is_labelled_and_touches_or_disturbs(kind):
    for perf in examples(kind):
        assert perf.label == INVALID and perf.invalid_kind == kind
        assert perf.event_start_s < perf.event_end_s <= perf.duration_s
        assert perf.event_start_s >= 0.1  # a little hovering first
        if kind == "noise_burst":
            assert not perf.contacts and len(perf.bursts) == 1
        else:
            touching = perf.touching()
            assert touching.any()
            assert perf.event_start_s == pytest.approx(np.flatnonzero(touching)[0] / FS)
            assert perf.event_end_s == pytest.approx((np.flatnonzero(touching)[-1] + 1) / FS)


def test_random_kinds_cover_the_list_and_bad_kinds_fail():
    rng = np.random.default_rng(0)
    kinds = {perform(INVALID, Person(), rng).invalid_kind for _ in range(120)}
    assert kinds == set(INVALID_KINDS)
    with pytest.raises(ValueError, match="unknown invalid kind"):
        perform(INVALID, Person(), rng, invalid_kind="sneeze")


@pytest.mark.parametrize("kind", ["short_tap", "partial_gesture"])
def test_short_contacts_end_before_the_dwell_time(kind):
    gestures = set()
    for perf in examples(kind):
        for c in perf.contacts:
            assert max(runs(c.touching)) < spec.DWELL_S * FS
        gestures.add(perf.params.get("gesture"))
    if kind == "partial_gesture":
        assert gestures <= set(GESTURE_NAMES) and len(gestures) > 5


def test_grasp_puts_four_fingers_on_one_edge_and_the_thumb_on_the_other():
    size = np.array([LAYOUT.width_mm, LAYOUT.height_mm])
    for perf in examples("grasp"):
        names = [c.finger for c in perf.contacts]
        assert "thumb" in names and len(names) >= 4  # a finger may miss a small skin
        centres = {
            c.finger: np.array([c.x_mm[c.touching].mean(), c.y_mm[c.touching].mean()])
            for c in perf.contacts
        }
        thumb = centres.pop("thumb")
        fingers = np.stack(list(centres.values()))
        near = [
            ((fingers[:, axis] < 15).all() and thumb[axis] > size[axis] - 15)
            or ((fingers[:, axis] > size[axis] - 15).all() and thumb[axis] < 15)
            for axis in (0, 1)
        ]
        assert any(near)
        assert sum(c.force_n.max() for c in perf.contacts) > 7.0  # a firm grip


def test_brushing_is_fast_light_and_often_enters_from_off_the_skin():
    entered_from_outside = 0
    for perf in examples("brush"):
        for c in perf.contacts:
            on = np.flatnonzero(c.touching)
            assert c.force_n.max() <= 0.5
            if on.size > 3:
                speed = np.hypot(np.diff(c.x_mm[on]), np.diff(c.y_mm[on])) * FS
                assert np.median(speed) > 250
        first = perf.contacts[0]
        before = np.flatnonzero(~first.touching)[0]
        x, y = first.x_mm[before], first.y_mm[before]
        entered_from_outside += not (0 <= x <= LAYOUT.width_mm and 0 <= y <= LAYOUT.height_mm)
    assert entered_from_outside >= 2


@pytest.mark.parametrize(("kind", "count"), [("three_fingers", 3), ("four_fingers", 4)])
def test_three_and_four_finger_touches(kind, count):
    moving = set()
    for perf in examples(kind):
        touching = np.stack([c.touching for c in perf.contacts])
        assert touching.sum(axis=0).max() == count
        moving.add(perf.params["moving"])
    assert moving == {True, False}


def test_palm_and_forearm_are_large_and_render_over_many_channels():
    physics = SkinPhysics().without_noise()
    for kind, min_axis, min_channels in (("palm", 9.0, 6), ("forearm", 22.0, 15)):
        for perf in examples(kind)[:6]:
            big = [c for c in perf.contacts if c.kind in ("palm", "forearm")]
            assert big and all(c.semi_minor_mm.min() >= min_axis for c in big)
            model = SkinModel(physics, LAYOUT, seed=0)
            d = model.render(perf.contacts, perf.n_frames) - model.baseline_pf
            assert (d.max(axis=0) > 0.05).sum() >= min_channels or _mostly_off_skin(perf)


def _mostly_off_skin(perf) -> bool:
    c = perf.contacts[-1]
    on = c.touching
    inside = (c.x_mm[on] > 0) & (c.x_mm[on] < LAYOUT.width_mm)
    inside &= (c.y_mm[on] > 0) & (c.y_mm[on] < LAYOUT.height_mm)
    return inside.mean() < 0.5


def test_forearm_is_sometimes_preceded_by_the_sleeve():
    sleeves = [p for p in examples("forearm") if any(c.kind == "sleeve" for c in p.contacts)]
    assert sleeves
    for perf in sleeves:
        sleeve = next(c for c in perf.contacts if c.kind == "sleeve")
        arm = next(c for c in perf.contacts if c.kind == "forearm")
        assert np.flatnonzero(sleeve.touching)[0] < np.flatnonzero(arm.touching)[0]


def test_scribbles_wander_on_the_skin():
    for perf in examples("scribble"):
        c = perf.contacts[0]
        on = c.touching
        x, y = c.x_mm[on], c.y_mm[on]
        length = np.hypot(np.diff(x), np.diff(y)).sum()
        chord = np.hypot(x[-1] - x[0], y[-1] - y[0])
        assert length > 1.3 * chord and length > 20
        assert x.min() > 0 and x.max() < LAYOUT.width_mm
        assert y.min() > 0 and y.max() < LAYOUT.height_mm


def test_noise_bursts_last_50_to_300_ms():
    for perf in examples("noise_burst"):
        (burst,) = perf.bursts
        assert 0.05 <= burst.duration_s <= 0.3
        assert perf.event_end_s - perf.event_start_s == pytest.approx(burst.duration_s)
        assert perf.n_frames / FS >= burst.start_s + burst.duration_s


@pytest.mark.parametrize("kind", INVALID_KINDS)
def test_every_kind_renders_on_a_small_skin(kind):
    small = SkinLayout(rows=6, cols=8)
    rng = np.random.default_rng(3)
    perf = perform(INVALID, Person.sample(rng), rng, small, invalid_kind=kind)
    frames = SkinModel(SkinPhysics(), small, seed=1).render(
        perf.contacts, perf.n_frames, perf.bursts
    )
    assert frames.shape == (perf.n_frames, 6, 8) and np.isfinite(frames).all()
