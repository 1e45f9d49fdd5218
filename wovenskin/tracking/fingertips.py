"""Fingertips and blobs in one conditioned frame, at sub-channel resolution.

A *blob* is a connected group of active channels (8-connected, on the contact detector's
mask grown by one channel, so that the leading edge of a moving finger on the short
moving average belongs to its blob).  Its moments (strength-weighted, in mm) give its
centroid, its spread along its major and minor axes and the major axis' angle.

A *fingertip* is a local maximum of the signal inside a blob that stands out from every
higher maximum of the same blob by a saddle: along the straight line between the two the
signal dips below ``saddle_ratio`` times the lower peak.  Its position is refined to a
fraction of a channel by fitting a parabola through the peak and its two neighbours on
each axis.  Two fingertips closer than about two channel pitches share one peak: a blob
with one peak whose body is shaped like a pair (long along its major axis, narrow across)
gives two fingertips either side of its centroid (``split_*`` settings), and the tracker
(:mod:`~wovenskin.tracking.tracker`) keeps their identities through the merge.

Positions are millimetres from the centre of channel ``[0, 0]``: ``y`` down the rows,
``x`` along the columns (the skin layout of :mod:`wovenskin.skin.layout`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from wovenskin.errors import ConfigError

_EIGHT = ndimage.generate_binary_structure(2, 2)


@dataclass(frozen=True)
class FingertipSettings:
    """How peaks become fingertips (see the module doc)."""

    saddle_ratio: float = 0.75
    min_peak_fraction: float = 0.2  # of the frame's strongest signal
    grow_mask: bool = True
    split_sd_mm: float = 10.0  # a one-peak blob this long along its major axis is two
    split_elongation: float = 1.8  # ... and at least this much longer than wide
    split_max_sd_mm: float = 14.5  # ... but no wider (a palm is not split)

    def __post_init__(self) -> None:
        if not 0.0 < self.saddle_ratio <= 1.0:
            raise ConfigError(f"saddle_ratio must lie in (0, 1], got {self.saddle_ratio!r}")
        if not (self.split_sd_mm >= 0 and self.split_elongation >= 1 and self.split_max_sd_mm >= 0):
            raise ConfigError("split_sd_mm and split_max_sd_mm must be >= 0, split_elongation >= 1")
        if not 0.0 <= self.min_peak_fraction < 1.0:
            raise ConfigError(
                f"min_peak_fraction must lie in [0, 1), got {self.min_peak_fraction!r}"
            )


@dataclass(frozen=True)
class Blob:
    """One connected group of active channels in one frame (mm, strength-weighted)."""

    y: float
    x: float
    channels: int
    strength: float
    peak: float
    major_sd: float  # spread along the major axis, mm
    minor_sd: float
    angle: float  # major axis from +x toward +y, radians in (-pi/2, pi/2]


@dataclass(frozen=True)
class FrameContacts:
    """Fingertips and blobs of one frame."""

    y: np.ndarray  # (k,) fingertip positions, mm
    x: np.ndarray
    amplitude: np.ndarray  # (k,) peak signal
    blob: np.ndarray  # (k,) index into blobs
    blobs: tuple[Blob, ...]
    peaks: int = -1  # the signal's distinct peaks (-1: as many as fingertips, none split)

    @property
    def peak_count(self) -> int:
        """Distinct peaks of the signal (a split pair counts once)."""
        return len(self) if self.peaks < 0 else self.peaks

    def __len__(self) -> int:
        return int(self.y.shape[0])


EMPTY = FrameContacts(np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0, dtype=np.int64), ())


def neighbourhood(values: np.ndarray, fill: float, reduce) -> np.ndarray:
    """``reduce`` (``np.maximum`` or ``np.logical_or``) of every channel's 3 x 3
    neighbourhood, ``fill`` beyond the edges: a grey or binary dilation by the 8-neighbour
    square, without scipy's per-call overhead on a skin-sized frame."""
    rows, cols = values.shape
    padded = np.full((rows + 2, cols + 2), fill, dtype=values.dtype)
    padded[1:-1, 1:-1] = values
    out = values.copy()
    for dr in (0, 1, 2):
        for dc in (0, 1, 2):
            if dr != 1 or dc != 1:
                reduce(out, padded[dr : dr + rows, dc : dc + cols], out=out)
    return out


def _refine(padded: np.ndarray, rows: np.ndarray, cols: np.ndarray, axis: int) -> np.ndarray:
    """Sub-channel offsets of peaks at ``(rows, cols)`` along ``axis`` from a parabola
    through the peak and its two neighbours; ``padded`` is the frame with a border of 0."""
    r, c = rows + 1, cols + 1
    if axis == 0:
        left, right = padded[r - 1, c], padded[r + 1, c]
    else:
        left, right = padded[r, c - 1], padded[r, c + 1]
    centre = padded[r, c]
    curvature = left - 2.0 * centre + right
    with np.errstate(divide="ignore", invalid="ignore"):
        offset = np.where(curvature < 0.0, 0.5 * (left - right) / curvature, 0.0)
    return np.clip(offset, -0.5, 0.5)


def _saddle(frame: np.ndarray, a: tuple[int, int], b: tuple[int, int]) -> float:
    """The lowest signal on the straight line between channels ``a`` and ``b``."""
    steps = max(abs(a[0] - b[0]), abs(a[1] - b[1]))
    rows = np.rint(np.linspace(a[0], b[0], steps + 1)).astype(int)
    cols = np.rint(np.linspace(a[1], b[1], steps + 1)).astype(int)
    return float(frame[rows, cols].min())


def find_fingertips(
    frame: np.ndarray,
    active: np.ndarray,
    row_pitch_mm: float,
    col_pitch_mm: float,
    settings: FingertipSettings | None = None,
    region: np.ndarray | None = None,
) -> FrameContacts:
    """Fingertips and blobs of one ``(R, C)`` frame and its active mask (see the module doc).

    ``region``, when given, is the active mask already grown by one channel."""
    settings = settings or FingertipSettings()
    if not active.any():
        return EMPTY
    frame = np.maximum(np.asarray(frame, dtype=np.float64), 0.0)
    if settings.grow_mask:
        mask = neighbourhood(active, False, np.logical_or) if region is None else region.copy()
    else:
        mask = active.copy()
    top = float(frame[mask].max())
    if top <= 0.0:
        return EMPTY
    mask &= frame > settings.min_peak_fraction * top * 0.5
    labels, count = ndimage.label(mask, structure=_EIGHT)
    masked = np.where(mask, frame, -1.0)
    is_peak = mask & (masked >= neighbourhood(masked, -1.0, np.maximum))
    is_peak &= frame >= settings.min_peak_fraction * top
    rows, cols = np.nonzero(is_peak)
    order = np.argsort(-frame[rows, cols], kind="stable")
    rows, cols = rows[order], cols[order]
    kept: list[tuple[int, int]] = []
    for r, c in zip(rows.tolist(), cols.tolist(), strict=True):
        here = frame[r, c]
        separate = True
        for kr, kc in kept:
            if labels[kr, kc] != labels[r, c]:
                continue
            if max(abs(kr - r), abs(kc - c)) <= 1 or (
                _saddle(frame, (kr, kc), (r, c)) >= settings.saddle_ratio * here
            ):
                separate = False
                break
        if separate:
            kept.append((r, c))
    if not kept:
        return EMPTY
    blobs = _blobs(frame, labels, count, row_pitch_mm, col_pitch_mm)
    pr = np.array([k[0] for k in kept])
    pc = np.array([k[1] for k in kept])
    padded = np.zeros((frame.shape[0] + 2, frame.shape[1] + 2))
    padded[1:-1, 1:-1] = frame
    ys = (pr + _refine(padded, pr, pc, 0)) * row_pitch_mm
    xs = (pc + _refine(padded, pr, pc, 1)) * col_pitch_mm
    amps = frame[pr, pc]
    which = labels[pr, pc].astype(np.int64) - 1
    return _split_pairs(FrameContacts(ys, xs, amps, which, blobs), settings)


def _split_pairs(contacts: FrameContacts, settings: FingertipSettings) -> FrameContacts:
    """Two fingertips for every blob whose one peak sits in a body shaped like a pair:
    longer than ``split_sd_mm`` along its major axis, ``split_elongation`` times longer
    than wide, no wider than ``split_max_sd_mm``.  They lie on the major axis either side
    of the blob's centroid, as far apart as the extra length says (the minor axis' spread
    standing for one fingertip's own)."""
    peaks = np.bincount(contacts.blob, minlength=len(contacts.blobs))
    ys, xs, amps, which = [], [], [], []
    for k in range(len(contacts)):
        b = int(contacts.blob[k])
        blob = contacts.blobs[b]
        if (
            peaks[b] == 1
            and settings.split_sd_mm <= blob.major_sd <= settings.split_max_sd_mm
            and blob.major_sd >= settings.split_elongation * blob.minor_sd
        ):
            half = float(np.sqrt(blob.major_sd**2 - blob.minor_sd**2))
            dy, dx = half * np.sin(blob.angle), half * np.cos(blob.angle)
            for sign in (-1.0, 1.0):
                ys.append(blob.y + sign * dy)
                xs.append(blob.x + sign * dx)
                amps.append(contacts.amplitude[k])
                which.append(b)
            continue
        ys.append(contacts.y[k])
        xs.append(contacts.x[k])
        amps.append(contacts.amplitude[k])
        which.append(b)
    if len(ys) == len(contacts):
        return contacts
    return FrameContacts(
        np.array(ys), np.array(xs), np.array(amps), np.array(which, dtype=np.int64),
        contacts.blobs, peaks=len(contacts),
    )  # fmt: skip


def _blobs(
    frame: np.ndarray, labels: np.ndarray, count: int, row_pitch: float, col_pitch: float
) -> tuple[Blob, ...]:
    """Each labelled blob's strength-weighted moments, in mm."""
    r, c = np.nonzero(labels)
    ids = labels[r, c] - 1
    w = frame[r, c]
    y, x = r * row_pitch, c * col_pitch
    n = np.bincount(ids, minlength=count)
    total = np.bincount(ids, weights=w, minlength=count)
    safe = np.where(total > 0, total, 1.0)
    my = np.bincount(ids, weights=w * y, minlength=count) / safe
    mx = np.bincount(ids, weights=w * x, minlength=count) / safe
    dy, dx = y - my[ids], x - mx[ids]
    cyy = np.bincount(ids, weights=w * dy * dy, minlength=count) / safe
    cxx = np.bincount(ids, weights=w * dx * dx, minlength=count) / safe
    cxy = np.bincount(ids, weights=w * dx * dy, minlength=count) / safe
    peak = np.zeros(count)
    np.maximum.at(peak, ids, w)
    half = 0.5 * (cxx + cyy)
    root = np.sqrt(np.maximum(half * half - (cxx * cyy - cxy * cxy), 0.0))
    major, minor = half + root, np.maximum(half - root, 0.0)
    angle = 0.5 * np.arctan2(2.0 * cxy, cxx - cyy)
    return tuple(
        Blob(float(my[b]), float(mx[b]), int(n[b]), float(total[b]), float(peak[b]),
             float(np.sqrt(major[b])), float(np.sqrt(minor[b])), float(angle[b]))
        for b in range(count)
    )  # fmt: skip
