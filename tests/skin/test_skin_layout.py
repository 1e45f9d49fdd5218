"""Tests of the skin layout: the one place that maps device channel order to [row, col]."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from wovenskin.skin.layout import ChannelOrder, SkinLayout


def test_default_layout_matches_gestures_md():
    layout = SkinLayout()
    assert layout.shape == (10, 10)
    assert layout.width_mm == pytest.approx(100.0)
    assert layout.height_mm == pytest.approx(140.0)
    x, y = layout.channel_centers_mm()
    assert x[0, 0] == pytest.approx(5.0) and y[0, 0] == pytest.approx(7.0)
    # columns grow to the right, rows grow downward
    assert x[0, 1] > x[0, 0] and y[1, 0] > y[0, 0]


def test_mm_and_rc_are_inverse():
    layout = SkinLayout(6, 8, 12.0, 9.0)
    row, col = layout.mm_to_rc(*layout.rc_to_mm(2.25, 5.5))
    assert row == pytest.approx(2.25) and col == pytest.approx(5.5)


def test_invalid_layout_rejected():
    with pytest.raises(ValueError, match="at least one row"):
        SkinLayout(0, 10)
    with pytest.raises(ValueError, match="pitches"):
        SkinLayout(10, 10, -1.0)


def test_row_major_identity():
    layout = SkinLayout(3, 4)
    samples = np.arange(12)
    frame = ChannelOrder().to_frames(samples, layout)
    assert frame[0].tolist() == [0, 1, 2, 3]
    assert frame[2, 3] == 11


def test_col_major_with_flips():
    layout = SkinLayout(2, 3)
    # device scans column by column, rows numbered from the bottom edge
    order = ChannelOrder.parse("col-major,flip-rows")
    samples = np.array([10, 11, 20, 21, 30, 31])  # (col0: row0,row1), (col1: ...), ...
    frame = order.to_frames(samples, layout)
    # device row 0 is the bottom edge, so it lands in frame row 1
    assert frame.tolist() == [[11, 21, 31], [10, 20, 30]]


def test_parse_rejects_unknown():
    with pytest.raises(ValueError, match="row-major or col-major"):
        ChannelOrder.parse("diagonal")
    with pytest.raises(ValueError, match="unknown channel order option"):
        ChannelOrder.parse("row-major,twist")


def test_wrong_channel_count_is_a_clear_error():
    with pytest.raises(ValueError, match="expected 100 channels"):
        ChannelOrder().to_frames(np.zeros(99), SkinLayout())


@given(
    rows=st.integers(1, 7),
    cols=st.integers(1, 7),
    major=st.sampled_from(["row", "col"]),
    flip_rows=st.booleans(),
    flip_cols=st.booleans(),
    lead=st.integers(0, 3),
)
def test_round_trip_any_order(rows, cols, major, flip_rows, flip_cols, lead):
    layout = SkinLayout(rows, cols)
    order = ChannelOrder(major, flip_rows, flip_cols)
    assert ChannelOrder.parse(str(order)) == order
    shape = (lead, rows * cols) if lead else (rows * cols,)
    samples = np.arange(np.prod(shape)).reshape(shape)
    frames = order.to_frames(samples, layout)
    assert frames.shape[-2:] == (rows, cols)
    np.testing.assert_array_equal(order.to_samples(frames, layout), samples)
