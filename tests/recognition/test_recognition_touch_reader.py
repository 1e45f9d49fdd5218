"""The touch reader: geometry and the network's windows fused over the whole touch."""

from __future__ import annotations

import numpy as np
import pytest

from tests.touch_synth import COLS, CP, RATE, ROWS, RP, active_of, frame_of
from wovenskin.errors import ConfigError
from wovenskin.gestures import CLASS_NAMES, INVALID
from wovenskin.independent import mixed_stream
from wovenskin.recognition.pipeline import (
    PipelineSettings,
    load_recognizer,
    pipeline_settings_for_model,
    run_pipeline,
)
from wovenskin.recognition.touch_reader import ReaderSettings, TouchRecognizer


def _probabilities(**named: float) -> np.ndarray:
    row = np.full(len(CLASS_NAMES), 1e-3)
    for name, p in named.items():
        row[CLASS_NAMES.index(name)] = p
    return row / row.sum()


def _readings(probabilities, frames: int = 80) -> list[str | None]:
    """The readings of one fingertip sliding up at 100 mm/s; ``probabilities(k)``: the
    network's row at frame ``k``."""
    reader = TouchRecognizer(CLASS_NAMES, ROWS, COLS, RP, CP, RATE)
    out = []
    for k in range(frames):
        frame = frame_of([(110.0 - 0.5 * k, 45.0)], sd_mm=6.0)
        row = reader.step(frame, active_of(frame), True, probabilities(k))
        out.append(CLASS_NAMES[int(np.argmax(row))])
    return out


def test_the_touch_reads_the_direction_the_window_got_wrong() -> None:
    down, up = _probabilities(swipe_down=0.9, invalid=0.1), _probabilities(swipe_up=0.6)

    readings = _readings(lambda k: down if k < 45 else up)  # the windows mostly say down
    assert readings[0] == INVALID  # no travel yet: nothing counts
    assert readings[-1] == "swipe_up"  # 40 mm up outweighs the windows' swipe_down


def test_the_evidence_the_bars_show_is_the_touch_so_far_not_the_latest_window() -> None:
    """The windows say down, the finger went 40 mm up: the reader reads swipe_up, and its
    evidence (what the dashboard's bars show) agrees with the reading, not the window."""
    down, up = _probabilities(swipe_down=0.9, invalid=0.1), _probabilities(swipe_up=0.6)
    reader = TouchRecognizer(CLASS_NAMES, ROWS, COLS, RP, CP, RATE)
    assert reader.evidence() is None  # no touch
    for k in range(80):
        frame = frame_of([(110.0 - 0.5 * k, 45.0)], sd_mm=6.0)
        reader.step(frame, active_of(frame), True, down if k < 45 else up)
    evidence = reader.evidence()
    assert reader.reading == "swipe_up"
    assert CLASS_NAMES[int(np.argmax(evidence))] == "swipe_up"
    assert evidence[CLASS_NAMES.index(INVALID)] == 0.0 and abs(float(evidence.sum()) - 1) < 1e-5
    reader.step(np.zeros((ROWS, COLS)), np.zeros((ROWS, COLS), bool), False, up)  # lift-off
    assert reader.evidence() is None


def test_geometry_alone_starts_nothing() -> None:
    readings = _readings(lambda k: _probabilities(invalid=0.97))
    assert set(readings) == {INVALID}


def test_bad_reader_settings_are_one_line() -> None:
    with pytest.raises(ConfigError, match="min_travel_mm"):
        ReaderSettings(min_travel_mm=-1.0)
    with pytest.raises(ConfigError, match="reader must be one of"):
        PipelineSettings(reader="bogus")


def test_the_shipped_model_reads_the_touch_and_any_split_of_the_stream_agrees() -> None:
    recognizer = load_recognizer(None, threads=1)
    settings = pipeline_settings_for_model(recognizer)
    assert settings.reader == "touch"
    assert pipeline_settings_for_model(recognizer, reader="window").reader == "window"
    stream = mixed_stream(20.0, 5)
    whole = run_pipeline(stream, recognizer, settings).commands
    pieces = run_pipeline(stream, recognizer, settings, block_frames=37).commands
    assert [(round(c.t, 6), c.gesture, c.reason) for c in whole] == [
        (round(c.t, 6), c.gesture, c.reason) for c in pieces
    ]
    assert any(c.gesture for c in whole)
