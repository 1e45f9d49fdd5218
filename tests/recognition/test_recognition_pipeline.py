"""Tests of wovenskin.recognition.pipeline: offline equals live, LiveSkin blocks, model checks."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from tiny_models import save_tiny_model

from wovenskin.gestures import CLASS_NAMES, INVALID
from wovenskin.recognition.arbiter import DWELL, LIFT_OFF
from wovenskin.recognition.event_scoring import score_stream
from wovenskin.recognition.onnx_runtime import OnnxRecognizer
from wovenskin.recognition.pipeline import (
    RESET,
    LivePipeline,
    PipelineSettings,
    arbiter_settings_for_model,
    conditioning_for_model,
    load_recognizer,
    run_pipeline,
)
from wovenskin.recording.formats import LabelledStream, write_labelled_stream
from wovenskin.recording.inspect import convert_file
from wovenskin.runtime.sources import open_source
from wovenskin.signal import ConditioningConfig
from wovenskin.signal.live_skin import LiveBlock, LiveSkin
from wovenskin.sim.stream import simulate_stream


def make_model(directory: Path, conditioning: dict | None = None) -> Path:
    """A tiny untrained TCN whose logits spread widely, so its classes change often."""
    return save_tiny_model(directory, seed=1, decisive=True, conditioning=conditioning)


@pytest.fixture(scope="module")
def model_dir(tmp_path_factory) -> Path:
    return make_model(tmp_path_factory.mktemp("model"))


@pytest.fixture(scope="module")
def stream() -> LabelledStream:
    return simulate_stream(12.0, seed=5)


def summary(commands):
    return [(c.t, c.gesture, c.reason) for c in commands]


@pytest.mark.parametrize("every", [1, 3])
def test_offline_equals_the_live_path_frame_by_frame(model_dir, stream, every: int) -> None:
    recognizer = OnnxRecognizer(model_dir)
    settings = PipelineSettings(every=every)
    offline = run_pipeline(stream, recognizer, settings)
    frame_by_frame = run_pipeline(stream, recognizer, settings, block_frames=1)
    in_live_blocks = run_pipeline(stream, recognizer, settings, block_frames=4)
    assert len(offline.commands) >= 6  # a meaningful comparison: several commands
    assert {c.reason for c in offline.commands} >= {DWELL, LIFT_OFF}
    assert summary(frame_by_frame.commands) == summary(offline.commands)
    assert summary(in_live_blocks.commands) == summary(offline.commands)
    assert offline.windows_inferred == frame_by_frame.windows_inferred
    assert 0 < offline.windows_inferred < offline.windows_predicted
    assert offline.n_frames == 2400 and offline.duration_s == pytest.approx(12.0)
    assert offline.realtime_factor > 0 and "calibration ok" in offline.calibration


def test_live_pipeline_on_live_skin_blocks(model_dir, stream, tmp_path) -> None:
    path = tmp_path / "s.npz"
    write_labelled_stream(path, stream)
    recognizer = OnnxRecognizer(model_dir)
    live_skin = LiveSkin(open_source(f"replay:{path}?speed=0"), conditioning_for_model(recognizer))
    pipeline = LivePipeline.for_live_skin(live_skin, recognizer)
    live_skin.start()
    seen_touch_probabilities = False
    try:
        while not live_skin.state.ended:
            block = live_skin.step(timeout=0.01)
            if block is not None:
                pipeline.feed(block)
                seen_touch_probabilities |= pipeline.latest_top()[0] != INVALID
    finally:
        live_skin.close()
    expected = run_pipeline(path, recognizer).commands
    assert len(expected) >= 6
    assert summary(pipeline.changes) == summary(expected)
    assert seen_touch_probabilities
    assert pipeline.latest_probabilities.shape == (len(CLASS_NAMES),)


class ContactMeansSwipeRight:
    """A stand-in model: every window with contact is a confident ``swipe_right``."""

    class_names = CLASS_NAMES

    class meta:  # noqa: N801 - mimics CheckpointMeta's window only
        window = 30

    def predict_proba(self, windows: np.ndarray) -> np.ndarray:
        out = np.zeros((len(windows), len(CLASS_NAMES)), dtype=np.float32)
        out[:, CLASS_NAMES.index("swipe_right")] = 1.0
        return out


def test_each_touch_gives_one_command_after_the_dwell_until_lift_off() -> None:
    stream = simulate_stream(15.0, seed=2, gestures=["swipe_right"], invalid_fraction=0.0)
    result = run_pipeline(stream, ContactMeansSwipeRight())
    commands = result.commands
    starts = [c for c in commands if c.gesture is not None]
    ends = [c for c in commands if c.gesture is None]
    assert len(starts) == len(stream.event_labels) >= 4
    assert [c.reason for c in starts] == [DWELL] * len(starts)
    assert [c.reason for c in ends] == [LIFT_OFF] * len(ends) and len(ends) == len(starts)
    for start, end, begin, finish in zip(
        starts, ends, stream.event_start_s, stream.event_end_s, strict=True
    ):
        # contact seen, then the dwell; a sensitive skin senses the approaching hand's
        # fringe field up to ~50 ms before the labelled landing
        assert begin + 0.05 <= start.t <= begin + 0.3
        # lift-off ends it within the debounce and the moving average's release (a
        # sensitive skin still feels the lifting hand's fringe field for a few frames)
        assert start.t < end.t <= finish + 0.15
    scores = score_stream(commands, stream)
    assert (scores.recall, scores.precision, scores.n_false) == (1.0, 1.0, 0)


def test_live_pipeline_state_and_reset() -> None:
    pipeline = LivePipeline(ContactMeansSwipeRight(), 10, 10, 200.0)
    signal = np.zeros((60, 10, 10), dtype=np.float32)
    signal[:, 4:6, 4:6] = 0.05
    active = signal > 0
    changes = pipeline.process(np.arange(60) / 200.0, signal, active, np.ones(60, dtype=bool))
    assert summary(changes) == [(49 / 200.0, "swipe_right", DWELL)]  # first window at 29
    assert pipeline.active == "swipe_right" and pipeline.touched
    assert pipeline.latest_top() == ("swipe_right", 1.0)
    ended = pipeline.reset()
    assert ended is not None and (ended.gesture, ended.reason) == (None, RESET)
    assert pipeline.active is None and pipeline.latest_top()[0] == INVALID
    with pytest.raises(ValueError, match="3 frame times for 60 frames"):
        pipeline.process(np.arange(3.0), signal, active, np.ones(60, dtype=bool))


def test_the_tracks_after_each_frame_of_a_block_are_those_of_frame_by_frame() -> None:
    n = 60
    rows, cols = np.mgrid[0:10, 0:10]
    centres = 2.0 + 5.0 * np.arange(n) / n  # a fingertip sliding along row 4
    signal = np.stack(
        [0.2 * np.exp(-((rows - 4.0) ** 2 + (cols - c) ** 2) / 1.5) for c in centres]
    ).astype(np.float32)
    active, touched, t = signal > 0.03, np.ones(n, dtype=bool), np.arange(n) / 200.0
    settings = PipelineSettings(reader="touch")
    whole = LivePipeline(ContactMeansSwipeRight(), 10, 10, 200.0, settings=settings)
    whole.process(t, signal, active, touched)
    single = LivePipeline(ContactMeansSwipeRight(), 10, 10, 200.0, settings=settings)
    for k in range(n):
        single.process(t[k : k + 1], signal[k : k + 1], active[k : k + 1], touched[k : k + 1])
        got = [(tr.id, tr.y, tr.x, tr.merged) for tr in whole.tracks_at(t[k])]
        assert got == [(tr.id, tr.y, tr.x, tr.merged) for tr in single.tracks()]
    assert whole.tracks_at(t[-1])[0].x == pytest.approx(centres[-1] * 10.0, abs=2.0)  # mm
    assert whole.tracks_at(1.0) is None  # a frame it never read
    whole.reset()
    assert whole.tracks_at(t[-1]) is None and whole.tracks() == []
    window = LivePipeline(ContactMeansSwipeRight(), 10, 10, 200.0)  # tracks nothing
    window.process(t, signal, active, touched)
    assert window.tracks_at(t[0]) == [] and window.tracks() == []


def test_a_recalibration_between_blocks_resets_the_pipeline() -> None:
    pipeline = LivePipeline(ContactMeansSwipeRight(), 10, 10, 200.0)

    def block(first_index: int, t0: float) -> LiveBlock:
        signal = np.zeros((60, 10, 10), dtype=np.float32)
        signal[:, 2:4, 2:4] = 0.05
        cond = SimpleNamespace(
            signal=signal,
            active=signal > 0,
            touched=np.ones(60, dtype=bool),
            index=np.arange(first_index, first_index + 60),
        )
        return LiveBlock(t0 + np.arange(60) / 200.0, cond)

    assert summary(pipeline.feed(block(100, 1.0))) == [(1.0 + 49 / 200.0, "swipe_right", DWELL)]
    assert pipeline.feed(block(160, 1.3)) == []  # the next frames: nothing changes
    changes = pipeline.feed(block(100, 5.0))  # a new conditioner: frames restart at 100
    assert summary(changes) == [(5.0, None, RESET), (5.0 + 49 / 200.0, "swipe_right", DWELL)]


def test_paths_and_bad_input(model_dir, stream, tmp_path) -> None:
    npz = tmp_path / "s.npz"
    write_labelled_stream(npz, stream)
    wsrec = tmp_path / "s.wsrec"
    convert_file(npz, wsrec)
    recognizer = load_recognizer(model_dir)
    expected = summary(run_pipeline(stream, recognizer).commands)
    assert summary(run_pipeline(npz, recognizer).commands) == expected
    assert summary(run_pipeline(wsrec, recognizer).commands) == expected
    with pytest.raises(FileNotFoundError, match="no such file"):
        run_pipeline(tmp_path / "missing.npz", recognizer)
    with pytest.raises(FileNotFoundError, match="no such model directory"):
        load_recognizer(tmp_path / "nowhere")
    with pytest.raises(ValueError, match="trained with other conditioning settings"):
        run_pipeline(stream, recognizer, conditioning=ConditioningConfig(smoothing_s=0.05))
    small = simulate_stream(3.0, seed=1, layout=None)
    small.frames = small.frames[:, :8]
    with pytest.raises(ValueError, match="model expects 10x10 frames at 200 Hz, got 8x10"):
        run_pipeline(small, recognizer)
    short = LabelledStream(stream.frames[:50], stream.t[:50], 200.0)
    with pytest.raises(ValueError, match="fewer than the 100 the calibration needs"):
        run_pipeline(short, recognizer)
    with pytest.raises(ValueError, match="block_frames"):
        run_pipeline(stream, recognizer, block_frames=0)


def test_models_not_trained_on_streams_are_refused(tmp_path) -> None:
    captures = make_model(tmp_path / "captures", {"capture_normalisation": {"scale": 1.0}})
    with pytest.raises(ValueError, match="not trained on conditioned skin streams"):
        conditioning_for_model(OnnxRecognizer(captures))


class _MetaOnly:
    def __init__(self, arbiter: dict) -> None:
        self.meta = type("Meta", (), {"arbiter": arbiter})()


def test_arbiter_settings_follow_the_models_recommendation_unless_overridden() -> None:
    recognizer = _MetaOnly({"min_probability": 0.9, "not_a_setting": 1})
    assert arbiter_settings_for_model(recognizer).min_probability == 0.9
    assert arbiter_settings_for_model(recognizer, min_probability=None).min_probability == 0.9
    assert arbiter_settings_for_model(recognizer, min_probability=0.5).min_probability == 0.5
    assert arbiter_settings_for_model(object()).min_probability == 0.0
    with pytest.raises(ValueError, match="min_probability"):
        arbiter_settings_for_model(_MetaOnly({"min_probability": 3.0}))
