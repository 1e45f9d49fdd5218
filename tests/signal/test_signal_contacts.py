"""Tests for wovenskin.signal.contacts: hysteresis, seeding, debounce and contact blobs."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import ndimage

from wovenskin.signal.config import ConditioningConfig
from wovenskin.signal.contacts import (
    Contact,
    ContactDetector,
    DetectorSettings,
    extract_contacts,
)


def _detector(on=0.1, off=0.05, shape=(1, 1), **rules) -> ContactDetector:
    return ContactDetector(np.full(shape, on), np.full(shape, off), DetectorSettings(**rules))


def _series(values) -> np.ndarray:
    return np.asarray(values, dtype=np.float64).reshape(-1, 1, 1)


def test_hysteresis_turns_on_above_on_and_off_below_off():
    signal = _series([0.0, 0.08, 0.11, 0.08, 0.06, 0.04, 0.08, 0.12, 0.05, 0.049])
    active = _detector().update_active(signal)[:, 0, 0]
    assert active.tolist() == [0, 0, 1, 1, 1, 0, 0, 1, 1, 0]


def test_debounce_ignores_short_blips_and_short_gaps():
    detector = _detector(debounce_on_frames=3, debounce_off_frames=4)
    pattern = [0, 1, 1, 0, 1, 1, 1, 1, 0, 0, 0, 1, 0, 0, 0, 0, 0]
    touched = detector.update_touched(np.asarray(pattern, bool).reshape(-1, 1, 1))
    assert touched.astype(int).tolist() == [0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 1, 1, 1, 1, 1, 0, 0]


def test_frame_peak_fraction_keeps_cross_talk_lines_inactive():
    frame = np.full((1, 5, 5), 0.0)
    frame[0, 2, :] = 0.15  # cross-talk along the pressed row
    frame[0, 2, 2] = 1.0
    plain = _detector(shape=(5, 5)).update_active(frame)
    assert plain[0, 2].all()
    guarded = _detector(shape=(5, 5), on_peak_fraction=0.2, off_peak_fraction=0.1)
    active = guarded.update_active(frame)
    assert active[0, 2, 2] and active.sum() == 1


def test_a_channel_releases_below_its_own_recent_peak_and_does_not_rearm_at_once():
    decay = np.exp(-1 / 100)
    detector = _detector(rearm_fraction=0.5, release_fraction=0.3, peak_decay=decay)
    signal = _series([0.0] * 3 + [1.0] * 10 + [0.25] * 20 + [0.12] * 300)
    active = detector.update_active(signal)[:, 0, 0]
    assert active[3:13].all()
    assert not active[13:140].any()  # 0.25 < 30 % of 1.0, and 0.12 < 50 % of the memory
    assert active[-1]  # once the memory has faded, a lasting 0.12 is a contact again
    # Without the envelope the lingering level would have stayed a contact throughout.
    assert _detector().update_active(signal)[:, 0, 0][13:].all()


def test_seeded_blobs_drop_candidates_without_a_strong_channel():
    detector = _detector(shape=(1, 6), seeded_blobs=True)  # on 0.1, off 0.05
    first = np.array([[[0.2, 0.2, 0.0, 0.0, 0.2, 0.0]]])
    assert detector.update_active(first)[0, 0].tolist() == [1, 1, 0, 0, 1, 0]
    # Channels 1 and 4 fall between the thresholds: both stay candidates, but only
    # channel 1 is in a blob with a seed (channel 0).
    second = np.array([[[0.2, 0.07, 0.0, 0.0, 0.07, 0.0]]])
    assert detector.update_active(second)[0, 0].tolist() == [1, 1, 0, 0, 0, 0]
    labels = detector.last_labels
    assert labels is not None and labels[0, 0, 0] == labels[0, 0, 1] > 0
    assert labels[0, 0, 4] == 0
    third = np.array([[[0.08, 0.07, 0.0, 0.0, 0.07, 0.0]]])
    assert not detector.update_active(third).any()


def test_common_mode_offset_of_the_whole_skin_is_not_contact():
    detector = _detector(shape=(4, 4), common_mode_quantile=0.25)
    frame = np.full((1, 4, 4), 0.3)  # the whole skin drifted up by 0.3
    assert not detector.update_active(frame).any()
    frame[0, 1, 1] = 0.5  # a finger on top of it: 0.2 above the skin's level
    assert detector.update_active(frame)[0, 1, 1]
    negative = np.full((1, 4, 4), -0.3)  # a negative level is not added back
    negative[0, 0, 0] = 0.0
    assert not detector.update_active(negative).any()


def test_from_calibration_uses_sigma_and_floors_and_disables_dead_channels():
    config = ConditioningConfig()
    noise = np.array([[1e-5, 1e-2], [1e-4, 1e-4]])
    dead = np.array([[False, True], [False, False]])
    detector = ContactDetector.from_calibration(noise, dead, config)
    assert detector.on_threshold[0, 0] == config.min_contact_rel  # quiet channel: floor
    assert detector.off_threshold[0, 0] == config.min_release_rel
    assert np.isinf(detector.on_threshold[0, 1])
    assert detector.settings == DetectorSettings.from_config(config)
    signal = np.zeros((3, 2, 2))
    signal[:, 0, :] = 1.0
    active = detector.update_active(signal)
    assert active[:, 0, 0].all() and not active[:, 0, 1].any()
    noisy = ContactDetector.from_calibration(np.array([[1e-2]]), np.array([[False]]), config)
    assert noisy.on_threshold[0, 0] == pytest.approx(config.contact_on_sigma * 1e-2)


@settings(max_examples=25, deadline=None, derandomize=True)
@given(sizes=st.lists(st.integers(1, 40), min_size=1, max_size=6), seed=st.integers(0, 5))
def test_detector_gives_identical_results_for_any_chunking(sizes, seed):
    rng = np.random.default_rng(seed)
    signal = np.cumsum(rng.normal(0, 0.03, (200, 3, 4)), axis=0)
    detector_rules = DetectorSettings.from_config(ConditioningConfig())
    whole = ContactDetector(np.full((3, 4), 0.1), np.full((3, 4), 0.05), detector_rules)
    expected = whole.process(signal)
    chunked = ContactDetector(np.full((3, 4), 0.1), np.full((3, 4), 0.05), detector_rules)
    parts, pos, k = [], 0, 0
    while pos < len(signal):
        stop = min(len(signal), pos + sizes[k % len(sizes)])
        parts.append(chunked.process(signal[pos:stop]))
        pos, k = stop, k + 1
    assert np.array_equal(np.concatenate([p[0] for p in parts]), expected[0])
    assert np.array_equal(np.concatenate([p[1] for p in parts]), expected[1])
    assert [c for p in parts for c in p[2]] == expected[2]
    assert expected[0].any()


def test_blob_centroid_size_peak_and_strength():
    signal = np.zeros((1, 5, 6))
    signal[0, 1, 2], signal[0, 2, 2], signal[0, 2, 3] = 0.1, 0.3, 0.1
    contacts = extract_contacts(signal, signal > 0)
    assert len(contacts) == 1 and len(contacts[0]) == 1
    contact = contacts[0][0]
    assert contact.size == 3
    assert contact.peak == pytest.approx(0.3)
    assert contact.strength == pytest.approx(0.5)
    assert contact.row == pytest.approx((0.1 * 1 + 0.3 * 2 + 0.1 * 2) / 0.5)
    assert contact.col == pytest.approx((0.1 * 2 + 0.3 * 2 + 0.1 * 3) / 0.5)
    assert contact.to_dict()["size"] == 3


def test_connectivity_decides_whether_diagonal_channels_join():
    active = np.zeros((1, 4, 4), bool)
    active[0, 0, 0] = active[0, 1, 1] = active[0, 3, 3] = True
    signal = active * 0.2
    assert len(extract_contacts(signal, active, connectivity=4)[0]) == 3
    eight = extract_contacts(signal, active, connectivity=8)[0]
    assert [c.size for c in eight] == [2, 1]
    with pytest.raises(ValueError, match="connectivity"):
        extract_contacts(signal, active, connectivity=6)


def test_blobs_never_join_across_frames_and_are_listed_in_raster_order():
    active = np.zeros((3, 4, 4), bool)
    active[0, 3, 0] = active[0, 0, 3] = True  # two blobs, the upper-right one first
    active[2, 1:3, 1] = True
    signal = active * 0.5
    contacts = extract_contacts(signal, active)
    assert [len(c) for c in contacts] == [2, 0, 1]
    assert (contacts[0][0].row, contacts[0][0].col) == (0.0, 3.0)
    assert (contacts[0][1].row, contacts[0][1].col) == (3.0, 0.0)
    assert contacts[2] == [Contact(row=1.5, col=1.0, size=2, peak=0.5, strength=1.0)]


def test_given_labels_in_any_numbering_give_the_same_contacts():
    rng = np.random.default_rng(3)
    signal = rng.uniform(0, 1, (40, 6, 7))
    active = signal > 0.6
    labels, count = ndimage.label(active, structure=_plane())
    shuffled = np.concatenate([[0], rng.permutation(count) + 100])[labels]
    assert extract_contacts(signal, active, labels=shuffled) == extract_contacts(signal, active)


def _plane() -> np.ndarray:
    structure = np.zeros((3, 3, 3), bool)
    structure[1] = ndimage.generate_binary_structure(2, 1)
    return structure


def test_a_frame_alone_gives_bit_identical_contacts_to_the_same_frame_in_a_batch():
    rng = np.random.default_rng(4)
    signal = rng.uniform(0, 1, (50, 6, 7))  # > 256 active pixels: the array path
    active = signal > 0.6
    batch = extract_contacts(signal, active)
    alone = [extract_contacts(signal[i : i + 1], active[i : i + 1])[0] for i in range(50)]
    assert alone == batch


def test_no_active_channel_gives_empty_lists():
    assert extract_contacts(np.zeros((3, 2, 2)), np.zeros((3, 2, 2), bool)) == [[], [], []]


def test_a_fast_signal_releases_a_lifted_finger_at_once():
    decay = np.exp(-1 / 200)
    rules = {"rearm_fraction": 0.25, "release_fraction": 0.2, "peak_decay": decay}
    smooth = _series([0.0] * 5 + [1.0] * 20 + list(np.linspace(0.95, 0.0, 20)))  # 20-frame mean
    fast = _series([0.0] * 5 + [1.0] * 20 + [0.75, 0.5, 0.25, 0.0] + [0.0] * 16)  # 4-frame
    slow_only = _detector(**rules).update_active(smooth)[:, 0, 0]
    with_fast = _detector(**rules).update_active(smooth, fast)[:, 0, 0]
    assert slow_only[5:25].all() and with_fast[5:25].all()
    released_slow = 25 + int(np.argmin(slow_only[25:]))
    released_fast = 25 + int(np.argmin(with_fast[25:]))
    assert released_fast == 28  # the fast signal fell below 20 % of the peak
    assert released_slow >= 40


def test_a_fast_signal_well_above_threshold_turns_a_channel_on_early():
    smooth = _series([0.0, 0.03, 0.06, 0.09, 0.12, 0.15])
    fast = _series([0.0, 0.12, 0.24, 0.3, 0.3, 0.3])
    plain = _detector().update_active(smooth)[:, 0, 0]
    early = _detector(fast_on_factor=2.0).update_active(smooth, fast)[:, 0, 0]
    assert plain.tolist() == [0, 0, 0, 0, 1, 1]
    assert early.tolist() == [0, 0, 1, 1, 1, 1]  # 0.24 > 2 x 0.1 two frames sooner
    with pytest.raises(ValueError, match="fast signal has shape"):
        _detector().update_active(smooth, fast[:3])


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"on_threshold": np.ones(3), "off_threshold": np.ones(3)}, "grids"),
        ({"on_threshold": np.ones((2, 2)), "off_threshold": np.full((2, 2), 2.0)}, "exceed"),
    ],
)
def test_constructor_rejects_bad_thresholds(kwargs, message):
    with pytest.raises(ValueError, match=message):
        ContactDetector(**kwargs)


@pytest.mark.parametrize(
    ("rules", "message"),
    [
        ({"debounce_on_frames": 0}, "at least 1 frame"),
        ({"connectivity": 5}, "connectivity"),
        ({"on_peak_fraction": 0.1, "off_peak_fraction": 0.2}, "peak fractions"),
        ({"rearm_fraction": 0.1, "release_fraction": 0.2}, "release_fraction"),
        ({"peak_decay": 1.0}, "peak_decay"),
        ({"common_mode_quantile": 1.0}, "common_mode_quantile"),
        ({"fast_on_factor": 0.5}, "fast_on_factor"),
    ],
)
def test_settings_reject_bad_rules(rules, message):
    with pytest.raises(ValueError, match=message):
        DetectorSettings(**rules)


def test_reset_forgets_state():
    detector = _detector()
    detector.update_active(_series([0.2]))
    assert detector.update_active(_series([0.07]))[0, 0, 0]
    detector.reset()
    assert not detector.update_active(_series([0.07]))[0, 0, 0]
