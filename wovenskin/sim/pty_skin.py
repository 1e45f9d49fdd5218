"""A simulated ESP32-S3 skin controller on a pseudo-terminal, with fault injection.

:class:`FakeSkinDevice` streams frames at a fixed rate into a pty created with
:func:`os.openpty`, in the binary protocol of ``docs/protocol.md`` (or as text lines),
exactly as firmware would on a USB serial port: it answers GET_INFO with INFO, ACKs
START/STOP/RECALIBRATE, and on demand misbehaves (garbage bytes, bad CRC, NaN frames,
wrong shapes, dropped frames, reboots, stalls, unplugging).  Its :attr:`port` is a
symlink in a temporary directory (like ``/dev/serial/by-id/...``) that keeps its name
across :meth:`unplug`/:meth:`replug`, so a host can reconnect to the same path.

``wovenskin fake-device`` (:mod:`wovenskin.sim.fake_device`) runs one with a simulated
person's gestures.

POSIX only (pseudo-terminals).
"""

from __future__ import annotations

import contextlib
import errno
import logging
import os
import select
import shutil
import tempfile
import threading
import time
import tty
from collections import deque
from collections.abc import Callable

import numpy as np

from wovenskin.errors import ConfigError
from wovenskin.sim.device_frames import (
    BOOT_BANNER,
    DEFAULT_SCALES,
    BaselineFrames,
    FrameFn,
    SentFrame,
)
from wovenskin.skin.layout import DEFAULT_SAMPLE_RATE_HZ, ROW_MAJOR, ChannelOrder, SkinLayout
from wovenskin.skin.messages import (
    AckMessage,
    AckStatus,
    CommandId,
    CommandMessage,
    FrameMessage,
    InfoMessage,
    LogMessage,
    SampleDtype,
    dequantize,
    quantize,
)
from wovenskin.skin.protocol import (
    DELIMITER,
    StreamDecoder,
    cobs_frame,
    encode_message,
    pack_message,
)

log = logging.getLogger(__name__)

MAX_TX_BACKLOG = 65536  # bytes buffered while no host reads; beyond this they are dropped


class FakeSkinDevice:
    """A simulated skin controller writing to a pty; see the module docstring.

    ``frames`` is a callable ``fn(index, t_s) -> (rows, cols)`` or an array
    ``(N, rows, cols)`` played in a loop; ``None`` gives :class:`BaselineFrames`.
    ``order`` is the channel order the device streams in (frames are given in
    ``[row, col]`` order and converted with :meth:`ChannelOrder.to_samples`).
    ``info_enabled=False`` mimics a firmware that never sends INFO (GET_INFO is then
    answered with an "unknown command" ACK); ``stream_at_boot=False`` one that waits
    for START.
    """

    def __init__(
        self,
        frames: FrameFn | np.ndarray | None = None,
        rate_hz: float = DEFAULT_SAMPLE_RATE_HZ,
        layout: SkinLayout | None = None,
        order: ChannelOrder = ROW_MAJOR,
        dtype: SampleDtype = SampleDtype.F32,
        fmt: str = "binary",
        *,
        scale: float | None = None,
        seed: int = 0,
        firmware: str = "fake-esp32s3 1.0",
        device_id: str = "fake-skin-0",
        text_separator: str = ",",
        text_counter: bool = True,
        boot_banner: bool = True,
        stream_at_boot: bool = True,
        info_enabled: bool = True,
        link_dir: str | None = None,
        history: int = 20000,
        on_start: Callable[[], None] | None = None,
    ) -> None:
        if fmt not in ("binary", "text"):
            raise ConfigError(f"format must be 'binary' or 'text', got {fmt!r}")
        if fmt == "text" and dtype != SampleDtype.F32:
            raise ConfigError("text lines carry decimal values: use dtype F32 with fmt='text'")
        if not rate_hz > 0:
            raise ConfigError(f"rate must be positive, got {rate_hz}")
        self.layout = layout or SkinLayout()
        self.order = order
        self.dtype = SampleDtype(dtype)
        scale = DEFAULT_SCALES[self.dtype] if scale is None else scale
        self.scale = float(np.float32(scale))  # INFO carries it as f32: use what the host sees
        self.fmt = fmt
        self.rate_hz = float(rate_hz)
        self.firmware = firmware
        self.device_id = device_id
        self.text_separator = text_separator
        self.text_counter = text_counter
        self.boot_banner = boot_banner
        self.stream_at_boot = stream_at_boot
        self.info_enabled = info_enabled
        self._frame_fn = self._as_frame_fn(frames, seed)
        self._on_start = on_start  # called when a host sends START or RECALIBRATE
        self._rng = np.random.default_rng(seed + 7)

        self._link_dir = link_dir
        self._own_link_dir = link_dir is None
        self.port: str | None = None
        """The stable port path (a symlink to the current pty), set by :meth:`start`."""
        self.pty_path: str | None = None

        self._lock = threading.RLock()
        self._master: int | None = None
        self._slave: int | None = None
        self._tx = bytearray()
        self._decoder = StreamDecoder()
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()

        # Device state, guarded by _lock.
        self.boot = 0
        self._power_on()
        self._corrupt_next_crc = False
        self._nan_next = False
        self._wrong_shape_next = False
        self._skip_next = 0

        # What happened, for tests and diagnostics.
        self.sent: deque[SentFrame] = deque(maxlen=history)
        self.commands: list[CommandMessage] = []
        self.frames_sent = 0
        self.tx_dropped_bytes = 0
        self.error: str = ""

    # ------------------------------------------------------------------ lifecycle

    def start(self) -> FakeSkinDevice:
        """Create the pty, boot and start streaming in a background thread."""
        with self._lock:
            if self._thread is not None:
                return self
            self._plug()
            self._boot_sequence()
            self._stop.clear()
            self._thread = threading.Thread(target=self._run, name="fake-skin", daemon=True)
            self._thread.start()
        return self

    def stop(self) -> None:
        """Stop streaming, close the pty and remove the port symlink (idempotent)."""
        self._stop.set()
        thread, self._thread = self._thread, None
        if thread is not None:
            thread.join(timeout=2.0)
        with self._lock:
            self._unplug()
        if self._own_link_dir and self._link_dir is not None:
            shutil.rmtree(self._link_dir, ignore_errors=True)
            self._link_dir = None

    def __enter__(self) -> FakeSkinDevice:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    # ------------------------------------------------------------------ fault injection

    def inject_garbage(self, n: int, delimited: bool = True) -> None:
        """Write ``n`` random bytes (then a delimiter, unless ``delimited=False``)."""
        junk = self._rng.integers(0, 256, size=n, dtype=np.uint8).tobytes()
        if self.fmt == "text":
            junk = junk.replace(b"\n", b"?").replace(b"\r", b"?") + b"\r\n"
        elif delimited:
            junk += DELIMITER
        with self._lock:
            self._tx += junk

    def corrupt_next_crc(self) -> None:
        """Send the next frame with a wrong CRC (binary only)."""
        self._require_binary("corrupt_next_crc")
        with self._lock:
            self._corrupt_next_crc = True

    def send_nan_frame(self) -> None:
        """Make the next frame hold a NaN (it still uses its sequence number)."""
        with self._lock:
            self._nan_next = True

    def send_wrong_shape(self) -> None:
        """Make the next frame one column wider (or narrower) than INFO declares."""
        with self._lock:
            self._wrong_shape_next = True

    def drop_frames(self, n: int) -> None:
        """Skip sending the next ``n`` frames: the host sees a sequence gap."""
        with self._lock:
            self._skip_next += n

    def reset(self) -> None:
        """Reboot: the sequence number and device clock restart from zero."""
        with self._lock:
            self.boot += 1
            self._power_on()
            self._boot_sequence()

    def pause(self, seconds: float) -> None:
        """Stop producing frames for ``seconds`` (a firmware stall); no sequence gap."""
        with self._lock:
            self._paused_until = time.monotonic() + seconds

    def unplug(self) -> None:
        """Close the pty and remove the port symlink, as pulling the USB cable would."""
        with self._lock:
            self._unplug()

    def replug(self) -> None:
        """Create a fresh pty behind the same :attr:`port` path and boot again."""
        with self._lock:
            if self._master is not None:
                return
            self._plug()
        self.reset()

    def send_log(self, text: str) -> None:
        """Send a LOG message (binary) or a ``#`` comment line (text)."""
        with self._lock:
            self._send_log(text)

    def expected_frames(self, boot: int | None = None) -> dict[int, np.ndarray]:
        """``{seq: frame}`` of what was sent in ``boot`` (default: the current boot)."""
        with self._lock:
            boot = self.boot if boot is None else boot
            return {s.seq: s.values for s in self.sent if s.boot == boot}

    @property
    def info(self) -> InfoMessage:
        return InfoMessage(
            seq=self._info_seq,
            device_t_us=self._now_us(),
            firmware=self.firmware,
            device_id=self.device_id,
            rows=self.layout.rows,
            cols=self.layout.cols,
            sample_rate_hz=self.rate_hz,
            dtype=self.dtype,
            channel_order=self.order,
            scale=self.scale,
            units="pF",
            row_pitch_mm=self.layout.row_pitch_mm,
            col_pitch_mm=self.layout.col_pitch_mm,
        )

    # ------------------------------------------------------------------ internals

    def _require_binary(self, what: str) -> None:
        if self.fmt != "binary":
            raise ValueError(f"{what} needs the binary format")

    def _as_frame_fn(self, frames: FrameFn | np.ndarray | None, seed: int) -> FrameFn:
        if frames is None:
            return BaselineFrames(self.layout, seed)
        if callable(frames):
            return frames
        array = np.asarray(frames, dtype=np.float32)
        if array.ndim != 3:
            raise ValueError(f"frames must be (N, rows, cols), got shape {array.shape}")
        self.layout.check_frames(array)
        return lambda index, t_s: array[index % len(array)]

    def _plug(self) -> None:
        if self._link_dir is None:
            self._link_dir = tempfile.mkdtemp(prefix="wovenskin-fake-")
        if self.port is None or os.path.dirname(self.port) != self._link_dir:
            self.port = os.path.join(self._link_dir, f"usb-wovenskin_{self.device_id}-if00")
        master, slave = os.openpty()
        # Raw mode on both ends: no CR/LF translation, no echo, every byte passes as is.
        tty.setraw(master)
        tty.setraw(slave)
        os.set_blocking(master, False)
        self._master, self._slave = master, slave
        self.pty_path = os.ttyname(slave)
        self._decoder.reset()
        self._tx.clear()
        tmp_link = self.port + ".tmp"
        with contextlib.suppress(FileNotFoundError):
            os.unlink(tmp_link)
        os.symlink(self.pty_path, tmp_link)
        os.replace(tmp_link, self.port)  # atomic repoint, like udev updating by-id links

    def _unplug(self) -> None:
        if self.port is not None:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(self.port)
        for fd in (self._master, self._slave):
            if fd is not None:
                with contextlib.suppress(OSError):
                    os.close(fd)
        self._master = self._slave = None
        self.pty_path = None
        self._tx.clear()

    def _power_on(self) -> None:
        """Sequence numbers and the device clock start from zero, as at power-on."""
        self._seq = 0
        self._info_seq = 0
        self._log_seq = 0
        self._boot_t = time.monotonic()
        self._next_due = self._boot_t
        self._paused_until = 0.0
        self.streaming = self.stream_at_boot

    def _now_us(self) -> int:
        return int(round((time.monotonic() - self._boot_t) * 1e6))

    def _boot_sequence(self) -> None:
        if self.boot_banner:
            self._tx += BOOT_BANNER
        if self.fmt == "binary":
            self._tx += DELIMITER  # delimit whatever came before (ROM banner, line noise)
            if self.info_enabled:
                self._send_info()
        self._send_log(f"{self.firmware} booted ({self.layout.rows}x{self.layout.cols})")

    def _send_info(self) -> None:
        self._tx += encode_message(self.info)
        self._info_seq += 1

    def _send_log(self, text: str) -> None:
        if self.fmt == "text":
            self._tx += b"# " + text.encode("utf-8", errors="replace") + b"\r\n"
            return
        self._tx += encode_message(LogMessage(self._log_seq, self._now_us(), text))
        self._log_seq += 1

    def _run(self) -> None:
        period = 1.0 / self.rate_hz
        while not self._stop.is_set():
            with self._lock:
                master = self._master
                now = time.monotonic()
                if master is not None:
                    self._read_commands(master)
                    if now >= self._paused_until and now >= self._next_due:
                        if self._paused_until:
                            self._next_due = max(self._next_due, self._paused_until)
                            self._paused_until = 0.0
                        if self.streaming and not self.error:
                            self._produce_frame(self._next_due)
                        self._next_due += period
                        if now - self._next_due > 0.25:
                            self._next_due = now + period  # fell far behind: skip, no burst
                    self._flush(master)
                wait = min(0.005, max(0.0, self._next_due - time.monotonic()))
            if master is None:
                self._stop.wait(0.005)
                continue
            try:
                select.select([master], [], [], wait)
            except (OSError, ValueError):
                self._stop.wait(0.005)  # the pty was closed under us (unplug)

    def _read_commands(self, master: int) -> None:
        try:
            data = os.read(master, 4096)
        except BlockingIOError:
            return
        except OSError as exc:
            if exc.errno not in (errno.EIO, errno.EBADF):
                log.warning("fake device read failed: %s", exc)
            return
        if self.fmt != "binary":
            return  # a text firmware ignores its input
        for item in self._decoder.feed(data):
            if isinstance(item, CommandMessage):
                self.commands.append(item)
                self._handle_command(item)

    def _handle_command(self, cmd: CommandMessage) -> None:
        status = AckStatus.OK
        if cmd.command == CommandId.GET_INFO and self.info_enabled:
            self._send_info()
            return
        if cmd.command == CommandId.START:
            self.streaming = True
            if self._on_start is not None:
                self._on_start()
        elif cmd.command == CommandId.STOP:
            self.streaming = False
        elif cmd.command == CommandId.RECALIBRATE:
            self._send_log("recalibrated")
            if self._on_start is not None:
                self._on_start()
        else:
            status = AckStatus.UNKNOWN_COMMAND
        self._tx += encode_message(AckMessage(cmd.seq, self._now_us(), cmd.command, status))

    def _produce_frame(self, due: float) -> None:
        seq = self._seq
        self._seq = (self._seq + 1) & 0xFFFFFFFF
        t_us = int(round((due - self._boot_t) * 1e6))
        if self._skip_next > 0:
            self._skip_next -= 1
            return
        try:
            values = np.asarray(self._frame_fn(seq, t_us / 1e6), dtype=np.float32)
            self.layout.check_frames(values)
        except Exception as exc:  # a user callable failed: stop streaming, keep the pty up
            self.error = f"frame function failed: {exc}"
            log.error("fake device: %s", self.error)
            return
        if self.fmt == "text":
            self._produce_text_line(seq, values)
        else:
            self._produce_binary_frame(seq, t_us, values)

    def _produce_binary_frame(self, seq: int, t_us: int, values: np.ndarray) -> None:
        rows, cols = self.layout.shape
        samples = self.order.to_samples(values, self.layout)
        dtype, scale = self.dtype, self.scale
        faulty = self._nan_next or self._wrong_shape_next
        if self._nan_next:
            self._nan_next = False
            samples = samples.copy()
            samples[len(samples) // 2] = np.nan
            dtype = SampleDtype.F32
        elif self._wrong_shape_next:
            self._wrong_shape_next = False
            cols = cols + 1 if cols < 255 else cols - 1
            samples = np.resize(samples, rows * cols)
        msg = FrameMessage(seq, t_us, rows, cols, samples, dtype, scale)
        payload = bytearray(pack_message(msg))
        if self._corrupt_next_crc:
            self._corrupt_next_crc = False
            payload[-1] ^= 0xA5
            faulty = True
        self._tx += cobs_frame(payload)
        self.frames_sent += 1
        if not faulty:
            expected = dequantize(quantize(samples, dtype, scale), scale)
            self.sent.append(
                SentFrame(self.boot, seq, t_us, self.order.to_frames(expected, self.layout))
            )

    def _produce_text_line(self, seq: int, values: np.ndarray) -> None:
        samples = self.order.to_samples(values, self.layout).astype(np.float64)
        faulty = self._nan_next or self._wrong_shape_next
        if self._nan_next:
            self._nan_next = False
            samples[len(samples) // 2] = np.nan
        elif self._wrong_shape_next:
            self._wrong_shape_next = False
            samples = samples[:-1]
        # repr() of the float64 of a float32 parses back to that exact float32.
        fields = [repr(v) for v in samples.tolist()]
        if self.text_counter:
            fields.insert(0, str(seq))
        self._tx += (self.text_separator.join(fields) + "\r\n").encode("ascii")
        self.frames_sent += 1
        if not faulty:
            self.sent.append(SentFrame(self.boot, seq, 0, values.copy()))

    def _flush(self, master: int) -> None:
        if not self._tx:
            return
        try:
            written = os.write(master, self._tx)
        except BlockingIOError:
            written = 0
        except OSError as exc:
            log.debug("fake device write failed: %s", exc)
            written = 0
        del self._tx[:written]
        if len(self._tx) > MAX_TX_BACKLOG:  # nobody is reading: drop, like USB CDC does
            self.tx_dropped_bytes += len(self._tx)
            self._tx.clear()
