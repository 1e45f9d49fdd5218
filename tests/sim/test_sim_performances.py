"""Tests of how simulated people perform the 14 gestures (wovenskin.sim.performances).

Every quantitative range of GESTURES.md is measured on the generated fingertip tracks
(not on the drawn parameters), for many people and trials, and orientation is also checked
on rendered frames.
"""

from __future__ import annotations

import math
import zlib
from functools import cache

import numpy as np
import pytest

from wovenskin.gestures import GESTURE_NAMES
from wovenskin.sim import spec
from wovenskin.sim.motion import Performance, minimum_jerk, peak_speed_factor
from wovenskin.sim.performances import perform
from wovenskin.sim.person import Person
from wovenskin.sim.physics import SkinModel
from wovenskin.sim.skin_physics import SkinPhysics
from wovenskin.skin.layout import SkinLayout

LAYOUT = SkinLayout()
FS = 200.0
SWIPES = [n for n in GESTURE_NAMES if n.startswith("swipe_")]
DIRECTION = {"up": (0.0, -1.0), "down": (0.0, 1.0), "right": (1.0, 0.0), "left": (-1.0, 0.0)}


@cache
def crowd(count: int = 16, seed: int = 0) -> tuple[Person, ...]:
    rng = np.random.default_rng(seed)
    return tuple(Person.sample(rng) for _ in range(count))


SEED = 0  # tests/robustness sweeps may change it


@cache
def performances(name: str, per_person: int = 2, layout: SkinLayout = LAYOUT):
    rng = np.random.default_rng([zlib.crc32(name.encode()), SEED])
    return tuple(perform(name, p, rng, layout) for p in crowd() for _ in range(per_person))


def xy(track) -> np.ndarray:
    return np.stack([track.x_mm, track.y_mm], axis=1)


def motion_span(perf: Performance) -> tuple[int, int]:
    """First and last frame index of the characteristic motion."""
    return round(perf.phases.motion_start_s * FS), round(perf.phases.motion_end_s * FS) - 1


def centroid(perf: Performance) -> np.ndarray:
    return np.mean([xy(c) for c in perf.fingertips()], axis=0)


# -- swipes -------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", SWIPES)
def test_swipes_honour_travel_speed_angle_and_curvature(name):
    nominal = np.array(DIRECTION[name.removeprefix("swipe_").removesuffix("_2f")])
    for perf in performances(name):
        start, end = motion_span(perf)
        path = centroid(perf)[start : end + 1]
        chord = path[-1] - path[0]
        travel = float(np.linalg.norm(chord))
        duration = (end - start) / FS
        # (tolerances here and below: tremor, sway and finger wander on top of the plan)
        assert spec.SWIPE_TRAVEL_MM[0] - 2.0 <= travel <= spec.SWIPE_TRAVEL_MM[1] + 2.0
        mean_speed = travel / duration
        low, high = spec.SWIPE_MEAN_SPEED_MM_S
        assert 0.96 * low <= mean_speed <= 1.04 * high
        off_axis = math.degrees(math.acos(np.dot(chord, nominal) / travel))
        assert off_axis <= spec.SWIPE_MAX_OFF_AXIS_DEG + 0.5
        normal = np.array([-chord[1], chord[0]]) / travel
        bow = np.abs((path - path[0]) @ normal).max()
        assert bow <= spec.SWIPE_MAX_BOW * travel + 1.0
        kernel = np.ones(5) / 5
        velocity = np.stack(
            [np.convolve(np.gradient(path[:, i]) * FS, kernel, "same") for i in (0, 1)]
        )
        speed = np.linalg.norm(velocity, axis=0)
        assert speed.max() <= spec.SWIPE_PEAK_SPEED_MM_S + 40
        # Bell-shaped: slow at both ends, fastest in the middle.
        peak_at = np.argmax(speed) / max(len(speed) - 1, 1)
        assert 0.2 < peak_at < 0.8
        assert speed[2] < 0.5 * speed.max() and speed[-3] < 0.5 * speed.max()


def test_minimum_jerk_profile_is_bell_shaped():
    s = minimum_jerk(201)
    v = np.diff(s)
    assert s[0] == 0.0 and s[-1] == pytest.approx(1.0)
    assert np.argmax(v) in (99, 100)
    assert peak_speed_factor(0.0) == pytest.approx(1.875, rel=0.01)
    assert np.argmax(np.diff(minimum_jerk(201, -0.2))) < 95  # negative skew peaks early


@pytest.mark.parametrize("name", [n for n in SWIPES if n.endswith("_2f")])
def test_two_finger_swipes_move_a_pair_together(name):
    relations = []
    for perf in performances(name):
        a, b = (xy(c) for c in perf.fingertips())
        start, end = motion_span(perf)
        spacing = np.linalg.norm(a[start] - b[start])
        low, high = spec.PAIR_SPACING_MM
        assert low - 1.5 <= spacing <= high + 1.5
        da, db = a[end] - a[start], b[end] - b[start]
        cos = np.dot(da, db) / (np.linalg.norm(da) * np.linalg.norm(db))
        assert cos > math.cos(math.radians(8))
        pair = (b[start] - a[start]) / spacing
        relations.append(abs(np.dot(pair, da / np.linalg.norm(da))))
    relations = np.degrees(np.arccos(np.clip(relations, 0, 1)))
    # Across (~90 deg), along (~0 deg) and diagonal pairs all occur.
    assert relations.max() > 60 and relations.min() < 45


def row_col(frame: np.ndarray) -> tuple[float, float]:
    """Change-weighted centroid of a frame in (row, col) channel coordinates."""
    rows, cols = np.mgrid[0 : frame.shape[0], 0 : frame.shape[1]]
    w = frame / frame.sum()
    return float((w * rows).sum()), float((w * cols).sum())


@pytest.mark.parametrize("name", ["swipe_up", "swipe_down", "swipe_right_2f", "swipe_left"])
def test_rendered_contact_centroid_moves_the_right_way(name):
    direction = name.removeprefix("swipe_").removesuffix("_2f")
    physics = SkinPhysics().without_noise()
    for perf in performances(name)[:4]:
        model = SkinModel(physics, LAYOUT, seed=0)
        d = model.render(perf.contacts, perf.n_frames).astype(np.float64) - model.baseline_pf
        d = np.clip(d, 0, None)
        start, end = motion_span(perf)
        (r0, c0), (r1, c1) = row_col(d[start]), row_col(d[min(end + 6, perf.n_frames - 1)])
        moved = {"up": r0 - r1, "down": r1 - r0, "right": c1 - c0, "left": c0 - c1}[direction]
        assert moved > 1.5  # channels toward row 0 for "up", higher columns for "right"


# -- circles ------------------------------------------------------------------------------------
def circle_centre(path: np.ndarray) -> np.ndarray:
    """Least-squares (Kasa) centre of the circle through ``path``."""
    a = np.column_stack([2 * path, np.ones(len(path))])
    solution, *_ = np.linalg.lstsq(a, (path**2).sum(axis=1), rcond=None)
    return solution[:2]


def signed_turns(path: np.ndarray) -> float:
    """Turns around the circle's centre; > 0 is clockwise as seen by the user (y down)."""
    rel = path - circle_centre(path)
    angle = np.unwrap(np.arctan2(rel[:, 1], rel[:, 0]))
    return float((angle[-1] - angle[0]) / (2 * np.pi))


@pytest.mark.parametrize("name", ["circle_cw_2f", "circle_ccw_2f"])
def test_circles_turn_the_right_way_within_the_ranges(name):
    clockwise = name == "circle_cw_2f"
    for perf in performances(name):
        start, end = motion_span(perf)
        path = centroid(perf)[start : end + 1]
        rel = path - circle_centre(path)
        velocity = np.gradient(path, axis=0)
        cross = rel[:, 0] * velocity[:, 1] - rel[:, 1] * velocity[:, 0]
        assert (cross.sum() > 0) == clockwise
        turns = signed_turns(path)
        assert (turns > 0) == clockwise
        low, high = spec.CIRCLE_TURNS
        assert low - 0.08 <= abs(turns) <= high + 0.08
        rate = abs(turns) / ((end - start) / FS)
        assert spec.CIRCLE_RATE_HZ[0] - 0.08 <= rate <= spec.CIRCLE_RATE_HZ[1] + 0.08
        radius = np.linalg.norm(rel, axis=1).mean()
        assert spec.CIRCLE_RADIUS_MM[0] - 2.0 <= radius <= spec.CIRCLE_RADIUS_MM[1] + 2.0
        a, b = (xy(c)[start : end + 1] for c in perf.fingertips())
        spacing = np.linalg.norm(b - a, axis=1)
        low, high = spec.CIRCLE_PAIR_SPACING_MM
        assert low - 1.0 <= spacing.mean() <= high + 1.0
        orientation = np.unwrap(np.arctan2(*(b - a).T[::-1]))
        assert np.degrees(orientation.std()) < 12  # the hand keeps its orientation


@pytest.mark.parametrize("name", ["circle_cw_2f", "circle_ccw_2f"])
def test_rendered_circle_has_the_right_sense_in_row_col(name):
    physics = SkinPhysics().without_noise()
    perf = performances(name)[0]
    model = SkinModel(physics, LAYOUT, seed=0)
    d = np.clip(model.render(perf.contacts, perf.n_frames) - model.baseline_pf, 0, None)
    rows, cols = np.mgrid[0 : LAYOUT.rows, 0 : LAYOUT.cols]
    start, end = motion_span(perf)
    w = d[start : end + 1] / d[start : end + 1].sum(axis=(1, 2), keepdims=True)
    path = np.stack([(w * cols).sum(axis=(1, 2)), (w * rows).sum(axis=(1, 2))], axis=1)
    assert (signed_turns(path) > 0.5) == (name == "circle_cw_2f")


# -- pinches -------------------------------------------------------------------------------------
def test_two_finger_pinch_converges_within_the_ranges():
    axes = []
    for perf in performances("pinch_in_2f"):
        a, b = (xy(c) for c in perf.fingertips())
        start, end = motion_span(perf)
        d0, d1 = np.linalg.norm(a[start] - b[start]), np.linalg.norm(a[end] - b[end])
        assert spec.PINCH_2F_START_MM[0] - 1.5 <= d0 <= spec.PINCH_2F_START_MM[1] + 1.5
        assert spec.PINCH_2F_END_MM[0] - 1.5 <= d1 <= spec.PINCH_2F_END_MM[1] + 1.5
        distance = np.linalg.norm(a - b, axis=1)[start : end + 1]
        assert distance[len(distance) // 2] < d0
        axes.append(math.degrees(math.atan2(*(b[start] - a[start])[::-1])) % 180)
    assert np.ptp(axes) > 90  # any orientation


def hand_radius(points: np.ndarray) -> float:
    """Mean distance of fingertip points ``(k, 2)`` from their centroid."""
    return float(np.linalg.norm(points - points.mean(axis=0), axis=1).mean())


@pytest.mark.parametrize("name", ["pinch_in_5f", "pinch_out_5f"])
def test_five_finger_pinches_change_radius_within_the_ranges(name):
    for perf in performances(name):
        tips = np.stack([xy(c) for c in perf.fingertips()])  # (5, T, 2)
        assert len(tips) == 5
        start, end = motion_span(perf)
        first, last = hand_radius(tips[:, start]), hand_radius(tips[:, end])
        spread, bunched = (first, last) if name == "pinch_in_5f" else (last, first)
        assert spec.PINCH_5F_SPREAD_MM[0] - 1.5 <= spread <= spec.PINCH_5F_SPREAD_MM[1] + 1.5
        assert spec.PINCH_5F_BUNCHED_MM[0] - 1.0 <= bunched <= spec.PINCH_5F_BUNCHED_MM[1] + 1.0
        # Hand-like: the thumb opposes the four fingers.
        names = [c.finger for c in perf.fingertips()]
        pts = tips[:, start if name == "pinch_in_5f" else end]
        thumb = pts[names.index("thumb")]
        others = np.mean([p for n, p in zip(names, pts, strict=True) if n != "thumb"], axis=0)
        centre = pts.mean(axis=0)
        u, v = thumb - centre, others - centre
        assert np.dot(u, v) / (np.linalg.norm(u) * np.linalg.norm(v)) < -0.5


# -- push ----------------------------------------------------------------------------------------
def test_push_presses_harder_over_the_ramp_and_barely_moves():
    for perf in performances("push"):
        (tip,) = perf.fingertips()
        start, _ = motion_span(perf)
        ramp = perf.params["ramp_s"]
        assert spec.PUSH_RAMP_S[0] <= ramp <= spec.PUSH_RAMP_S[1]
        held, landing = perf.params["held_force_n"], tip.force_n[start - 1]
        assert held / landing > 1.5
        assert tip.force_n[start + round(0.4 * ramp * FS)] < 0.9 * held  # still rising
        assert tip.force_n[start + round(ramp * FS)] > 0.85 * held  # and then held
        touching = tip.touching
        pos = xy(tip)[touching]
        assert np.linalg.norm(pos - pos[0], axis=1).max() < spec.PUSH_MAX_MOTION_MM
        pressed = tip.force_n >= 0.9 * held
        assert tip.semi_minor_mm[pressed].mean() > tip.semi_minor_mm[touching][:3].mean()


def test_push_force_rises_over_exactly_the_ramp_without_wobble():
    rng = np.random.default_rng(2)
    for pace in (0.0, 0.5, 1.0):
        perf = perform("push", Person(pace=pace, force_wobble=0.0, consistency=0.5), rng)
        (tip,) = perf.fingertips()
        start, _ = motion_span(perf)
        held = perf.params["held_force_n"]
        rising = np.flatnonzero(np.diff(tip.force_n[start - 1 :]) > 1e-3 * held)
        rise_s = (rising[-1] + 1 - rising[0]) / FS
        assert spec.PUSH_RAMP_S[0] - 0.011 <= rise_s <= spec.PUSH_RAMP_S[1] + 0.011


# -- what all gestures share ------------------------------------------------------------------
@pytest.mark.parametrize("name", GESTURE_NAMES)
def test_contacts_ramp_patches_rest_and_stay_on_the_skin(name):
    low_patch, high_patch = spec.FINGERTIP_PATCH_MM
    for perf in performances(name):
        assert perf.label == name and perf.invalid_kind is None
        expected_fingers = {"pinch_in_5f": 5, "pinch_out_5f": 5}.get(
            name, 2 if ("2f" in name) else 1
        )
        assert len(perf.fingertips()) == expected_fingers == len(perf.contacts)
        first = min(np.flatnonzero(c.touching)[0] for c in perf.contacts)
        last = max(np.flatnonzero(c.touching)[-1] for c in perf.contacts)
        assert perf.event_start_s == pytest.approx(first / FS)
        assert perf.event_end_s == pytest.approx((last + 1) / FS)
        rest = perf.phases.lift_start_s - perf.phases.motion_end_s
        assert -0.045 <= rest <= spec.REST_S[1] + 0.01
        for c in perf.contacts:
            on = np.flatnonzero(c.touching)
            assert np.all(np.diff(on) == 1)  # one contact per finger
            assert 2 * c.semi_minor_mm[on].min() >= low_patch - 1e-9
            assert 2 * c.semi_major_mm[on].max() <= high_patch + 1e-9
            margin = spec.SKIN_MARGIN_MM - 0.8
            assert c.x_mm[on].min() >= margin and c.x_mm[on].max() <= LAYOUT.width_mm - margin
            assert c.y_mm[on].min() >= margin and c.y_mm[on].max() <= LAYOUT.height_mm - margin
            if name == "push":
                continue
            force = c.force_n[on]
            typical = np.median(force)
            ramp_in = np.argmax(force >= 0.4 * typical)
            ramp_out = np.argmax(force[::-1] >= 0.4 * typical)
            limit = spec.CONTACT_RAMP_S[1] * FS + 1
            assert 1 <= ramp_in <= limit and 1 <= ramp_out <= limit


def test_resting_fingers_are_steady():
    rested = 0
    for name in ("swipe_up", "swipe_left_2f", "circle_cw_2f", "pinch_out_5f"):
        for perf in performances(name):
            start = round(perf.phases.rest_start_s * FS) + 10
            stop = round(perf.phases.lift_start_s * FS) - 2
            if stop - start < 0.2 * FS:
                continue
            rested += 1
            for c in perf.contacts:
                pos = xy(c)[start:stop]
                assert np.ptp(pos, axis=0).max() < 3.0
                force = c.force_n[start:stop]
                assert force.std() / force.mean() < 0.15
    assert rested >= 10


def test_unknown_names_are_rejected():
    with pytest.raises(ValueError, match="unknown gesture"):
        perform("wave", Person(), np.random.default_rng(0))
    with pytest.raises(ValueError, match="invalid_kind"):
        perform("push", Person(), np.random.default_rng(0), invalid_kind="palm")


def test_same_seed_same_performance():
    a = perform("circle_ccw_2f", Person(), np.random.default_rng(7))
    b = perform("circle_ccw_2f", Person(), np.random.default_rng(7))
    for ca, cb in zip(a.contacts, b.contacts, strict=True):
        assert np.array_equal(ca.x_mm, cb.x_mm) and np.array_equal(ca.force_n, cb.force_n)


@pytest.mark.parametrize("name", GESTURE_NAMES)
def test_every_gesture_fits_a_small_skin(name):
    small = SkinLayout(rows=6, cols=8)
    rng = np.random.default_rng(1)
    model = SkinModel(SkinPhysics(), small, seed=0)
    for person in crowd()[:4]:
        perf = perform(name, person, rng, small)
        for c in perf.contacts:
            on = c.touching
            assert on.any()
            margin = spec.SKIN_MARGIN_MM - 0.8
            assert margin <= c.x_mm[on].min() and c.x_mm[on].max() <= small.width_mm - margin
            assert margin <= c.y_mm[on].min() and c.y_mm[on].max() <= small.height_mm - margin
        frames = model.render(perf.contacts, perf.n_frames)
        assert frames.shape == (perf.n_frames, 6, 8)


# -- diversity ------------------------------------------------------------------------------------
def test_performances_are_diverse_across_people():
    rng = np.random.default_rng(11)
    speeds, travels, starts, durations, forces = [], [], [], [], []
    for person in crowd(40, seed=3):
        perf = perform("swipe_right", person, rng)
        start, end = motion_span(perf)
        path = centroid(perf)
        travel = np.linalg.norm(path[end] - path[start])
        travels.append(travel)
        speeds.append(travel / ((end - start) / FS))
        starts.append(path[start])
        durations.append(perf.event_end_s - perf.event_start_s)
        forces.append(np.median(perf.contacts[0].force_n[perf.contacts[0].touching]))
    low, high = spec.SWIPE_MEAN_SPEED_MM_S
    assert np.ptp(speeds) > 0.6 * (high - low)
    assert np.ptp(travels) > 25
    assert np.std(np.array(starts)[:, 1]) > 10  # people swipe at different heights
    assert np.ptp(durations) > 0.8
    assert max(forces) / min(forces) > 3
