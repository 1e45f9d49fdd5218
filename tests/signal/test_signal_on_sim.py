"""Signal conditioning on the simulated skin: contact detection scored against ground truth.

The seeds are the hard cases found while tuning the two packages against each other:

- 0: a light person (0.5 N) on a weak, noisy skin whose firmware averages 13 frames, with
  0.3 glitches/s (each one a 13-frame pulse after the average) and fast common drift;
- 1: strong per-channel drift on channels in the middle of the skin, touched so often
  that they are frozen nearly all the time;
- 2: glitches smeared into 2-frame pulses (too long for the median of three);
- 9: a forearm and sleeve whose negative fringe field sinks the whole skin by ~0.5 %
  for 3 s without any contact being detected (its baseline once followed it down and a
  channel stayed "touched" for 26 s after the forearm left);
- 19: a glitch pulse at the end of calibration (it once biased a baseline and left a
  +1.5 % phantom for 30 s).

Targets over seeds 0-19 (``python -m wovenskin.bench.detection``): phantom <= 0.5 % mean
and <= 2 % worst, median touched fraction of gesture events >= 0.95.  The assertions
here keep a margin on these harder seeds.
"""

from __future__ import annotations

import numpy as np
import pytest

from wovenskin.bench.detection import DetectionReport, run_detection_benchmark
from wovenskin.signal.calibration import calibrate
from wovenskin.signal.conditioner import ConditionedFrames, Conditioner
from wovenskin.signal.config import ConditioningConfig
from wovenskin.sim.stream import simulate_stream

HARD_SEEDS = (0, 1, 2, 9, 19)


@pytest.fixture(scope="module")
def report() -> DetectionReport:
    return run_detection_benchmark(HARD_SEEDS, seconds=60.0)


def test_calibration_is_ok_on_every_contact_free_start(report):
    assert all(s.contact_free_start for s in report.seeds)
    assert [s.seed for s in report.seeds if not s.calibration_ok] == []


def test_nothing_reads_as_touched_while_nobody_touches(report):
    phantoms = {s.seed: round(s.phantom_fraction, 4) for s in report.seeds}
    # seed 9 (1.2 %): a hand hovering over a sensitive skin before it lands
    assert max(phantoms.values()) <= 0.015, phantoms
    assert report.mean_phantom <= 0.0025, phantoms


def test_gestures_read_as_touched_for_nearly_their_whole_duration(report):
    touched = report.event_touched
    assert touched.size > 100
    assert report.median_touched >= 0.9  # 0.94 on 2026-11-25
    assert np.mean(touched >= 0.8) >= 0.9
    # The one below 0.6 is a quick swipe_up of seed 1 (touched 26 % of its span).
    assert len(report.weak_events(0.6)) <= 2
    assert {seed for seed, *_ in report.weak_events(0.6)} <= {1}
    assert touched.min() >= 0.2


def test_lift_off_releases_the_touched_flag_promptly(report):
    release = report.release_latency_s
    assert release.size > 50
    assert np.median(release) <= 0.13
    assert np.percentile(release, 90) <= 0.2
    assert release.max() < 0.3


def test_live_frame_by_frame_equals_the_whole_recording_on_a_glitchy_skin():
    # Seed 0: firmware-smeared glitches, quantisation, drift and gestures.
    frames = simulate_stream(20.0, 0).frames.astype(np.float32)
    config = ConditioningConfig()
    calibration = calibrate(frames[: config.calibration_frames], config)
    whole = Conditioner(calibration, config).process(frames)
    live = Conditioner(calibration, config)
    parts = ConditionedFrames.concat([live.process(frame) for frame in frames])
    for name in ("signal", "active", "touched", "n_contacts", "saturated", "invalid"):
        assert np.array_equal(getattr(parts, name), getattr(whole, name)), name
    assert np.array_equal(parts.baseline, whole.baseline)
    assert parts.contacts == whole.contacts
    assert whole.touched.any()
