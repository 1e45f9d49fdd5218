"""Tests of the performance building blocks (wovenskin.sim.motion)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wovenskin.sim.motion import (
    FingerMotion,
    assemble_hand,
    contact_envelope,
    fit_onto_skin,
    fold_into_box,
    largest_fitting_scale,
    rotate,
    smooth_noise,
)
from wovenskin.sim.person import Person, Trial
from wovenskin.skin.layout import SkinLayout

FS = 200.0


def test_contact_envelope_ramps_and_cuts():
    env = contact_envelope(40, land=5, ramp_in=4, lift=20, ramp_out=3)
    assert (env[:5] == 0).all() and (env[5:9] > 0).all() and (env[5:9] < 1).all()
    assert (env[9:20] == 1).all()
    assert (env[20:23] > 0).all() and (env[23:] == 0).all()
    assert (np.diff(env[5:10]) > 0).all() and (np.diff(env[19:24]) < 0).all()
    cut = contact_envelope(40, land=5, ramp_in=10, lift=8, ramp_out=3)
    assert cut.max() < 1 and (cut[11:] == 0).all()


@settings(max_examples=30, deadline=None)
@given(n=st.integers(5, 600), low=st.floats(0.2, 5.0), width=st.floats(0.5, 10.0))
def test_smooth_noise_is_band_limited_and_scaled(n, low, width):
    rng = np.random.default_rng(n)
    x = smooth_noise(rng, n, FS, (low, low + width), 0.5)
    assert x.shape == (n,) and np.isfinite(x).all()
    assert np.abs(x).max() < 6 * 0.5  # no blow-up of short slices
    long = smooth_noise(rng, 8000, FS, (8.0, 12.0), 1.0)
    spectrum = np.abs(np.fft.rfft(long)) ** 2
    freq = np.fft.rfftfreq(8000, 1 / FS)
    assert spectrum[(freq >= 8) & (freq <= 12)].sum() > 0.99 * spectrum.sum()
    assert long.std() == pytest.approx(1.0, rel=0.05)


def test_rotate_is_clockwise_on_screen():
    up = np.array([0.0, -1.0])
    right = rotate(up, np.pi / 2)
    assert right == pytest.approx([1.0, 0.0])


def test_fit_onto_skin_moves_and_only_shrinks_when_needed():
    layout = SkinLayout()
    path = np.stack([np.linspace(0, 40, 10), np.zeros(10)], axis=1)
    (placed,), scale = fit_onto_skin([path], layout, np.array([500.0, -500.0]))
    assert scale == 1.0
    assert placed[:, 0].max() <= layout.width_mm - 8.5 + 1e-9 and placed[:, 1].min() >= 8.5 - 1e-9
    huge = path * 5
    (placed,), scale = fit_onto_skin([huge], layout, np.array([50.0, 70.0]))
    assert scale < 1.0
    assert placed[:, 0].min() >= 8.5 - 1e-9 and placed[:, 0].max() <= layout.width_mm - 8.5 + 1e-9
    unit = np.array([[0.0, 0.0], [1.0, 0.0]])
    k = largest_fitting_scale(unit, np.array([20.0, 0.0]), layout)
    assert k == pytest.approx(layout.width_mm - 17.0 - 20.0)


def test_fold_into_box_keeps_paths_inside_and_continuous():
    low, high = np.array([0.0, 0.0]), np.array([10.0, 20.0])
    path = np.stack([np.linspace(-35, 47, 500), np.linspace(5, 90, 500)], axis=1)
    folded = fold_into_box(path, low, high)
    assert (folded >= low - 1e-9).all() and (folded <= high + 1e-9).all()
    assert np.abs(np.diff(folded, axis=0)).max() <= np.abs(np.diff(path, axis=0)).max() + 1e-9


def test_assemble_hand_builds_phases_in_order():
    trial = Trial(Person(finger_async_s=0.03), np.random.default_rng(0))
    path = np.stack([np.linspace(30, 60, 50), np.full(50, 70.0)], axis=1)
    perf = assemble_hand(
        trial,
        [FingerMotion("index", path), FingerMotion("middle", path + [0.0, 18.0])],
        FS,
        label="swipe_right_2f",
        settle_s=0.05,
        rest_s=0.4,
    )
    ph = perf.phases
    assert 0 < ph.landing_s < ph.motion_start_s < ph.motion_end_s <= ph.rest_start_s
    assert ph.rest_start_s < ph.lift_start_s < ph.lift_end_s < perf.duration_s
    assert ph.lift_start_s - ph.motion_end_s == pytest.approx(0.4, abs=0.011)
    assert ph.motion_end_s - ph.motion_start_s == pytest.approx(50 / FS)
    index = perf.contacts[0]
    start = round(ph.motion_start_s * FS)
    assert index.x_mm[start] == pytest.approx(30.0, abs=1.5)
    assert index.x_mm[start + 49] == pytest.approx(60.0, abs=1.5)
