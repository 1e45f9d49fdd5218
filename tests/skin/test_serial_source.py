"""End-to-end tests of SerialSkinSource against FakeSkinDevice over real pseudo-terminals.

Timing is never asserted: every wait is a polling loop bounded by a generous timeout that
only guards against hangs.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Iterator

import numpy as np
import pytest

from wovenskin.runtime.sources import open_source
from wovenskin.sim.pty_skin import FakeSkinDevice
from wovenskin.skin.frames import Frame, SourceEvent
from wovenskin.skin.layout import ChannelOrder, SkinLayout
from wovenskin.skin.messages import CommandId, SampleDtype
from wovenskin.skin.serial_source import SerialSkinSource
from wovenskin.skin.source import SkinSource

WAIT_S = 5.0


class Collector:
    """Everything a source delivered, with a bounded wait for a condition."""

    def __init__(self, source: SerialSkinSource) -> None:
        self.source = source
        self.frames: list[Frame] = []
        self.events: list[SourceEvent] = []

    def kinds(self) -> list[str]:
        return [e.kind for e in self.events]

    def wait(self, condition: Callable[[], bool], what: str, timeout: float = WAIT_S) -> None:
        deadline = time.monotonic() + timeout
        while not condition():
            if time.monotonic() > deadline:
                raise AssertionError(
                    f"timed out waiting for {what}; events={self.kinds()}, "
                    f"frames={len(self.frames)}, stats={self.source.stats()}"
                )
            for item in self.source.poll(0.02):
                (self.frames if isinstance(item, Frame) else self.events).append(item)

    def wait_frames(self, n: int, what: str = "frames") -> None:
        target = len(self.frames) + n
        self.wait(lambda: len(self.frames) >= target, f"{n} {what}")


@pytest.fixture
def rig() -> Iterator[Callable[..., tuple[FakeSkinDevice, SerialSkinSource, Collector]]]:
    opened: list = []

    def make(spec_options: str = "", **device_kwargs):
        device = FakeSkinDevice(**device_kwargs).start()
        opened.append(device)
        source = open_source(f"serial:{device.port}" + (f"?{spec_options}" if spec_options else ""))
        assert isinstance(source, SerialSkinSource) and isinstance(source, SkinSource)
        opened.append(source)
        source.start()
        return device, source, Collector(source)

    yield make
    for thing in reversed(opened):
        thing.close() if isinstance(thing, SerialSkinSource) else thing.stop()


def _assert_matches_device(frames: list[Frame], expected: dict[int, np.ndarray]) -> int:
    checked = 0
    for frame in frames:
        if frame.seq in expected:
            assert frame.values.dtype == np.float32
            np.testing.assert_array_equal(frame.values, expected[frame.seq])
            checked += 1
    return checked


def _increasing(frames: list[Frame]) -> bool:
    times = [f.t for f in frames]
    return all(b > a for a, b in zip(times, times[1:], strict=False))


def test_info_is_picked_up_and_frames_arrive_bit_exact_in_row_col_order(rig):
    layout = SkinLayout(6, 8, row_pitch_mm=12.0, col_pitch_mm=9.0)
    order = ChannelOrder("col", flip_rows=True, flip_cols=False)
    device, source, got = rig(layout=layout, order=order, rate_hz=250.0, device_id="skin-A")
    got.wait(lambda: "info" in got.kinds(), "the INFO event")
    info = source.info
    assert (info.rows, info.cols, info.sample_rate_hz) == (6, 8, 250.0)
    assert ChannelOrder.parse(info.channel_order) == order
    assert (info.row_pitch_mm, info.col_pitch_mm, info.device_id) == (12.0, 9.0, "skin-A")
    assert got.events[0].kind == "connected"
    got.wait_frames(60)
    frames = [f for f in got.frames if f.values.shape == (6, 8)]
    assert _assert_matches_device(frames, device.expected_frames()) == len(got.frames) >= 60
    assert _increasing(got.frames)
    assert all(b.seq == a.seq + 1 for a, b in zip(got.frames, got.frames[1:], strict=False))
    stats = source.stats()
    assert stats.connected and stats.dropped_frames == 0 and stats.bytes_read > 0
    assert stats.good_frames >= len(got.frames)  # more may have arrived since the last poll
    sent = [c.command for c in device.commands]
    assert CommandId.GET_INFO in sent and CommandId.START in sent


def test_integer_samples_are_scaled_with_the_info_scale(rig):
    device, source, got = rig(dtype=SampleDtype.U16, scale=0.001)
    got.wait_frames(40)
    values = np.stack([f.values for f in got.frames])
    assert 10.0 < float(values.mean()) < 30.0  # pF, not counts
    assert _assert_matches_device(got.frames, device.expected_frames()) == len(got.frames)


def test_bad_packets_are_counted_and_the_stream_goes_on(rig):
    device, source, got = rig()
    got.wait_frames(10)

    def inject_and_wait(inject: Callable[[], None], reason: str) -> None:
        before = source.stats().bad_reasons.get(reason, 0)
        inject()
        got.wait(lambda: source.stats().bad_reasons.get(reason, 0) > before, f"a {reason} error")
        got.wait_frames(3, f"frames after {reason}")

    inject_and_wait(device.corrupt_next_crc, "crc")
    inject_and_wait(device.send_nan_frame, "nonfinite")
    inject_and_wait(device.send_wrong_shape, "shape")
    bad_before = source.stats().bad_frames
    device.inject_garbage(300)
    got.wait(lambda: source.stats().bad_frames > bad_before, "garbage to be counted")
    device.drop_frames(3)
    got.wait(lambda: source.stats().dropped_frames >= 4, "the dropped frames")
    got.wait_frames(10, "frames after the faults")

    stats = source.stats()
    # The frame lost to the CRC error is a gap too; NaN / wrong-shape frames kept their seq.
    assert stats.dropped_frames == 4
    assert stats.resets == 0 and stats.connected
    assert _assert_matches_device(got.frames, device.expected_frames()) == len(got.frames)
    assert _increasing(got.frames)


def test_a_device_reset_is_detected_and_the_clock_stays_continuous(rig):
    device, source, got = rig()
    got.wait_frames(20)
    device.reset()
    got.wait(lambda: source.stats().resets == 1, "the reset")
    got.wait_frames(20, "frames after the reset")
    stats = source.stats()
    assert stats.resets == 1 and stats.dropped_frames == 0
    assert "reset" in got.kinds()
    assert _increasing(got.frames)
    seqs = [f.seq for f in got.frames]
    restart = next(i for i in range(1, len(seqs)) if seqs[i] < seqs[i - 1])
    after = got.frames[restart:]
    assert after[0].seq < 20 and len(after) >= 20
    assert _assert_matches_device(after, device.expected_frames(boot=1)) == len(after)


def test_a_pause_is_reported_as_stalled_then_resumed(rig):
    device, source, got = rig()
    got.wait_frames(10)
    device.pause(0.3)
    got.wait(lambda: "resumed" in got.kinds(), "stalled then resumed")
    kinds = got.kinds()
    assert kinds.index("stalled") < kinds.index("resumed")
    stalled = next(e for e in got.events if e.kind == "stalled")
    last_frame = max(f.t_host for f in got.frames if f.t_host <= stalled.t_host)
    assert stalled.t_host - last_frame > source.stall_s
    assert not source.stats().stalled
    got.wait_frames(5)
    assert source.stats().dropped_frames == 0 and _increasing(got.frames)


def test_unplug_and_replug_reconnects_and_frames_resume(rig):
    device, source, got = rig()
    got.wait_frames(10)
    device.unplug()
    got.wait(lambda: "disconnected" in got.kinds(), "the disconnection")
    assert not source.stats().connected
    time.sleep(0.2)  # a few failed reconnection attempts while the port is gone
    device.replug()
    got.wait(lambda: got.kinds().count("connected") == 2, "the reconnection")
    got.wait_frames(20, "frames after the reconnection")
    stats = source.stats()
    assert stats.reconnects == 1 and stats.connected
    assert _increasing(got.frames)
    kinds = got.kinds()
    assert kinds.index("disconnected") < len(kinds) - 1 - kinds[::-1].index("connected")


def test_commands_reach_the_device_and_are_acknowledged(rig):
    device, source, got = rig()
    got.wait_frames(5)
    source.send_command("stop")
    got.wait(lambda: any(a.command == CommandId.STOP and a.ok for a in source.acks), "ACK of stop")
    got.wait(lambda: "stalled" in got.kinds(), "the stream to stop")
    assert not device.streaming
    source.send_command("recalibrate")
    source.send_command("start")
    got.wait(lambda: "resumed" in got.kinds(), "the stream to restart")
    acked = {a.command for a in source.acks if a.ok}
    assert {CommandId.START, CommandId.STOP, CommandId.RECALIBRATE} <= acked
    assert "error" not in got.kinds()
    with pytest.raises(ValueError, match="unknown skin command"):
        source.send_command("selfdestruct")


def test_integer_frames_without_any_info_are_rejected_and_info_is_requested_again(rig):
    device, source, got = rig(dtype=SampleDtype.U16, info_enabled=False)
    got.wait(lambda: source.stats().bad_reasons.get("no-info", 0) >= 20, "no-info rejections")
    got.wait(
        lambda: sum(c.command == CommandId.GET_INFO for c in device.commands) >= 2,
        "a repeated GET_INFO",
    )
    assert got.frames == []
    assert any("refused 'get_info'" in e.message for e in got.events if e.kind == "error")


def test_text_lines_over_a_pty(rig, caplog):
    layout = SkinLayout(4, 5)
    order = ChannelOrder("col", flip_rows=False, flip_cols=True)
    device, source, got = rig(
        "format=text&order=col-major,flip-cols&rows=4&cols=5&skip=1&rate=200",
        layout=layout,
        order=order,
        fmt="text",
    )
    got.wait_frames(30)
    device.send_nan_frame()
    device.send_wrong_shape()
    device.inject_garbage(200)
    got.wait(lambda: source.stats().bad_frames >= 3, "bad text lines")
    got.wait_frames(20, "frames after the bad lines")
    stats = source.stats()
    assert stats.bad_reasons.get("nonfinite") == 1 and stats.bad_reasons.get("channels", 0) >= 1
    # Lines carry no device seq: the host numbers them and they match the device in order.
    sent = [s.values for s in device.sent]
    start = next(i for i, s in enumerate(sent) if np.array_equal(s, got.frames[0].values))
    for frame, expected in zip(got.frames, sent[start:], strict=False):
        np.testing.assert_array_equal(frame.values, expected)
    assert [f.seq for f in got.frames] == list(range(len(got.frames)))
    assert _increasing(got.frames)
    assert source.info.channel_order == "col-major,flip-cols"
    with caplog.at_level(logging.WARNING):
        source.send_command("recalibrate")
    assert "no commands" in caplog.text


def test_opening_a_missing_port_fails_clearly_and_close_is_idempotent(tmp_path):
    source = SerialSkinSource(str(tmp_path / "no-such-port"))
    with pytest.raises(ConnectionError, match="cannot open serial port"):
        source.start()
    source.close()
    source.close()


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ("serial:/dev/x?format=morse", "format"),
        ("serial:/dev/x?rows=ten", "rows: Input should be a valid integer"),
        ("serial:/dev/x?colour=red", "serial options: unknown setting 'colour'"),
        ("serial:/dev/x?order=col-major", "INFO"),
        ("serial:/dev/x?format=text&order=diagonal", "channel order"),
        ("serial:/dev/x?stall_ms=0", "stall_ms"),
    ],
)
def test_bad_options_are_rejected_with_a_clear_message(spec, message):
    with pytest.raises(ValueError, match=message):
        open_source(spec)


def test_options_are_parsed():
    source = SerialSkinSource.from_options(
        "/dev/x",
        {
            "format": "text",
            "order": "row-major,flip-rows",
            "rows": "8",
            "cols": "12",
            "rate": "100",
            "baud": "115200",
            "stall_ms": "50",
            "sep": "tab",
            "skip": "1",
        },
    )
    assert (source.fmt, source.baud, source.stall_s) == ("text", 115200, 0.05)
    assert (source.info.rows, source.info.cols, source.info.sample_rate_hz) == (8, 12, 100.0)
    assert source.info.channel_order == "row-major,flip-rows"
    assert source.info.source == "serial:/dev/x"
    assert source.poll(0.0) == [] and not source.stats().connected
