"""A skin on a serial port: :class:`SerialSkinSource`, the ``serial:PORT`` skin source.

A background thread reads the port, decodes the binary protocol of ``docs/protocol.md``
(or text lines, see :mod:`wovenskin.skin.textlines`) and queues ``[row, col]``
:class:`Frame` items and :class:`SourceEvent` items that :meth:`SerialSkinSource.poll`
drains.  The thread never dies on stream problems; it counts them in
:class:`SourceStats` and reports them as events:

- garbage, truncated packets, CRC errors, NaN/inf samples, frames whose shape differs
  from INFO: bad frames, with the reason;
- sequence gaps: dropped frames; the sequence going backwards (or the device clock):
  a device reset (``reset`` event), not a drop;
- no good frame for ``stall_ms``: ``stalled`` (then ``resumed``);
- an INFO declaring a grid or rate outside the supported range
  (:func:`~wovenskin.skin.layout.check_supported`): one ``error`` event with that line; the
  source keeps its previous layout, so the device's frames count as bad (``shape``);
- serial errors or the port vanishing: ``disconnected``, then reconnection with
  exponential backoff (0.05 s doubling to 2 s), ``connected``, GET_INFO and START again.

Frames carry the stream clock of :mod:`wovenskin.skin.stream_clock`; the commands and their
ACKs are :mod:`~wovenskin.skin.serial_commands`', the options :mod:`~.serial_options`'.
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from collections import deque

import serial

from wovenskin.errors import ConfigError, DeviceError
from wovenskin.skin.frames import Frame, SkinInfo, SourceEvent, SourceStats
from wovenskin.skin.layout import (
    DEFAULT_SAMPLE_RATE_HZ,
    ROW_MAJOR,
    ChannelOrder,
    SkinLayout,
    UnsupportedSkinError,
)
from wovenskin.skin.messages import (
    AckMessage,
    CommandId,
    DecodeError,
    FrameMessage,
    InfoMessage,
    LogMessage,
    MessageType,
)
from wovenskin.skin.protocol import StreamDecoder
from wovenskin.skin.serial_commands import CommandLink
from wovenskin.skin.serial_options import DEFAULT_BAUD, DEFAULT_STALL_MS, read_serial_options
from wovenskin.skin.stream_clock import StreamClock
from wovenskin.skin.textlines import TextLineDecoder

log = logging.getLogger(__name__)

READ_TIMEOUT_S = 0.005  # longest a read blocks: bounds stall-detection and close latency
WRITE_TIMEOUT_S = 0.5
BACKOFF_START_S = 0.05
BACKOFF_MAX_S = 2.0
INFO_RETRY_S = 1.0
MAX_QUEUED_ITEMS = 4000  # 20 s at 200 Hz; beyond this the oldest items are dropped

COMMANDS = {
    "start": CommandId.START,
    "stop": CommandId.STOP,
    "recalibrate": CommandId.RECALIBRATE,
    "get_info": CommandId.GET_INFO,
}


class SerialSkinSource:
    """A skin streaming over a serial port (binary protocol or text lines)."""

    def __init__(
        self,
        port: str,
        *,
        fmt: str = "binary",
        layout: SkinLayout | None = None,
        order: ChannelOrder = ROW_MAJOR,
        rate_hz: float = DEFAULT_SAMPLE_RATE_HZ,
        baud: int = DEFAULT_BAUD,
        stall_ms: float = DEFAULT_STALL_MS,
        text_separator: str | None = None,
        skip_columns: int = 0,
    ) -> None:
        if fmt not in ("binary", "text"):
            raise ConfigError(f"serial format must be binary or text, got {fmt!r}")
        if not rate_hz > 0:
            raise ConfigError(f"rate must be positive, got {rate_hz}")
        if not stall_ms > 0:
            raise ConfigError(f"stall_ms must be positive, got {stall_ms}")
        if baud <= 0:
            raise ConfigError(f"baud must be positive, got {baud}")
        self.port = port
        self.fmt = fmt
        self.baud = baud
        self.stall_s = stall_ms / 1000.0
        self._layout = layout or SkinLayout()
        self._order = order
        self._nominal_rate = float(rate_hz)
        self._source_name = f"serial:{port}"
        self._info = SkinInfo(
            rows=self._layout.rows,
            cols=self._layout.cols,
            sample_rate_hz=self._nominal_rate,
            channel_order=str(order),
            source=self._source_name,
            row_pitch_mm=self._layout.row_pitch_mm,
            col_pitch_mm=self._layout.col_pitch_mm,
            protocol_version=1 if fmt == "binary" else 0,
        ).check_supported()
        self._refused_info: SkinInfo | None = None  # the last unsupported INFO reported
        self._binary = StreamDecoder()
        self._text = TextLineDecoder(self._layout, order, text_separator or None, skip_columns)

        self._cond = threading.Condition()  # guards everything below and the queue
        self._queue: deque[Frame | SourceEvent] = deque()
        self._stats = SourceStats()
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._serial: serial.Serial | None = None
        self._t0 = 0.0
        self._ever_connected = False
        self._backoff_s = BACKOFF_START_S
        self._next_attempt = 0.0
        self._overrun_logged = False

        self._device_info: InfoMessage | None = None
        self._info_since_connect = False
        self._next_info_request = 0.0
        self._commands = CommandLink()

        self._clock = StreamClock()
        self._text_seq = 0
        self._last_good: float | None = None
        self._stalled = False

    @classmethod
    def from_options(cls, port: str, options: dict[str, str]) -> SerialSkinSource:
        """Build from ``serial:PORT?key=value&...`` options (see ``docs/protocol.md``)."""
        o = read_serial_options(options)
        return cls(
            port,
            fmt=o.format,
            layout=SkinLayout(o.rows, o.cols),
            order=ChannelOrder.parse(o.order or "row-major"),
            rate_hz=o.rate,
            baud=o.baud,
            stall_ms=o.stall_ms,
            text_separator=o.separator,
            skip_columns=o.skip,
        )

    # ------------------------------------------------------------------ SkinSource API

    @property
    def info(self) -> SkinInfo:
        return self._info

    @property
    def acks(self) -> list[AckMessage]:
        """The most recent ACKs the device sent (newest last)."""
        with self._cond:
            return list(self._commands.acks)

    def start(self) -> None:
        """Open the port and start the reader thread (idempotent).

        Raises :class:`~wovenskin.errors.DeviceError` (a ``ConnectionError``) if the port
        cannot be opened at all; once streaming, losing the port is reported as events and
        handled by reconnecting.
        """
        with self._cond:
            if self._thread is not None:
                return
            self._t0 = time.monotonic()
            error = self._connect(self._t0)
            if error:
                raise DeviceError(f"cannot open serial port {self.port}: {error}")
            self._stop.clear()
            self._thread = threading.Thread(
                target=self._run, name=f"skin-serial-{self.port}", daemon=True
            )
            self._thread.start()

    def poll(self, timeout: float = 0.05) -> list[Frame | SourceEvent]:
        deadline = time.monotonic() + max(0.0, timeout)
        with self._cond:
            while not self._queue:
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return []
                self._cond.wait(remaining)
            items = list(self._queue)
            self._queue.clear()
            return items

    def stats(self) -> SourceStats:
        with self._cond:
            return self._stats.copy()

    def send_command(self, command: str) -> None:
        name = command.strip().lower()
        if name not in COMMANDS:
            raise ConfigError(f"unknown skin command {command!r}; use {', '.join(COMMANDS)}")
        if self.fmt != "binary":
            log.warning(
                "serial %s: text-format devices take no commands; %r ignored", self.port, name
            )
            return
        with self._cond:
            self._commands.queue(COMMANDS[name])

    def close(self) -> None:
        self._stop.set()
        thread, self._thread = self._thread, None
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout=2.0)
        with self._cond:
            self._close_port()
            self._stats.connected = False

    def __enter__(self) -> SerialSkinSource:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------------ connection

    def _open_port(self) -> serial.Serial:
        # Configure everything on an unopened port, then open it: pyserial applies DTR/RTS
        # at open().  An ESP32-S3 (native USB-Serial-JTAG, or a UART bridge wired to EN/IO0
        # for auto-programming) treats DTR/RTS transitions as a reset / download-mode
        # request, so the lines must stay deasserted and hardware flow control off.
        port = serial.Serial()
        port.port = self.port
        port.baudrate = self.baud
        port.timeout = READ_TIMEOUT_S
        port.write_timeout = WRITE_TIMEOUT_S
        port.dsrdtr = False
        port.rtscts = False
        port.dtr = False
        port.rts = False
        port.exclusive = True  # two readers on one port would each get half the bytes
        port.open()
        return port

    def _connect(self, now: float) -> str:
        """Try to open the port; return an error message, or ``""`` on success.

        The port is opened without holding the lock (opening can be slow), then registered.
        """
        try:
            port = self._open_port()
        except (serial.SerialException, OSError, ValueError) as exc:
            with self._cond:
                self._next_attempt = now + self._backoff_s
                self._backoff_s = min(BACKOFF_MAX_S, self._backoff_s * 2)
            return str(exc) or type(exc).__name__
        with self._cond:
            self._register_port(port, now)
        return ""

    def _register_port(self, port: serial.Serial, now: float) -> None:
        self._serial = port
        self._backoff_s = BACKOFF_START_S
        self._binary.reset()
        self._text.reset()
        self._stats.connected = True
        if self._ever_connected:
            self._stats.reconnects += 1
        self._ever_connected = True
        self._emit(SourceEvent("connected", f"opened {self.port}", time.monotonic()))
        if self.fmt == "binary":
            self._info_since_connect = False
            self._commands.queue_first([CommandId.GET_INFO, CommandId.START])
            self._next_info_request = now + INFO_RETRY_S

    def _close_port(self) -> None:
        port, self._serial = self._serial, None
        if port is not None:
            with contextlib.suppress(Exception):
                port.close()

    def _lose_connection(self, reason: str) -> None:
        now = time.monotonic()
        self._close_port()
        self._stats.connected = False
        self._stats.last_error = reason
        self._commands.forget_awaited()
        self._backoff_s = BACKOFF_START_S
        self._next_attempt = now + self._backoff_s
        log.warning("serial %s disconnected: %s", self.port, reason)
        self._emit(SourceEvent("disconnected", reason, now))

    # ------------------------------------------------------------------ reader thread

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                self._step()
            except Exception as exc:  # a bug here must not silently end the stream
                log.exception("serial %s: reader error", self.port)
                with self._cond:
                    self._stats.last_error = f"reader error: {exc}"
                    self._emit(SourceEvent("error", f"reader error: {exc}", time.monotonic()))
                self._stop.wait(0.05)

    def _step(self) -> None:
        now = time.monotonic()
        port = self._serial
        if port is None:
            if now >= self._next_attempt and not self._stop.is_set():
                self._connect(now)
            with self._cond:
                self._check_stall(now)
            if self._serial is None:
                self._stop.wait(READ_TIMEOUT_S)
            return
        try:
            with self._cond:
                outgoing = self._take_queued_commands(now)
            for wire in outgoing:  # written outside the lock: a slow write never blocks poll()
                port.write(wire)
            waiting = port.in_waiting
            data = port.read(waiting if waiting else 1)
        except serial.SerialTimeoutException as exc:
            with self._cond:
                self._emit(SourceEvent("error", f"write timed out: {exc}", now))
            return
        except (serial.SerialException, OSError, TypeError, AttributeError) as exc:
            # TypeError/AttributeError: pyserial's fd vanished under a concurrent close().
            if not self._stop.is_set():
                with self._cond:
                    self._lose_connection(str(exc) or type(exc).__name__)
            return
        now = time.monotonic()
        with self._cond:
            if data:
                self._stats.bytes_read += len(data)
                if self.fmt == "binary":
                    self._process_binary(data, now)
                else:
                    self._process_text(data, now)
            self._check_stall(now)
            self._check_acks(now)

    def _emit(self, item: Frame | SourceEvent) -> None:
        if len(self._queue) >= MAX_QUEUED_ITEMS:
            dropped = self._queue.popleft()
            if isinstance(dropped, Frame):
                self._stats.dropped_frames += 1
            if not self._overrun_logged:
                log.warning("serial %s: consumer is not polling; dropping oldest items", self.port)
                self._overrun_logged = True
        self._queue.append(item)
        self._cond.notify_all()

    def _check_stall(self, now: float) -> None:
        if self._last_good is None or self._stalled:
            return
        quiet = now - self._last_good
        if quiet > self.stall_s:
            self._stalled = True
            self._stats.stalled = True
            self._emit(SourceEvent("stalled", f"no frame for {quiet * 1000:.0f} ms", now))

    def _frame_arrived(self, now: float) -> None:
        if self._stalled:
            quiet = now - (self._last_good or now)
            self._stalled = False
            self._stats.stalled = False
            self._emit(SourceEvent("resumed", f"frames resumed after {quiet:.3f} s", now))
        self._last_good = now

    # ------------------------------------------------------------------ commands

    def _take_queued_commands(self, now: float) -> list[bytes]:
        """Wire bytes of the commands to send now (ACKs are awaited from now on)."""
        if self._device_info_missing(now):
            self._commands.queue(CommandId.GET_INFO)
            self._next_info_request = now + INFO_RETRY_S
        return self._commands.take(now, int((now - self._t0) * 1e6))

    def _device_info_missing(self, now: float) -> bool:
        return (
            self.fmt == "binary" and not self._info_since_connect and now >= self._next_info_request
        )

    def _check_acks(self, now: float) -> None:
        for message in self._commands.overdue(now):
            log.warning("serial %s: %s", self.port, message)
            self._emit(SourceEvent("error", message, now))

    def _on_ack(self, ack: AckMessage, now: float) -> None:
        message = self._commands.acknowledged(ack)
        if message is not None:
            log.warning("serial %s: %s", self.port, message)
            self._emit(SourceEvent("error", message, now))

    # ------------------------------------------------------------------ decoding

    def _process_binary(self, data: bytes, now: float) -> None:
        for item in self._binary.feed(data):
            if isinstance(item, FrameMessage):
                self._on_frame(item, now)
            elif isinstance(item, DecodeError):
                self._on_bad(item, now)
            elif isinstance(item, InfoMessage):
                self._on_info(item, now)
            elif isinstance(item, AckMessage):
                self._on_ack(item, now)
            elif isinstance(item, LogMessage):
                log.info("skin %s says: %s", self.port, item.text)
            else:  # a COMMAND coming from the device: an echo or a wiring loop
                self._stats.count_bad("direction")

    def _on_info(self, msg: InfoMessage, now: float) -> None:
        self._info_since_connect = True
        info = msg.to_skin_info(source=self._source_name)
        try:
            info.check_supported()
        except UnsupportedSkinError as exc:
            if info != self._refused_info:  # once per INFO, not once per GET_INFO answer
                self._refused_info = info
                self._stats.last_error = "unsupported"
                self._emit(SourceEvent("error", str(exc), now, info))
            return
        self._device_info = msg
        self._layout = msg.layout
        self._order = msg.channel_order
        if info != self._info:
            self._info = info
            self._emit(
                SourceEvent(
                    "info",
                    f"{info.rows}x{info.cols} {info.channel_order} at {info.sample_rate_hz:g} Hz,"
                    f" firmware {info.firmware!r}, device {info.device_id!r}",
                    now,
                    info,
                )
            )

    def _on_bad(self, error: DecodeError, now: float) -> None:
        self._stats.count_bad(error.reason)
        if error.msg_type == MessageType.FRAME and error.seq is not None:
            # The header passed its CRC: account for the sequence number so a rejected
            # frame is not also counted as dropped.
            self._stream_time(error.seq, error.device_t_us or 0, now)

    def _on_frame(self, msg: FrameMessage, now: float) -> None:
        if (msg.rows, msg.cols) != self._layout.shape:
            self._stats.count_bad("shape")
            self._stream_time(msg.seq, msg.device_t_us, now)
            return
        if msg.dtype.is_integer and self._device_info is None:
            self._stats.count_bad("no-info")  # counts without a scale: units unknown
            self._stream_time(msg.seq, msg.device_t_us, now)
            return
        t = self._stream_time(msg.seq, msg.device_t_us, now)
        if t is None:
            self._stats.count_bad("duplicate")
            return
        values = self._order.to_frames(msg.samples, self._layout)
        self._stats.good_frames += 1
        self._frame_arrived(now)
        self._emit(Frame(msg.seq, t, values, t_host=now, device_t_us=msg.device_t_us))

    def _stream_time(self, seq: int, device_us: int, now: float) -> float | None:
        """Account for ``seq`` (drops, resets) and return the frame's stream time, or
        ``None`` for an exact duplicate of the previous frame."""
        period_s = 1.0 / self._info.sample_rate_hz
        placed = self._clock.place_frame(seq, device_us, now - self._t0, period_s)
        if placed.reset_from is not None:
            self._stats.resets += 1
            message = f"device reset: sequence {placed.reset_from} -> {seq}"
            log.info("serial %s: %s", self.port, message)
            self._emit(SourceEvent("reset", message, now))
        self._stats.dropped_frames += placed.dropped
        return placed.t

    def _process_text(self, data: bytes, now: float) -> None:
        for item in self._text.feed(data):
            if isinstance(item, DecodeError):
                self._stats.count_bad(item.reason)
                continue
            seq = self._text_seq
            self._text_seq += 1
            t = self._clock.place_line(now - self._t0, 1.0 / self._nominal_rate)
            self._stats.good_frames += 1
            self._frame_arrived(now)
            self._emit(Frame(seq, t, item, t_host=now, device_t_us=None))
