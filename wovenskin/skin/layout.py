"""Skin geometry and the only conversions between device channel order and frames.

A *frame* everywhere in wovenskin is an array indexed ``[row, col]`` as the user faces
the skin (``docs/gestures.md``): row 0 is the top edge and rows grow downward,
column 0 is the left edge and columns grow to the right.  Physical positions are in
millimetres with ``x`` to the right and ``y`` downward from the top-left corner of the
sensing area, so "up" is ``-y``.

Devices may stream their channels in another order (column-major, mirrored
electrodes).  :class:`ChannelOrder` describes that order and is the one place where
wovenskin flips or transposes channel data; no other module may do it.

Any grid of :data:`MIN_GRID_SIDE`-:data:`MAX_GRID_SIDE` rows and columns streaming at
:data:`MIN_SAMPLE_RATE_HZ`-:data:`MAX_SAMPLE_RATE_HZ` can be conditioned and recognised
live (``docs/skins.md`` says why these bounds); :func:`check_supported` is the one check of
that range, which every live source (simulated, serial, replayed, idle) and the pipeline
run on a file pass through, so anything outside it is one :class:`UnsupportedSkinError`
line.  Files and layouts themselves may hold any grid (``info`` and ``convert`` read them).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from wovenskin.errors import ConfigError
from wovenskin.settings import from_dict

DEFAULT_ROWS = 10
DEFAULT_COLS = 10
DEFAULT_ROW_PITCH_MM = 14.0
DEFAULT_COL_PITCH_MM = 10.0
DEFAULT_SAMPLE_RATE_HZ = 200.0

MIN_GRID_SIDE = 2
"""Fewest rows (and columns) of a usable skin: a single line of channels has no second
axis, so half the gestures (a swipe across it, a circle) cannot be told apart."""
MAX_GRID_SIDE = 32
"""Most rows (and columns): the shipped architecture recognising a 32x32 grid at 200 Hz
takes under a third of one core, a 64x64 one more than the whole core (docs/skins.md)."""
MIN_SAMPLE_RATE_HZ = 25.0
"""Slowest usable rate: at 22 Hz and below the default 0.5 s calibration holds fewer frames
than the smoothing window + 10 that calibration needs (``ConditioningConfig`` refuses it)."""
MAX_SAMPLE_RATE_HZ = 2000.0
"""Fastest usable rate: conditioning a 32x32 grid at 2 kHz takes under half of one core, a
64x64 one more than the whole core (docs/skins.md)."""


class UnsupportedSkinError(ConfigError):
    """A grid size or sample rate outside the range wovenskin can condition and recognise."""


def supported_range() -> str:
    """The supported range in words, e.g. ``"2-32 rows and columns at 25-2000 Hz"``."""
    return (
        f"{MIN_GRID_SIDE}-{MAX_GRID_SIDE} rows and columns at "
        f"{MIN_SAMPLE_RATE_HZ:g}-{MAX_SAMPLE_RATE_HZ:g} Hz"
    )


def check_supported(
    rows: object, cols: object, sample_rate_hz: object = DEFAULT_SAMPLE_RATE_HZ, where: str = ""
) -> None:
    """Raise one :class:`UnsupportedSkinError` line (prefixed ``where: ``) unless a
    ``rows x cols`` grid at ``sample_rate_hz`` is in the supported range (module doc)."""
    problems = []

    def side_ok(n: object) -> bool:
        return isinstance(n, int | np.integer) and MIN_GRID_SIDE <= n <= MAX_GRID_SIDE

    if not (side_ok(rows) and side_ok(cols)):
        problems.append(f"a {rows}x{cols} grid")
    try:
        rate = float(sample_rate_hz)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        rate = math.nan
    if not (math.isfinite(rate) and MIN_SAMPLE_RATE_HZ <= rate <= MAX_SAMPLE_RATE_HZ):
        shown = repr(sample_rate_hz) if math.isnan(rate) else f"{rate:g} Hz"
        problems.append(f"a sample rate of {shown}")
    if problems:
        prefix = f"{where}: " if where else ""
        raise UnsupportedSkinError(
            f"{prefix}{' and '.join(problems)} cannot be used: wovenskin supports skins of "
            f"{supported_range()} (docs/skins.md)"
        )


@dataclass(frozen=True)
class SkinLayout:
    """Grid size and channel pitch of a skin; other grid sizes work the same way."""

    rows: int = DEFAULT_ROWS
    cols: int = DEFAULT_COLS
    row_pitch_mm: float = DEFAULT_ROW_PITCH_MM
    col_pitch_mm: float = DEFAULT_COL_PITCH_MM

    def __post_init__(self) -> None:
        if self.rows < 1 or self.cols < 1:
            raise ConfigError(
                f"skin needs at least one row and column, got {self.rows}x{self.cols}"
            )
        if self.row_pitch_mm <= 0 or self.col_pitch_mm <= 0:
            raise ConfigError("channel pitches must be positive")

    @property
    def shape(self) -> tuple[int, int]:
        return (self.rows, self.cols)

    @property
    def channels(self) -> int:
        return self.rows * self.cols

    @property
    def width_mm(self) -> float:
        """Extent along x (columns)."""
        return self.cols * self.col_pitch_mm

    @property
    def height_mm(self) -> float:
        """Extent along y (rows)."""
        return self.rows * self.row_pitch_mm

    def channel_centers_mm(self) -> tuple[np.ndarray, np.ndarray]:
        """``(x, y)`` arrays of shape ``(rows, cols)``: the centre of every channel."""
        x = (np.arange(self.cols) + 0.5) * self.col_pitch_mm
        y = (np.arange(self.rows) + 0.5) * self.row_pitch_mm
        xx, yy = np.meshgrid(x, y)
        return xx, yy

    def rc_to_mm(self, row: float | np.ndarray, col: float | np.ndarray):
        """Fractional channel coordinates (channel centres at integers) to ``(x, y)`` mm."""
        return (np.asarray(col) + 0.5) * self.col_pitch_mm, (np.asarray(row) + 0.5) * (
            self.row_pitch_mm
        )

    def mm_to_rc(self, x: float | np.ndarray, y: float | np.ndarray):
        """``(x, y)`` mm to fractional ``(row, col)`` with channel centres at integers."""
        return np.asarray(y) / self.row_pitch_mm - 0.5, np.asarray(x) / self.col_pitch_mm - 0.5

    def check_frames(self, frames: np.ndarray) -> None:
        """Raise ``ValueError`` unless ``frames`` ends in ``(rows, cols)``."""
        if frames.ndim < 2 or tuple(frames.shape[-2:]) != self.shape:
            raise ValueError(
                f"expected frames of shape (..., {self.rows}, {self.cols}), got {frames.shape}"
            )

    def check_supported(
        self, sample_rate_hz: float = DEFAULT_SAMPLE_RATE_HZ, where: str = ""
    ) -> SkinLayout:
        """This layout, after :func:`check_supported` of its grid at ``sample_rate_hz``."""
        check_supported(self.rows, self.cols, sample_rate_hz, where)
        return self

    def to_dict(self) -> dict:
        return {
            "rows": self.rows,
            "cols": self.cols,
            "row_pitch_mm": self.row_pitch_mm,
            "col_pitch_mm": self.col_pitch_mm,
        }

    @classmethod
    def from_dict(cls, d: dict) -> SkinLayout:
        """The layout :meth:`to_dict` wrote; one :class:`ConfigError` line if it is bad."""
        return from_dict(cls, d, "skin layout")


@dataclass(frozen=True)
class ChannelOrder:
    """How a device orders its ``rows * cols`` channels in one sample.

    ``major="row"``: channel ``k`` is device row ``k // cols``, column ``k % cols``;
    ``major="col"``: channel ``k`` is device column ``k // rows``, row ``k % rows``.
    ``flip_rows``/``flip_cols`` mirror the device's rows/columns to reach the
    user-facing orientation of docs/gestures.md (for example when the electrodes are
    numbered from the bottom edge).
    """

    major: str = "row"
    flip_rows: bool = False
    flip_cols: bool = False

    def __post_init__(self) -> None:
        if self.major not in ("row", "col"):
            raise ConfigError(f"channel order must be row- or col-major, got {self.major!r}")

    @classmethod
    def parse(cls, text: str) -> ChannelOrder:
        """Parse ``"row-major"``, ``"col-major,flip-rows"``, ``"row,flip-cols,flip-rows"``."""
        parts = [p.strip().lower() for p in text.replace("+", ",").split(",") if p.strip()]
        if not parts:
            return cls()
        major_word = parts[0].removesuffix("-major")
        aliases = {"row": "row", "rows": "row", "col": "col", "cols": "col", "column": "col"}
        if major_word not in aliases:
            raise ConfigError(f"unknown channel order {text!r}: start with row-major or col-major")
        flips = set(parts[1:])
        unknown = flips - {"flip-rows", "flip-cols"}
        if unknown:
            raise ConfigError(f"unknown channel order option(s) {sorted(unknown)} in {text!r}")
        return cls(aliases[major_word], "flip-rows" in flips, "flip-cols" in flips)

    def __str__(self) -> str:
        words = [f"{self.major}-major"]
        if self.flip_rows:
            words.append("flip-rows")
        if self.flip_cols:
            words.append("flip-cols")
        return ",".join(words)

    def to_frames(self, samples: np.ndarray, layout: SkinLayout) -> np.ndarray:
        """Device samples ``(..., rows*cols)`` to frames ``(..., rows, cols)`` (a copy)."""
        samples = np.asarray(samples)
        if samples.shape[-1] != layout.channels:
            raise ValueError(
                f"expected {layout.channels} channels per sample, got {samples.shape[-1]}"
            )
        lead = samples.shape[:-1]
        if self.major == "row":
            frames = samples.reshape(*lead, layout.rows, layout.cols)
        else:
            frames = np.swapaxes(samples.reshape(*lead, layout.cols, layout.rows), -1, -2)
        if self.flip_rows:
            frames = frames[..., ::-1, :]
        if self.flip_cols:
            frames = frames[..., :, ::-1]
        return np.ascontiguousarray(frames)

    def to_samples(self, frames: np.ndarray, layout: SkinLayout) -> np.ndarray:
        """Frames ``(..., rows, cols)`` back to device order ``(..., rows*cols)``."""
        frames = np.asarray(frames)
        layout.check_frames(frames)
        if self.flip_rows:
            frames = frames[..., ::-1, :]
        if self.flip_cols:
            frames = frames[..., :, ::-1]
        if self.major == "col":
            frames = np.swapaxes(frames, -1, -2)
        lead = frames.shape[:-2]
        return np.ascontiguousarray(frames).reshape(*lead, layout.channels)


ROW_MAJOR = ChannelOrder()
