"""Tests for wovenskin.signal.contacts: hysteresis, debounce and contact blobs."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from wovenskin.signal.config import ConditioningConfig
from wovenskin.signal.contacts import Contact, ContactDetector, extract_contacts


def _detector(on=0.1, off=0.05, debounce_on=1, debounce_off=1, shape=(1, 1), connectivity=4):
    return ContactDetector(
        np.full(shape, on), np.full(shape, off), debounce_on, debounce_off, connectivity
    )


def _series(values) -> np.ndarray:
    return np.asarray(values, dtype=np.float64).reshape(-1, 1, 1)


def test_hysteresis_turns_on_above_on_and_off_below_off():
    signal = _series([0.0, 0.08, 0.11, 0.08, 0.06, 0.04, 0.08, 0.12, 0.05, 0.049])
    active = _detector().update_active(signal)[:, 0, 0]
    assert active.tolist() == [0, 0, 1, 1, 1, 0, 0, 1, 1, 0]


def test_debounce_ignores_short_blips_and_short_gaps():
    detector = _detector(debounce_on=3, debounce_off=4)
    pattern = [0, 1, 1, 0, 1, 1, 1, 1, 0, 0, 0, 1, 0, 0, 0, 0, 0]
    touched = detector.update_touched(np.asarray(pattern, bool).reshape(-1, 1, 1))
    assert touched.astype(int).tolist() == [0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 1, 1, 1, 1, 1, 0, 0]


def test_from_calibration_uses_sigma_and_floors_and_disables_dead_channels():
    config = ConditioningConfig()
    noise = np.array([[1e-4, 1e-2]])
    dead = np.array([[False, True]])
    detector = ContactDetector.from_calibration(noise, dead, config)
    assert detector.on_threshold[0, 0] == config.min_contact_rel  # quiet channel: floor
    assert detector.off_threshold[0, 0] == config.min_release_rel
    assert np.isinf(detector.on_threshold[0, 1])
    active = detector.update_active(np.full((3, 1, 2), 1e3))
    assert active[:, 0, 0].all() and not active[:, 0, 1].any()
    noisy = ContactDetector.from_calibration(np.array([[1e-2]]), np.array([[False]]), config)
    assert noisy.on_threshold[0, 0] == pytest.approx(config.contact_on_sigma * 1e-2)


@settings(max_examples=25, deadline=None, derandomize=True)
@given(sizes=st.lists(st.integers(1, 40), min_size=1, max_size=6), seed=st.integers(0, 5))
def test_detector_gives_identical_results_for_any_chunking(sizes, seed):
    rng = np.random.default_rng(seed)
    signal = np.cumsum(rng.normal(0, 0.03, (200, 3, 4)), axis=0)
    whole = _detector(debounce_on=3, debounce_off=5, shape=(3, 4)).process(signal)
    chunked = _detector(debounce_on=3, debounce_off=5, shape=(3, 4))
    parts, pos, k = [], 0, 0
    while pos < len(signal):
        stop = min(len(signal), pos + sizes[k % len(sizes)])
        parts.append(chunked.process(signal[pos:stop]))
        pos, k = stop, k + 1
    assert np.array_equal(np.concatenate([p[0] for p in parts]), whole[0])
    assert np.array_equal(np.concatenate([p[1] for p in parts]), whole[1])
    assert [c for p in parts for c in p[2]] == whole[2]


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


def test_a_frame_alone_gives_bit_identical_contacts_to_the_same_frame_in_a_batch():
    rng = np.random.default_rng(4)
    signal = rng.uniform(0, 1, (50, 6, 7))
    active = signal > 0.6
    batch = extract_contacts(signal, active)
    alone = [extract_contacts(signal[i : i + 1], active[i : i + 1])[0] for i in range(50)]
    assert alone == batch


def test_no_active_channel_gives_empty_lists():
    assert extract_contacts(np.zeros((3, 2, 2)), np.zeros((3, 2, 2), bool)) == [[], [], []]


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"on_threshold": np.ones(3), "off_threshold": np.ones(3)}, "grids"),
        ({"on_threshold": np.ones((2, 2)), "off_threshold": np.full((2, 2), 2.0)}, "exceed"),
        ({"debounce_on_frames": 0}, "at least 1 frame"),
        ({"connectivity": 5}, "connectivity"),
    ],
)
def test_constructor_rejects_bad_settings(kwargs, message):
    args = {"on_threshold": np.ones((2, 2)), "off_threshold": np.zeros((2, 2)), **kwargs}
    with pytest.raises(ValueError, match=message):
        ContactDetector(**args)


def test_reset_forgets_state():
    detector = _detector()
    detector.update_active(_series([0.2]))
    assert detector.update_active(_series([0.07]))[0, 0, 0]
    detector.reset()
    assert not detector.update_active(_series([0.07]))[0, 0, 0]
