"""The data that every skin source delivers: frames, device info, events and counters.

A :class:`Frame` carries one sample of the whole skin already in ``[row, col]`` order
(see :mod:`wovenskin.skin.layout`), its device sequence number and a time on the
*stream clock*: seconds since the source started, continuous across device resets.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from wovenskin.skin.layout import (
    DEFAULT_COL_PITCH_MM,
    DEFAULT_COLS,
    DEFAULT_ROW_PITCH_MM,
    DEFAULT_ROWS,
    DEFAULT_SAMPLE_RATE_HZ,
    SkinLayout,
    check_supported,
)


@dataclass(frozen=True)
class SkinInfo:
    """What a source knows about the skin behind it (the device INFO message)."""

    rows: int = DEFAULT_ROWS
    cols: int = DEFAULT_COLS
    sample_rate_hz: float = DEFAULT_SAMPLE_RATE_HZ
    firmware: str = ""
    protocol_version: int = 1
    device_id: str = ""
    channel_order: str = "row-major"
    units: str = "pF"
    source: str = ""
    row_pitch_mm: float = DEFAULT_ROW_PITCH_MM
    col_pitch_mm: float = DEFAULT_COL_PITCH_MM

    @property
    def layout(self) -> SkinLayout:
        return SkinLayout(self.rows, self.cols, self.row_pitch_mm, self.col_pitch_mm)

    def check_supported(self, where: str = "") -> SkinInfo:
        """This info, after :func:`~wovenskin.skin.layout.check_supported` of its grid and
        rate: one :class:`~wovenskin.skin.layout.UnsupportedSkinError` line naming ``where``
        (default: the source) otherwise."""
        check_supported(self.rows, self.cols, self.sample_rate_hz, where or self.source)
        return self

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass
class Frame:
    """One sample of the skin: raw channel values as ``[row, col]`` float32."""

    seq: int
    t: float
    values: np.ndarray
    t_host: float = 0.0
    device_t_us: int | None = None


EVENT_KINDS = (
    "connected",
    "disconnected",
    "stalled",
    "resumed",
    "reset",
    "info",
    "error",
    "end",
)


@dataclass
class SourceEvent:
    """Something the consumer should know about the stream, besides frames.

    ``kind`` is one of :data:`EVENT_KINDS`; ``message`` is a one-line explanation.
    ``end`` means a finite source (a replay) has no more frames.
    """

    kind: str
    message: str = ""
    t_host: float = 0.0
    info: SkinInfo | None = None


@dataclass
class SourceStats:
    """Counters a source keeps; ``dropped_frames`` counts sequence gaps."""

    good_frames: int = 0
    bad_frames: int = 0
    dropped_frames: int = 0
    resets: int = 0
    reconnects: int = 0
    bytes_read: int = 0
    stalled: bool = False
    connected: bool = False
    last_error: str = ""
    bad_reasons: dict[str, int] = field(default_factory=dict)

    def count_bad(self, reason: str) -> None:
        self.bad_frames += 1
        self.bad_reasons[reason] = self.bad_reasons.get(reason, 0) + 1
        self.last_error = reason

    def copy(self) -> SourceStats:
        out = SourceStats(**{k: v for k, v in asdict(self).items() if k != "bad_reasons"})
        out.bad_reasons = dict(self.bad_reasons)
        return out
