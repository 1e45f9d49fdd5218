"""Tests for the simulated skin controller, read from its pseudo-terminal."""

from __future__ import annotations

import contextlib
import os
import select
import threading
import time
from collections.abc import Callable, Iterator

import numpy as np
import pytest

from wovenskin.sim.fake_device import REST_ON_START_S, RestingPerson, run_fake_device
from wovenskin.sim.pty_skin import FakeSkinDevice
from wovenskin.skin.frames import Frame
from wovenskin.skin.layout import ChannelOrder, SkinLayout
from wovenskin.skin.messages import (
    AckMessage,
    AckStatus,
    CommandId,
    CommandMessage,
    FrameMessage,
    InfoMessage,
    SampleDtype,
)
from wovenskin.skin.protocol import StreamDecoder, encode_message
from wovenskin.skin.serial_source import SerialSkinSource
from wovenskin.skin.textlines import TextLineDecoder

WAIT_S = 5.0


class Host:
    """A bare host end: the pty opened with os.open, decoded by hand."""

    def __init__(self, path: str, decode: Callable[[bytes], list]) -> None:
        self.fd = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        self.decode = decode
        self.items: list = []

    def read_until(self, condition: Callable[[list], bool], what: str) -> list:
        deadline = time.monotonic() + WAIT_S
        while not condition(self.items):
            assert time.monotonic() < deadline, f"timed out waiting for {what}"
            ready, _, _ = select.select([self.fd], [], [], 0.02)
            if ready:
                with contextlib.suppress(BlockingIOError):
                    self.items.extend(self.decode(os.read(self.fd, 65536)))
        return self.items

    def send(self, data: bytes) -> None:
        os.write(self.fd, data)

    def close(self) -> None:
        os.close(self.fd)


@pytest.fixture
def devices() -> Iterator[list[FakeSkinDevice]]:
    made: list[FakeSkinDevice] = []
    yield made
    for device in made:
        device.stop()


def _of(items: list, kind: type) -> list:
    return [i for i in items if isinstance(i, kind)]


def test_binary_stream_answers_commands_and_follows_the_channel_order(devices):
    layout = SkinLayout(3, 5)
    order = ChannelOrder("col", flip_rows=False, flip_cols=True)
    device = FakeSkinDevice(layout=layout, order=order, dtype=SampleDtype.U16).start()
    devices.append(device)
    host = Host(device.port, StreamDecoder(scale=device.scale).feed)
    try:
        items = host.read_until(lambda i: len(_of(i, FrameMessage)) >= 10, "frames")
        expected = device.expected_frames()
        for frame in _of(items, FrameMessage):
            assert (frame.rows, frame.cols, frame.dtype) == (3, 5, SampleDtype.U16)
            np.testing.assert_array_equal(
                order.to_frames(frame.samples, layout), expected[frame.seq]
            )
        host.send(encode_message(CommandMessage(41, 0, CommandId.GET_INFO)))
        host.send(encode_message(CommandMessage(42, 0, CommandId.STOP)))
        host.send(encode_message(CommandMessage(43, 0, 99)))
        items = host.read_until(lambda i: len(_of(i, AckMessage)) >= 2, "two ACKs")
        info = _of(items, InfoMessage)[-1]
        assert (info.rows, info.cols, info.channel_order, info.dtype) == (
            3,
            5,
            order,
            SampleDtype.U16,
        )
        acks = {a.seq: a for a in _of(items, AckMessage)}
        assert acks[42].command == CommandId.STOP and acks[42].ok
        assert acks[43].status == AckStatus.UNKNOWN_COMMAND
        assert [c.seq for c in device.commands] == [41, 42, 43]
        assert not device.streaming
    finally:
        host.close()


def test_unplug_removes_the_port_and_replug_repoints_it(devices):
    device = FakeSkinDevice().start()
    devices.append(device)
    assert os.path.realpath(device.port) == device.pty_path
    device.unplug()
    assert not os.path.exists(device.port) and device.pty_path is None
    device.replug()
    assert os.path.realpath(device.port) == device.pty_path
    assert device.boot == 1
    host = Host(device.port, StreamDecoder().feed)
    try:
        host.read_until(lambda i: len(_of(i, FrameMessage)) >= 3, "frames after replug")
    finally:
        host.close()
    link_dir = os.path.dirname(device.port)
    device.stop()
    assert not os.path.exists(link_dir)


def test_text_lines_with_an_array_of_frames(devices):
    layout = SkinLayout(2, 3)
    frames = np.arange(4 * 6, dtype=np.float32).reshape(4, 2, 3) / 7.0
    device = FakeSkinDevice(frames, layout=layout, fmt="text", text_separator=" ").start()
    devices.append(device)
    host = Host(device.port, TextLineDecoder(layout, skip_columns=1).feed)
    try:
        items = host.read_until(lambda i: len(_of(i, np.ndarray)) >= 9, "text frames")
    finally:
        host.close()
    got = _of(items, np.ndarray)
    start = next(k for k in range(4) if np.array_equal(got[0], frames[k]))
    for n, frame in enumerate(got):
        np.testing.assert_array_equal(frame, frames[(start + n) % 4])


def test_invalid_configurations_are_rejected():
    with pytest.raises(ValueError, match="format"):
        FakeSkinDevice(fmt="morse")
    with pytest.raises(ValueError, match="F32"):
        FakeSkinDevice(fmt="text", dtype=SampleDtype.U16)
    with pytest.raises(ValueError, match="shape"):
        FakeSkinDevice(np.zeros((5, 3, 3), np.float32))
    text_device = FakeSkinDevice(fmt="text")
    try:
        with pytest.raises(ValueError, match="binary"):
            text_device.corrupt_next_crc()
    finally:
        text_device.stop()


def test_run_fake_device_streams_a_simulated_person_that_a_source_can_read():
    lines: list[str] = []
    devices_run: list[FakeSkinDevice] = []

    class Console:
        def print(self, text: str) -> None:
            lines.append(text)

    runner = threading.Thread(
        target=lambda: devices_run.append(run_fake_device(seconds=1.5, console=Console()))
    )
    runner.start()
    deadline = time.monotonic() + WAIT_S
    while not lines and time.monotonic() < deadline:
        time.sleep(0.01)
    assert lines, "run_fake_device printed nothing"
    port = lines[0].rsplit(" on ", 1)[1]
    source = SerialSkinSource(port)
    frames = []
    try:
        source.start()
        while len(frames) < 50 and time.monotonic() < deadline:
            frames += [i for i in source.poll(0.05) if isinstance(i, Frame)]
    finally:
        source.close()
        runner.join(timeout=WAIT_S)
    assert len(frames) >= 50
    values = np.stack([f.values for f in frames])
    assert values.shape[1:] == (10, 10) and 1.0 < values.mean() < 200.0
    assert devices_run and devices_run[0].frames_sent >= 50
    assert "--skin 'serial:" in lines[1] and lines[-1].startswith("sent ")


def test_the_simulated_person_rests_while_a_host_calibrates():
    """A host sends START when it starts reading: the person keeps hands off for a second,
    so the reader's calibration (its first 0.5 s) sees no touch wherever the loop was."""
    rng = np.random.default_rng(0)
    frames = 20.0 + rng.normal(0, 0.01, size=(400, 2, 2)).astype(np.float32)
    frames[100:] += 5.0  # a touch from frame 100 on; frames 0-99 are idle
    person = RestingPerson(frames, 100, 200.0)
    assert person(150, 0.75).mean() > 24.0  # mid-touch
    person.rest()  # START arrives
    resting = np.stack([person(k, k / 200.0) for k in range(151, 151 + int(REST_ON_START_S * 200))])
    assert resting.max() < 21.0
    assert person(151 + int(REST_ON_START_S * 200), 0.0).mean() > 24.0  # then the loop goes on


def test_sigterm_ends_fake_device_and_removes_its_folder(tmp_path):
    import os
    import signal
    import subprocess
    import sys

    process = subprocess.Popen(
        [sys.executable, "-m", "wovenskin.cli", "fake-device"],
        stdout=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        first = process.stdout.readline()
        port = first.rsplit(" on ", 1)[1].strip()
        assert os.path.exists(port) and "\n" not in port
        process.send_signal(signal.SIGTERM)
        process.wait(timeout=WAIT_S)
    finally:
        if process.poll() is None:
            process.kill()
    assert not os.path.exists(os.path.dirname(port))
