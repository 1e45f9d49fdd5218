"""The "no skin" source: contact-free frames on a stream clock, opened as ``none``."""

from __future__ import annotations

import numpy as np
import pytest

from wovenskin.errors import ConfigError
from wovenskin.runtime.idle import IdleSkinSource
from wovenskin.runtime.sources import open_source
from wovenskin.skin.frames import Frame, SourceEvent
from wovenskin.skin.source import MAX_READER_LAG_S, SkinSource


def _frames(items):
    return [item for item in items if isinstance(item, Frame)]


def test_fast_frames_are_contact_free_and_on_the_stream_clock():
    source = open_source("none:speed=0,rows=4,cols=6")
    assert isinstance(source, IdleSkinSource) and isinstance(source, SkinSource)
    assert source.poll(0.0) == []  # not started
    source.start()
    first = source.poll(0.0)
    assert isinstance(first[0], SourceEvent) and first[0].kind == "connected"
    frames = _frames(first) + _frames(source.poll(0.0))
    assert [f.seq for f in frames] == list(range(len(frames)))
    assert np.allclose([f.t for f in frames], np.arange(len(frames)) / 200.0)
    values = np.stack([f.values for f in frames])
    assert values.shape == (len(frames), 4, 6) and values.dtype == np.float32
    assert np.all(np.abs(values - 10.0) < 0.05) and values.std() > 0  # flat is "dead"
    assert source.stats().good_frames == len(frames) and source.info.source == "none"
    source.close()
    assert source.poll(0.0) == [] and not source.stats().connected


def test_real_time_pacing_follows_the_clock():
    now = [100.0]
    source = IdleSkinSource(rate=100.0, clock=lambda: now[0])
    source.start()
    assert len(_frames(source.poll(0.0))) == 1  # the frame at t = 0
    now[0] += 0.105
    frames = _frames(source.poll(0.0))
    assert [f.t for f in frames] == pytest.approx([0.01 * i for i in range(1, 11)])
    now[0] += 0.5  # a reader half a second behind gets at most MAX_READER_LAG_S of frames:
    late = _frames(source.poll(0.0))  # the stream clock is held back, nothing is skipped
    assert len(late) == round(MAX_READER_LAG_S * 100.0)
    assert [f.seq for f in late] == list(range(11, 11 + len(late)))
    now[0] += 0.05  # then the stream goes on at its pace from there
    assert len(_frames(source.poll(0.0))) == 5


@pytest.mark.parametrize(
    "spec, words",
    [
        ("none:speed=-1", "speed"),
        ("none:rate=0", "rate"),
        ("none:noise=5", "noise"),
        ("none:colour=red", "colour"),
        ("none:/dev/ttyACM0", "target"),
    ],
)
def test_bad_specs_are_one_config_error(spec, words):
    with pytest.raises(ConfigError, match=words):
        open_source(spec)


def test_commands_are_accepted_or_refused():
    source = IdleSkinSource()
    source.send_command("recalibrate")
    with pytest.raises(ConfigError, match="unknown command"):
        source.send_command("explode")
