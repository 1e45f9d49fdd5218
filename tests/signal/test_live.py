"""Tests of LiveSkin: source -> calibration/conditioning -> recorder, and its events."""

import numpy as np

from wovenskin.recording.formats import LabelledStream, write_labelled_stream
from wovenskin.recording.native import read_recording
from wovenskin.recording.writer import RecordingWriter
from wovenskin.runtime.sources import open_source
from wovenskin.signal.conditioner import condition_recording
from wovenskin.signal.config import ConditioningConfig
from wovenskin.signal.live_skin import LiveSkin, RateMeter


def _stream(tmp_path, seconds=3.0, rate=200.0, press=(1.5, 2.2)):
    rng = np.random.default_rng(0)
    n = int(seconds * rate)
    t = np.arange(n) / rate
    frames = (20.0 + rng.normal(0, 0.01, (n, 10, 10))).astype(np.float32)
    on = (t >= press[0]) & (t < press[1])
    frames[on, 4:6, 4:6] += 3.0
    path = tmp_path / "s.npz"
    write_labelled_stream(
        path,
        LabelledStream(
            frames, t, rate, np.array([press[0]]), np.array([press[1]]), np.array(["push"])
        ),
    )
    return path, frames


def _drain(skin, limit=10_000):
    blocks = []
    for _ in range(limit):
        block = skin.step(timeout=0.01)
        if block is not None:
            blocks.append(block)
        if skin.state.ended:
            break
    return blocks


def test_live_skin_matches_offline_conditioning(tmp_path):
    path, frames = _stream(tmp_path)
    skin = LiveSkin(open_source(f"replay:{path}?speed=0"))
    skin.start()
    blocks = _drain(skin)
    skin.close()
    assert skin.state.ended and not skin.state.calibrating
    live_signal = np.concatenate([b.cond.signal for b in blocks])
    _, offline = condition_recording(frames, ConditioningConfig())
    # the live path conditions the frames after calibration exactly as the offline path
    np.testing.assert_array_equal(live_signal, offline.signal[-len(live_signal) :])
    times = np.concatenate([b.t for b in blocks])
    touched_t = times[np.concatenate([b.cond.touched for b in blocks])]
    assert 1.5 <= touched_t.min() < 1.6 and 2.2 <= touched_t.max() < 2.4


def test_live_skin_records_every_raw_frame_and_the_calibration(tmp_path):
    path, frames = _stream(tmp_path)
    source = open_source(f"replay:{path}?speed=0")
    with RecordingWriter(tmp_path / "r.wsrec", source.info) as writer:
        skin = LiveSkin(source, recorder=writer)
        skin.start()
        _drain(skin)
        skin.close()
    rec = read_recording(tmp_path / "r.wsrec")
    np.testing.assert_array_equal(rec.frames, frames)
    assert len(rec.calibrations) == 1


def test_rate_meter_counts_a_window():
    meter = RateMeter(window_s=1.0)
    meter.add(50, now=10.0)
    meter.add(50, now=10.5)
    assert meter.rate(now=10.9) == 100
    assert meter.rate(now=11.2) == 50
