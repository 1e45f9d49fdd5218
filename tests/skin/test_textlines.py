"""Tests for the text-line stream format decoder."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from wovenskin.skin.layout import ChannelOrder, SkinLayout
from wovenskin.skin.messages import DecodeError
from wovenskin.skin.textlines import TextLineDecoder

LAYOUT = SkinLayout(3, 4)
SAMPLES = np.arange(12, dtype=np.float32) + 20.5


def _line(values, sep: str = ",", prefix: list[str] | None = None, end: str = "\r\n") -> bytes:
    fields = (prefix or []) + [repr(float(v)) for v in values]
    return (sep.join(fields) + end).encode()


def _frames(items) -> list[np.ndarray]:
    return [i for i in items if isinstance(i, np.ndarray)]


def _reasons(items) -> list[str]:
    return [i.reason for i in items if isinstance(i, DecodeError)]


@pytest.mark.parametrize("sep", [",", ", ", ";", "\t", " ", "   "])
def test_separators_are_detected(sep):
    out = TextLineDecoder(LAYOUT).feed(_line(SAMPLES, sep))
    assert len(out) == 1
    np.testing.assert_array_equal(out[0], SAMPLES.reshape(3, 4))
    assert out[0].dtype == np.float32


def test_explicit_separator_and_trailing_separator():
    decoder = TextLineDecoder(LAYOUT, separator=";")
    out = decoder.feed(_line(SAMPLES, ";", end=";\n"))
    np.testing.assert_array_equal(out[0], SAMPLES.reshape(3, 4))
    assert _reasons(decoder.feed(_line(SAMPLES, ","))) == ["channels"]


@pytest.mark.parametrize(
    "order",
    [
        ChannelOrder(m, fr, fc)
        for m in ("row", "col")
        for fr in (False, True)
        for fc in (False, True)
    ],
)
def test_channel_order_is_applied_by_channel_order_only(order):
    frame = np.arange(12, dtype=np.float32).reshape(3, 4)
    device_samples = order.to_samples(frame, LAYOUT)
    out = TextLineDecoder(LAYOUT, order).feed(_line(device_samples))
    np.testing.assert_array_equal(out[0], frame)


def test_skip_columns_ignores_a_leading_counter_even_if_not_numeric():
    decoder = TextLineDecoder(LAYOUT, skip_columns=2)
    out = decoder.feed(_line(SAMPLES, prefix=["T:1234", "7"]))
    np.testing.assert_array_equal(out[0], SAMPLES.reshape(3, 4))
    assert _reasons(decoder.feed(_line(SAMPLES))) == ["channels"]


def test_line_endings_blank_lines_and_comments():
    data = (
        b"# firmware 1.0, 12 channels\r\n\r\n"
        + _line(SAMPLES, end="\n")
        + b"   \n"
        + _line(SAMPLES, end="\r")
        + b"#\n"
        + _line(SAMPLES, end="\r\n")
    )
    out = TextLineDecoder(LAYOUT).feed(data)
    assert len(out) == 3 and all(isinstance(f, np.ndarray) for f in out)


def test_partial_lines_wait_for_their_end():
    decoder = TextLineDecoder(LAYOUT)
    line = _line(SAMPLES)
    assert decoder.feed(line[:10]) == []
    assert decoder.feed(line[10:-2]) == []
    out = decoder.feed(line[-2:])
    assert len(out) == 1
    np.testing.assert_array_equal(out[0], SAMPLES.reshape(3, 4))


def test_bad_lines_are_reported_and_the_stream_goes_on():
    good = _line(SAMPLES)
    data = (
        good
        + b"hello world\n"  # junk: wrong field count
        + b"1,2,3\n"  # too few channels
        + _line(np.arange(13))  # too many channels
        + b"1,2,3,4,5,6,7,8,9,10,11,abc\n"  # not a number
        + b"1,2,3,4,5,6,7,8,9,10,,12\n"  # empty field
        + b"1,2,3,4,5,6,7,8,9,10,11,nan\n"
        + b"1,2,3,4,5,6,7,8,9,10,11,-inf\n"
        + b"1,2,3,4,5,6,7,8,9,10,11,1e39\n"  # beyond float32
        + b"1,2,3,4,5,6,7,8,9,10,11,\xc2\xb5\n"
        + good
    )
    out = TextLineDecoder(LAYOUT).feed(data)
    assert len(_frames(out)) == 2
    assert _reasons(out) == [
        "channels",
        "channels",
        "channels",
        "parse",
        "parse",
        "nonfinite",
        "nonfinite",
        "nonfinite",
        "encoding",
    ]


def test_overlong_lines_are_dropped_once_across_feeds():
    decoder = TextLineDecoder(LAYOUT, max_line_bytes=200)
    out = decoder.feed(b"1," * 80)
    out += decoder.feed(b"1," * 80)  # over the limit, still no newline
    out += decoder.feed(b"1," * 500)
    out += decoder.feed(b"1\n" + _line(SAMPLES))
    assert _reasons(out) == ["overlong"]
    assert len(_frames(out)) == 1
    complete = TextLineDecoder(LAYOUT, max_line_bytes=200).feed(b"2," * 150 + b"\n")
    assert _reasons(complete) == ["overlong"]


def test_invalid_arguments():
    with pytest.raises(ValueError, match="skip_columns"):
        TextLineDecoder(LAYOUT, skip_columns=-1)


@settings(max_examples=300)
@given(st.binary(max_size=2000), st.lists(st.integers(0, 2000), max_size=15))
def test_random_bytes_never_raise(data, cuts):
    decoder = TextLineDecoder(LAYOUT, max_line_bytes=300)
    points = sorted({c % (len(data) + 1) for c in cuts})
    bounds = [0, *points, len(data)]
    for a, b in zip(bounds, bounds[1:], strict=False):
        for item in decoder.feed(data[a:b]):
            assert isinstance(item, np.ndarray | DecodeError)
            if isinstance(item, np.ndarray):
                assert item.shape == (3, 4) and np.isfinite(item).all()


@given(
    st.lists(
        hnp.arrays(
            np.float32, 12, elements=st.floats(width=32, allow_nan=False, allow_infinity=False)
        ),
        min_size=1,
        max_size=8,
    ),
    st.lists(st.integers(0, 4000), max_size=10),
    st.sampled_from([",", " ", "\t", ";"]),
)
def test_printed_float32_values_come_back_bit_exact_in_any_chunking(frames, cuts, sep):
    data = b"".join(_line(f, sep, prefix=[str(i)]) for i, f in enumerate(frames))
    decoder = TextLineDecoder(LAYOUT, ChannelOrder("col", True, False), skip_columns=1)
    points = sorted({c % (len(data) + 1) for c in cuts})
    bounds = [0, *points, len(data)]
    out = []
    for a, b in zip(bounds, bounds[1:], strict=False):
        out.extend(decoder.feed(data[a:b]))
    assert len(out) == len(frames)
    for got, samples in zip(out, frames, strict=True):
        expected = ChannelOrder("col", True, False).to_frames(samples, LAYOUT)
        np.testing.assert_array_equal(got.view(np.uint32), expected.view(np.uint32))
