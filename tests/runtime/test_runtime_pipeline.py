"""Tests of the composition root's live chain (wovenskin.runtime.pipeline and .sources)."""

from __future__ import annotations

import pytest
from stand_ins import ContactMeans

from wovenskin.errors import ConfigError
from wovenskin.recognition.pipeline import LivePipeline
from wovenskin.recording.formats import write_labelled_stream
from wovenskin.recording.native import read_recording
from wovenskin.runtime.pipeline import open_live_pipeline, open_live_skin
from wovenskin.runtime.sources import open_source
from wovenskin.signal.live_skin import LiveSkin
from wovenskin.sim.live import SimulatedSkinSource
from wovenskin.sim.stream import simulate_stream


def test_a_simulated_skin_wired_by_the_runtime_produces_commands() -> None:
    chain = open_live_pipeline("sim:seed=3,speed=0", recognizer=ContactMeans("swipe_up"))
    assert isinstance(chain.source, SimulatedSkinSource) and chain.source.speed == 0.0
    assert isinstance(chain.live_skin, LiveSkin) and chain.live_skin.source is chain.source
    assert isinstance(chain.pipeline, LivePipeline) and chain.recorder is None
    chain.live_skin.start()
    try:
        for _ in range(2000):  # a few seconds of stream: calibration, then the first touch
            block = chain.live_skin.step(timeout=0.05)
            if block is not None:
                chain.pipeline.feed(block)
            if any(change.gesture == "swipe_up" for change in chain.pipeline.changes):
                break
    finally:
        chain.close()
    assert [c.gesture for c in chain.pipeline.changes][:1] == ["swipe_up"]


@pytest.mark.parametrize(
    ("spec", "words"),
    [
        ("bogus:x", "unknown skin source"),
        ("sim:colour=red", "unknown setting 'colour'"),
        ("sim:speed=fast", "speed"),
        ("serial", "names no port"),
        ("replay:", "names no file"),
        ("sim:seed", "gives the simulated skin a target"),
        ("sim:seed=1,seed=2", "twice"),
    ],
)
def test_a_bad_spec_is_one_config_error_line(spec: str, words: str) -> None:
    with pytest.raises(ConfigError, match=words) as caught:
        open_live_pipeline(spec, recognizer=ContactMeans("push"))
    assert "\n" not in str(caught.value)
    with pytest.raises(ConfigError):
        open_source(spec)


def test_defaults_fill_only_the_options_a_spec_leaves_unset(tmp_path) -> None:
    path = tmp_path / "s.npz"
    write_labelled_stream(path, simulate_stream(2.0, seed=1))
    fast = open_live_skin(f"replay:{path}", defaults={"speed": 0})
    assert fast.spec.options == {"speed": "0"} and fast.spec.target == str(path)
    kept = open_live_skin(f"replay:{path}?speed=2", defaults={"speed": 0})
    assert kept.spec.options == {"speed": "2"}


def test_a_recording_holds_the_conditioning_and_the_given_settings(tmp_path) -> None:
    out = tmp_path / "r.wsrec"
    chain = open_live_pipeline("sim:seed=2,speed=0", recognizer=ContactMeans("push"))
    chain.record(out, settings={"session": {"robot": "sim"}})
    assert chain.live_skin.recorder is chain.recorder is not None
    chain.live_skin.start()
    try:
        for _ in range(20):
            chain.live_skin.step(timeout=0.05)
    finally:
        chain.close()
    recording = read_recording(out)
    assert recording.provenance["skin_source"] == "sim:seed=2,speed=0"
    assert recording.settings["conditioning"] == chain.live_skin.config.to_dict()
    assert recording.settings["session"] == {"robot": "sim"}
    assert len(recording.frames) > 0


class EightByEight(ContactMeans):
    """A stand-in recogniser trained on an 8x8 skin: it refuses any other grid."""

    def check_input(self, rows, cols, window, sample_rate_hz, conditioning) -> None:
        if (rows, cols) != (8, 8):
            raise ValueError(f"the model needs an 8x8 skin, got {rows}x{cols}")


def test_the_model_checks_the_skin_it_is_wired_to() -> None:
    with pytest.raises(ValueError, match="8x8"):
        open_live_pipeline("sim:speed=0", recognizer=EightByEight("push"))
    chain = open_live_pipeline("sim:speed=0,rows=8,cols=8", recognizer=EightByEight("push"))
    assert chain.pipeline is not None and chain.pipeline.streaming.shape == (8, 8)


def test_a_recording_started_with_the_skin_records_from_the_first_frame(tmp_path) -> None:
    out = tmp_path / "v.wsrec"
    chain = open_live_skin(
        "sim:seed=4,speed=0",
        record=out,
        provenance=lambda info: {"skin_id": info.device_id},
        recorded={"plan": "none"},
    )
    chain.live_skin.start()
    try:
        for _ in range(200):
            chain.live_skin.step(timeout=0.05)
            if chain.live_skin.stats().good_frames >= 50:
                break
    finally:
        chain.close()
    recording = read_recording(out)
    assert recording.provenance["skin_id"] == "sim-seed-4"
    assert recording.settings["plan"] == "none" and recording.seq[0] == 0
