"""The text-line stream format: one skin sample per line of numbers.

Many hobby firmwares ``printf`` each scan as a line such as ``12034,20.1,20.3,...\\r\\n``.
:class:`TextLineDecoder` turns such a byte stream into ``[row, col]`` float32 frames,
tolerating partial lines across reads, ``\\r\\n``/``\\r``/``\\n`` endings, blank lines,
``#`` comment lines, junk, wrong channel counts, NaN/inf and overlong lines; each bad
line becomes a :class:`~wovenskin.skin.protocol.DecodeError` and :meth:`feed` never raises.

Fields are separated by ``,``, ``;``, tabs or spaces (auto-detected per line unless a
separator is given); one trailing separator is tolerated.  The device's channel order is
converted with :meth:`ChannelOrder.to_frames` only.
"""

from __future__ import annotations

import math

import numpy as np

from wovenskin.errors import ConfigError
from wovenskin.skin.layout import ROW_MAJOR, ChannelOrder, SkinLayout
from wovenskin.skin.messages import BytesLike, DecodeError

_AUTO_SEPARATORS = (",", ";", "\t")


def _default_max_line(fields: int) -> int:
    # 32 characters per field covers "-1.2345678901234567e-300," with room to spare.
    return max(4096, 32 * fields + 256)


class TextLineDecoder:
    """Incremental decoder of numeric text lines into ``(rows, cols)`` float32 frames.

    ``separator=None`` detects ``,`` / ``;`` / tab / whitespace per line.  The first
    ``skip_columns`` fields (a timestamp or counter printed by the firmware) are ignored.
    """

    def __init__(
        self,
        layout: SkinLayout,
        order: ChannelOrder = ROW_MAJOR,
        separator: str | None = None,
        skip_columns: int = 0,
        max_line_bytes: int | None = None,
    ) -> None:
        if skip_columns < 0:
            raise ConfigError(f"skip_columns must be >= 0, got {skip_columns}")
        if separator is not None and separator.strip() == "" and separator != "\t":
            separator = None  # whitespace: str.split() handles any run of blanks
        self.layout = layout
        self.order = order
        self.separator = separator
        self.skip_columns = skip_columns
        self.fields_per_line = skip_columns + layout.channels
        self.max_line_bytes = max_line_bytes or _default_max_line(self.fields_per_line)
        self._pending = bytearray()
        self._discarding = False

    def reset(self) -> None:
        """Forget any partial line (after a reconnect)."""
        self._pending = bytearray()
        self._discarding = False

    def feed(self, data: BytesLike) -> list[np.ndarray | DecodeError]:
        """Frames and errors for every line completed by ``data``."""
        data = bytes(data).replace(b"\r", b"\n")
        if not data:
            return []
        out: list[np.ndarray | DecodeError] = []
        if self._discarding:
            end = data.find(b"\n")
            if end < 0:
                return out
            data = data[end + 1 :]
            self._discarding = False
        if b"\n" not in data:  # a line still arriving: append without rescanning it
            self._pending += data
            if len(self._pending) > self.max_line_bytes:
                self._start_discarding(out)
            return out
        buffer = bytes(self._pending) + data if self._pending else data
        lines = buffer.split(b"\n")
        tail = lines.pop()
        for line in lines:
            if not line:
                continue
            result = self.decode_line(line)
            if result is not None:
                out.append(result)
        self._pending = bytearray(tail)
        if len(tail) > self.max_line_bytes:
            self._start_discarding(out)
        return out

    def _start_discarding(self, out: list[np.ndarray | DecodeError]) -> None:
        out.append(DecodeError("overlong", f"more than {self.max_line_bytes} bytes in a line"))
        self._discarding = True
        self._pending = bytearray()

    def decode_line(self, line: bytes) -> np.ndarray | DecodeError | None:
        """One line (without its ending) to a frame, an error, or ``None`` (blank/comment)."""
        if len(line) > self.max_line_bytes:
            return DecodeError("overlong", f"{len(line)}-byte line")
        try:
            text = line.decode("ascii").strip()
        except UnicodeDecodeError:
            return DecodeError("encoding", "line is not ASCII text")
        if not text or text.startswith("#"):
            return None
        fields = self._split(text)
        if len(fields) != self.fields_per_line:
            return DecodeError("channels", f"{len(fields)} fields, expected {self.fields_per_line}")
        try:
            values = [float(f) for f in fields[self.skip_columns :]]
        except ValueError:
            return DecodeError("parse", f"non-numeric field in {text[:40]!r}")
        with np.errstate(over="ignore"):  # beyond float32 becomes inf, rejected below
            samples = np.array(values, dtype=np.float64).astype(np.float32)
        if not math.isfinite(samples.sum(dtype=np.float64)):
            return DecodeError("nonfinite", "line holds NaN, inf or a value beyond float32")
        return self.order.to_frames(samples, self.layout)

    def _split(self, text: str) -> list[str]:
        separator = self.separator
        if separator is None:
            separator = next((s for s in _AUTO_SEPARATORS if s in text), None)
        if separator is None:
            return text.split()
        fields = text.split(separator)
        if len(fields) > 1 and not fields[-1].strip():
            fields.pop()  # "1,2,3," -- a trailing separator, common with Serial.print loops
        return fields
