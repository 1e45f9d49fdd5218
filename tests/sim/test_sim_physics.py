"""Tests of the simulated skin's physics (wovenskin.sim.physics)."""

from __future__ import annotations

import math
from dataclasses import fields, replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wovenskin.sim.contact import ContactTrack, NoiseBurst, hertz_pressure_kpa
from wovenskin.sim.physics import LIFT_HOVER_TAU_S, SkinModel
from wovenskin.sim.skin_physics import TYPICAL_GAIN_PF, SkinPhysics
from wovenskin.skin.layout import SkinLayout

LAYOUT = SkinLayout()
FS = 200.0


def quiet(**changes) -> SkinPhysics:
    """Default skin without random disturbances, no crosstalk, creep or fringe field."""
    base = replace(
        SkinPhysics().without_noise(),
        row_crosstalk=0.0,
        col_crosstalk=0.0,
        creep_fraction=0.0,
        proximity_fraction=0.0,
    )
    return replace(base, **changes)


def finger(
    n: int, x: float, y: float, force: float, width: float = 10.0, start: int = 0
) -> ContactTrack:
    f = np.zeros(n)
    f[start:] = force
    return ContactTrack(np.full(n, x), np.full(n, y), f, width / 2, width / 2)


def change(model: SkinModel, contacts, n: int) -> np.ndarray:
    return model.render(contacts, n).astype(np.float64) - model.baseline_pf


def channel_centre(row: int, col: int) -> tuple[float, float]:
    x, y = LAYOUT.rc_to_mm(row, col)
    return float(x), float(y)


# -- parameters ------------------------------------------------------------------------------
def test_sample_draws_every_parameter_within_its_range():
    rng = np.random.default_rng(0)
    skins = [SkinPhysics.sample(rng) for _ in range(200)]
    for f in fields(SkinPhysics):
        low, high = f.metadata["range"]
        values = np.array([getattr(s, f.name) for s in skins])
        assert values.min() >= low - 1e-12 and values.max() <= high + 1e-12, f.name
        assert f.metadata["doc"] and f.metadata["unit"], f.name
    gains = np.array([s.gain_pf for s in skins])
    assert gains.max() / gains.min() > 2.5  # one skin can read well over 2x another
    mains = np.array([s.mains_hz for s in skins])
    assert ((abs(mains - 50) < 0.3) | (abs(mains - 60) < 0.3)).all()
    assert (abs(mains - 50) < 0.3).any() and (abs(mains - 60) < 0.3).any()


def test_dict_round_trip_and_bad_values():
    skin = SkinPhysics.sample(np.random.default_rng(1))
    assert SkinPhysics.from_dict(skin.to_dict()) == skin
    with pytest.raises(ValueError, match="skin physics: unknown setting 'gain'"):
        SkinPhysics.from_dict({"gain": 1.0})
    with pytest.raises(ValueError, match="gain_pf"):
        SkinPhysics(gain_pf=-1.0)
    with pytest.raises(ValueError, match="noise_pf"):
        SkinPhysics(noise_pf=float("nan"))
    assert "pressure_scale_kpa" in SkinPhysics.describe()


def test_contact_track_validation():
    with pytest.raises(ValueError, match="NaN"):
        ContactTrack(np.array([np.nan]), np.zeros(1), np.ones(1), 5.0, 5.0)
    with pytest.raises(ValueError, match="shape"):
        ContactTrack(np.zeros(3), np.zeros(2), np.ones(3), 5.0, 5.0)
    with pytest.raises(ValueError, match=">= 0"):
        ContactTrack(np.zeros(2), np.zeros(2), -np.ones(2), 5.0, 5.0)
    with pytest.raises(ValueError, match="semi-axes"):
        ContactTrack(np.zeros(2), np.zeros(2), np.ones(2), 4.0, 5.0)
    with pytest.raises(ValueError, match="kind"):
        ContactTrack(np.zeros(2), np.zeros(2), np.ones(2), 5.0, 5.0, kind="elbow")
    model = SkinModel(quiet())
    with pytest.raises(TypeError, match="ContactTrack"):
        model.render([{"x": 1}], 3)


# -- contact mechanics -------------------------------------------------------------------------
def test_hertz_profile_integrates_to_the_force():
    step = 0.05
    grid = np.arange(-8, 8, step) + step / 2
    dx, dy = np.meshgrid(grid, grid)
    p = hertz_pressure_kpa(dx, dy, 6.0, 4.0, 0.7, 2.0)
    force_n = p.sum() * step * step / 1000.0  # kPa * mm^2 = mN
    assert force_n == pytest.approx(2.0, rel=0.01)
    assert p.max() == pytest.approx(1.5e3 * 2.0 / (math.pi * 24.0), rel=0.01)


def test_response_rises_monotonically_and_saturates_with_pressure():
    model = SkinModel(quiet(), LAYOUT)
    x, y = channel_centre(4, 5)
    forces = np.geomspace(0.05, 200.0, 40)
    track = ContactTrack(np.full(40, x), np.full(40, y), forces, 6.0, 6.0)
    response = model.pressure_response([track], 40)[:, 4, 5]
    assert np.all(np.diff(response) > 0)
    assert response[-1] < 1.0
    # Saturation: the response grows ever more slowly with force.
    increments = np.diff(response) / np.diff(np.log(forces))
    assert increments[-5:].mean() < 0.35 * increments[:5].mean()
    # A 12 mm patch pressing ~100 kPa peak is close to saturation under the patch.
    local = 1 - math.exp(-100.0 / model.physics.pressure_scale_kpa)
    assert local > 0.9


def test_larger_patch_spreads_over_more_channels():
    model = SkinModel(quiet(), LAYOUT)
    x, y = channel_centre(4, 4)
    x, y = x + 5.0, y + 7.0  # on the corner of four channels
    counts = []
    for width in (8.0, 11.0, 14.0, 30.0):
        r = model.pressure_response([finger(1, x, y, 1.0, width)], 1)[0]
        counts.append(int((r > 1e-3).sum()))
    assert counts == sorted(counts) and counts[-1] > counts[0]


def test_sliding_fingertip_gives_a_smooth_total_signal():
    model = SkinModel(quiet(channel_edge_sensitivity=1.0), LAYOUT)
    n = 300
    track = ContactTrack(
        np.linspace(20, 80, n), np.linspace(30, 110, n), np.full(n, 1.0), 5.0, 4.5, 0.3
    )
    total = model.pressure_response([track], n).sum(axis=(1, 2))
    assert total.std() / total.mean() < 0.03  # little sampling ripple


def test_contact_between_channels_is_shared_and_off_skin_is_invisible():
    model = SkinModel(quiet(), LAYOUT)
    x, y = channel_centre(3, 3)
    r = model.pressure_response([finger(1, x + 5.0, y, 1.5)], 1)[0]
    assert r[3, 3] == pytest.approx(r[3, 4], rel=0.05)
    off = model.pressure_response([finger(1, -20.0, 50.0, 3.0)], 1)[0]
    assert not off.any()
    half = model.pressure_response([finger(1, 0.0, 49.0, 3.0)], 1)[0]
    inside = model.pressure_response([finger(1, 6.0, 49.0, 3.0)], 1)[0]
    assert 0 < half.sum() < inside.sum()


def test_gain_scales_the_whole_response_and_channels_differ():
    x, y = channel_centre(5, 5)
    track = [finger(60, x, y, 1.0, start=10)]
    low = change(SkinModel(quiet(gain_pf=2.0), LAYOUT, seed=4), track, 60)
    high = change(SkinModel(quiet(gain_pf=4.0), LAYOUT, seed=4), track, 60)
    assert high[-1, 5, 5] == pytest.approx(2 * low[-1, 5, 5], rel=1e-4)
    model = SkinModel(quiet(channel_gain_spread=0.2, baseline_spread=0.25), LAYOUT, seed=4)
    gains = model.channel_gain_pf / model.physics.gain_pf
    assert 0.1 < gains.std() < 0.3
    spread = model.baseline_pf.std() / model.baseline_pf.mean()
    assert 0.15 < spread < 0.4


def test_gain_gradient_and_dead_channels():
    model = SkinModel(quiet(gain_gradient=0.3, channel_gain_spread=0.0), LAYOUT, seed=2)
    ratio = model.channel_gain_pf / model.physics.gain_pf
    assert ratio.min() == pytest.approx(0.7, abs=0.05) and ratio.max() == pytest.approx(
        1.3, abs=0.05
    )
    model = SkinModel(quiet(dead_channel_fraction=0.5), LAYOUT, seed=2)
    dead = model.channel_gain_pf < 0.2 * model.physics.gain_pf
    assert 0.3 < dead.mean() < 0.7


def test_mechanical_lag_follows_the_time_constant():
    tau = 0.02
    model = SkinModel(quiet(mechanical_tau_s=tau), LAYOUT)
    x, y = channel_centre(5, 5)
    d = change(model, [finger(40, x, y, 1.0, start=10)], 40)[:, 5, 5]
    final = d[-1]
    after_tau = d[10 + int(round(tau * FS)) - 1]
    assert after_tau / final == pytest.approx(1 - math.exp(-1), abs=0.06)
    assert np.abs(d[:10]).max() < 1e-5  # float32 rounding only


def test_creep_leaves_a_slowly_decaying_tail():
    model = SkinModel(quiet(creep_fraction=0.1, creep_tau_s=0.5), LAYOUT)
    x, y = channel_centre(5, 5)
    f = np.zeros(300)
    f[10:150] = 1.0
    track = ContactTrack(np.full(300, x), np.full(300, y), f, 5.0, 5.0)
    d = change(model, [track], 300)[:, 5, 5]
    peak = d[149]
    assert 0.02 * peak < d[150 + 40] < 0.12 * peak  # 0.2 s after lift-off
    assert d[150 + 40] > d[150 + 100] > 0


def test_crosstalk_leaks_along_the_row_and_column_only():
    x, y = channel_centre(2, 3)
    track = [finger(30, x, y, 2.0, width=8.0)]
    clean = change(SkinModel(quiet(), LAYOUT), track, 30)[-1]
    leaky = change(SkinModel(quiet(row_crosstalk=0.04, col_crosstalk=0.02), LAYOUT), track, 30)[-1]
    leak = leaky - clean
    assert leak[2, 8] == pytest.approx(0.04 * clean[2].sum(), rel=0.05)  # far along the row
    assert leak[8, 3] == pytest.approx(0.02 * clean[:, 3].sum(), rel=0.05)  # down the column
    assert abs(leak[8, 8]) < 1e-6  # neither row nor column
    assert leak[2, 8] > 0.03 * clean[2, 3]


def test_proximity_is_felt_before_landing_and_around_the_contact():
    model = SkinModel(quiet(proximity_fraction=0.05, hover_tau_s=0.04), LAYOUT)
    x, y = channel_centre(5, 5)
    d = change(model, [finger(60, x, y, 1.0, start=30)], 60)
    assert d[26, 5, 5] > 0.002 * model.physics.gain_pf  # hand approaching, not yet touching
    assert d[0, 5, 5] < d[20, 5, 5] < d[26, 5, 5]
    assert d[-1, 5, 7] > 0  # fringe field two columns away


def test_a_lifted_fingertip_fades_within_a_few_milliseconds():
    """A finger slows down as it approaches but accelerates away when it lifts: the hand is
    sensed tens of milliseconds before landing, a lifted fingertip for a few only."""
    model = SkinModel(quiet(proximity_fraction=0.05, hover_tau_s=0.06), LAYOUT)
    x, y = channel_centre(5, 5)
    track = finger(80, x, y, 1.0, start=30)
    track.force_n[40:] = 0.0  # lands at frame 30, lifts at frame 40
    proximity = change(model, [track], 80)[:, 5, 7]  # two columns away: fringe field only
    assert proximity[24] > 0.5 * proximity[29]  # 30 ms before landing: still well sensed
    assert proximity[44] < 0.03 * proximity[39]  # 25 ms after the lift: gone
    assert LIFT_HOVER_TAU_S <= 0.01


def test_proximity_can_lower_the_reading_in_a_mutual_capacitance_skin():
    model = SkinModel(quiet(proximity_fraction=-0.015, hover_tau_s=0.04), LAYOUT)
    x, y = channel_centre(5, 5)
    d = change(model, [finger(60, x, y, 1.0, start=30)], 60)
    assert d[26, 5, 5] < 0  # the hovering hand shunts the field
    assert d[-1, 5, 5] > 0  # pressing still increases the capacitance


# -- noise ---------------------------------------------------------------------------------------
def test_white_noise_level_matches_the_parameter():
    physics = replace(SkinPhysics().without_noise(), noise_pf=0.02)
    frames = SkinModel(physics, LAYOUT, seed=2).render_idle(2000).astype(np.float64)
    sd = frames.std(axis=0)
    assert np.median(sd) == pytest.approx(0.02, rel=0.15)


@pytest.mark.parametrize("mains_hz", [50.0, 60.0])
def test_mains_pickup_appears_at_the_mains_frequency(mains_hz):
    physics = replace(SkinPhysics().without_noise(), mains_pf=0.02, mains_hz=mains_hz)
    model = SkinModel(physics, LAYOUT, seed=3)
    frames = model.render_idle(2000).astype(np.float64)
    signal = frames[:, 4, 4] - frames[:, 4, 4].mean()
    spectrum = np.abs(np.fft.rfft(signal))
    freq = np.fft.rfftfreq(signal.size, 1 / FS)
    assert freq[np.argmax(spectrum)] == pytest.approx(mains_hz, abs=0.5)
    # Channels are scanned at different times within the scan: their phases differ.
    a, b = frames[:, 0, 0] - frames[:, 0, 0].mean(), frames[:, 9, 9] - frames[:, 9, 9].mean()
    corr = np.corrcoef(a, b)[0, 1]
    assert corr < 0.9999


def test_drift_is_slow_and_of_the_stated_size():
    physics = replace(
        SkinPhysics().without_noise(), drift_common_per_min=0.005, drift_channel_per_min=0.0
    )
    model = SkinModel(physics, LAYOUT, seed=5)
    steps = []
    for _ in range(40):  # 40 independent minutes, one frame per minute end
        start = model.render_idle(1)[0, 0, 0]
        model.render_idle(int(60 * FS) - 2)
        end = model.render_idle(1)[0, 0, 0]
        steps.append((end - start) / model.baseline_pf[0, 0])
    rms = float(np.sqrt(np.mean(np.square(steps))))
    assert 0.0025 < rms < 0.009


def test_drift_is_smooth_on_the_scale_of_frames():
    physics = replace(
        SkinPhysics().without_noise(), drift_common_per_min=0.01, drift_channel_per_min=0.004
    )
    model = SkinModel(physics, LAYOUT, seed=11)
    x = model.render_idle(int(120 * FS)).astype(np.float64) / model.baseline_pf
    per_block = np.sqrt(np.mean((x[20:] - x[:-20]) ** 2))  # rms change over 0.1 s
    per_minute = np.sqrt(np.mean((x[int(60 * FS) :] - x[: -int(60 * FS)]) ** 2))
    # A random walk would change by sqrt(0.1 / 60) = 4 % of the minute's change in 0.1 s.
    assert per_block < 0.01 * per_minute


def test_a_light_touch_is_visible_even_on_the_weakest_skin():
    def peak(physics: SkinPhysics, force: float) -> float:
        model = SkinModel(physics, LAYOUT, seed=12)
        x, y = channel_centre(4, 4)
        relative = change(model, [finger(200, x, y, force, width=9.0)], 200) / model.baseline_pf
        return float(relative[-1].max())

    typical = quiet()
    assert 0.025 < peak(typical, 1.0) < 0.06  # several percent under a 1 N press
    assert 0.007 < peak(typical, 0.25) < 0.02  # about 1 % under a light touch
    weakest = replace(
        quiet(),
        c0_pf=30.0,
        gain_pf=3.0,
        pressure_scale_kpa=45.0,
        channel_edge_sensitivity=0.5,
        proximity_fraction=-0.015,
    )
    # Every weak corner of the ranges at once, the lightest touch: hard, but above the
    # 0.2 % contact floor of signal conditioning and far above the noise of any skin.
    assert peak(weakest, 0.25) > 0.0025


def test_glitches_are_single_frame_single_channel_spikes():
    physics = replace(SkinPhysics().without_noise(), glitch_rate_hz=5.0, glitch_pf=3.0)
    model = SkinModel(physics, LAYOUT, seed=6)
    d = np.abs(model.render_idle(2000).astype(np.float64) - model.baseline_pf)
    spikes = np.argwhere(d > 0.3)
    assert 20 < len(spikes) < 100
    for t, _, _ in spikes[:20]:
        assert (d[t] > 0.3).sum() <= 2  # one channel (rarely two coincide)


def test_noise_burst_covers_many_channels_for_its_duration_only():
    physics = replace(SkinPhysics().without_noise(), burst_pf=0.5)
    model = SkinModel(physics, LAYOUT, seed=7)
    burst = NoiseBurst(start_s=0.5, duration_s=0.2, strength=1.0, line_fraction=0.8)
    d = model.render((), 200, [burst]).astype(np.float64) - model.baseline_pf
    inside = np.abs(d[105:135]).max(axis=0)
    assert (inside > 0.05).mean() > 0.5
    assert np.abs(d[:95]).max() < 1e-5 and np.abs(d[145:]).max() < 1e-5


def test_quantisation_and_firmware_average():
    physics = replace(SkinPhysics(), adc_lsb_pf=0.004, firmware_average_s=0.05)
    frames = SkinModel(physics, LAYOUT, seed=8).render_idle(400).astype(np.float64)
    steps = frames / 0.004
    assert np.allclose(steps, np.round(steps), atol=1e-3)
    raw = SkinModel(replace(physics, firmware_average_s=0.0), LAYOUT, seed=8).render_idle(400)
    assert frames.std(axis=0).mean() < 0.7 * raw.astype(np.float64).std(axis=0).mean()


# -- rendering -------------------------------------------------------------------------------------
def test_firmware_average_starts_from_the_skin_at_rest():
    # The device was averaging before the host connected: the first frames are no copy
    # of the first raw reading (its mains and noise would decay over the window, which
    # once looked like a touch during calibration).
    physics = replace(SkinPhysics(), mains_pf=0.04, mains_spread=0.8, firmware_average_s=0.1)
    frames = SkinModel(physics, LAYOUT, seed=13).render_idle(400).astype(np.float64)
    raw = SkinModel(replace(physics, firmware_average_s=0.0), LAYOUT, seed=13).render_idle(1)
    rest = frames[200:].mean(axis=0)
    start_error = np.abs(frames[:20] - rest).max(axis=0)
    raw_error = np.abs(raw[0] - rest)
    assert (start_error < 0.2 * raw_error.max()).all()
    assert start_error.max() < 1.5 * np.abs(frames[200:] - rest).max()


def test_render_is_deterministic_for_a_seed():
    physics = SkinPhysics.sample(np.random.default_rng(9))
    x, y = channel_centre(3, 6)
    track = [finger(100, x, y, 1.0, start=20)]
    a = SkinModel(physics, LAYOUT, seed=11).render(track, 100)
    b = SkinModel(physics, LAYOUT, seed=11).render(track, 100)
    c = SkinModel(physics, LAYOUT, seed=12).render(track, 100)
    assert a.dtype == np.float32 and a.shape == (100, 10, 10)
    assert np.array_equal(a, b) and not np.array_equal(a, c)


def test_rendering_in_chunks_continues_the_state():
    physics = replace(
        SkinPhysics().without_noise(), mains_pf=0.02, creep_fraction=0.1, firmware_average_s=0.03
    )
    n = 240
    t = np.arange(n)
    x = 20 + 60 * t / n
    f = np.where((t > 30) & (t < 200), 1.2, 0.0)
    track = ContactTrack(x, np.full(n, 70.0), f, 5.5, 4.5, 0.3)
    whole = SkinModel(physics, LAYOUT, seed=1).render([track], n)
    model = SkinModel(physics, LAYOUT, seed=1)
    pieces = [model.render([track], k, offset=o) for o, k in ((0, 50), (50, 17), (67, 173))]
    assert np.allclose(np.concatenate(pieces), whole, atol=1e-5)
    assert model.frames_rendered == n and model.time_s == pytest.approx(n / FS)


def test_any_grid_size_renders():
    layout = SkinLayout(rows=6, cols=8, row_pitch_mm=12.0, col_pitch_mm=9.0)
    model = SkinModel(SkinPhysics(), layout, seed=0)
    frames = model.render([finger(20, 30.0, 30.0, 1.0)], 20)
    assert frames.shape == (20, 6, 8)
    assert np.isfinite(frames).all()


@settings(max_examples=40, deadline=None)
@given(
    x=st.floats(-30, 130),
    y=st.floats(-30, 170),
    force=st.floats(0.0, 50.0),
    a=st.floats(4.0, 60.0),
    ratio=st.floats(0.2, 1.0),
    angle=st.floats(-4.0, 4.0),
)
def test_response_is_bounded_for_any_contact(x, y, force, a, ratio, angle):
    model = SkinModel(quiet(), LAYOUT)
    track = ContactTrack(np.full(2, x), np.full(2, y), np.full(2, force), a, a * ratio, angle)
    r = model.pressure_response([track], 2)
    assert np.isfinite(r).all() and r.min() >= 0.0
    assert r.max() <= model._sub_weight.max() + 1e-9


def test_an_explicit_presence_renders_like_the_one_derived_from_the_force():
    physics = replace(SkinPhysics().without_noise(), proximity_fraction=0.05)
    n, hover = 60, physics.hover_tau_s * FS
    lift = LIFT_HOVER_TAU_S * FS  # a lifted fingertip fades faster than one approaches
    force = np.zeros(n)
    force[20:40] = 1.0
    x, y = np.full(n, 45.0), np.full(n, 63.0)
    derived = ContactTrack(x, y, force, 5.0, 4.0)
    frames = np.arange(n)
    before = np.exp(-np.maximum(20 - frames, 0) / hover)
    after = np.exp(-np.maximum(frames - 39, 0) / lift)
    explicit = ContactTrack(x, y, force, 5.0, 4.0, presence=np.minimum(before, after))
    a = SkinModel(physics, LAYOUT, seed=3).render([derived], n)
    b = SkinModel(physics, LAYOUT, seed=3).render([explicit], n)
    np.testing.assert_allclose(a, b, atol=1e-6)
    rest = SkinModel(physics, LAYOUT, seed=3).render([], n)
    assert (b[15] - rest[15]).max() > 0  # sensed before landing: the fringe field
    none = ContactTrack(x, y, force, 5.0, 4.0, presence=np.zeros(n))
    c = SkinModel(physics, LAYOUT, seed=3).render([none], n)
    np.testing.assert_allclose(c[:20], rest[:20], atol=1e-6)  # no presence: nothing before


@pytest.mark.parametrize("presence", [np.full(5, 1.5), np.full(4, 0.5), np.full(5, np.nan)])
def test_a_bad_presence_is_refused(presence):
    with pytest.raises(ValueError, match="presence"):
        ContactTrack(np.zeros(5), np.zeros(5), np.ones(5), 5.0, 4.0, presence=presence)


def test_field_spread_widens_a_fingertip_as_a_gaussian_blur_would():
    from scipy.ndimage import gaussian_filter

    base = SkinPhysics().without_noise()
    press = ContactTrack(np.full(3, 45.0), np.full(3, 63.0), np.full(3, 1.0), 5.0, 5.0)
    footprint = {}
    for spread in (0.0, 7.0):
        model = SkinModel(replace(base, field_spread_mm=spread), seed=1)
        frame = model.pressure_response([press], 3)[1]
        footprint[spread] = int((frame > 0.25 * frame.max()).sum())
    assert footprint[0.0] == 1 and footprint[7.0] >= 3  # 1 channel -> 3-4 channels

    # The separable product equals a Gaussian filter of the supersampled response.
    sharp = SkinModel(base, seed=1)
    spread = SkinModel(replace(base, field_spread_mm=4.0), seed=1)
    track = ContactTrack(np.full(3, 37.0), np.full(3, 50.0), np.full(3, 1.5), 6.0, 5.0)
    py, px, s = sharp._py, sharp._px, sharp.supersample
    image = np.zeros(3 * py * px + 1)
    sharp._splat(track, 0, 3, np.arange(3), image)
    local = -np.expm1(-image[:-1].reshape(3, py, px)[1] / base.pressure_scale_kpa)
    blurred = gaussian_filter(local, sigma=(4.0 / sharp._dy, 4.0 / sharp._dx), mode="constant")
    rows, cols = sharp.layout.shape
    expected = (blurred.reshape(rows, s, cols, s) * sharp._sub_weight[:, None, :]).mean(axis=(1, 3))
    got = spread.pressure_response([track], 3)[1]
    assert np.allclose(got, expected, atol=2e-5 * expected.max() + 1e-9)


def test_sample_typical_keeps_the_gain_of_a_typical_skin():
    for seed in range(40):
        wide = SkinPhysics.sample(np.random.default_rng(seed))
        typical = SkinPhysics.sample_typical(np.random.default_rng(seed))
        assert TYPICAL_GAIN_PF[0] <= typical.gain_pf <= TYPICAL_GAIN_PF[1]
        assert replace(typical, gain_pf=wide.gain_pf) == wide  # only the gain differs
    gains = [SkinPhysics.sample(np.random.default_rng(s)).gain_pf for s in range(40)]
    assert min(gains) < TYPICAL_GAIN_PF[0] and max(gains) > TYPICAL_GAIN_PF[1]
