"""Contact tracks: every fingertip followed from landing to lift with an identity.

:class:`ContactTracker` takes each frame's fingertips (:mod:`~wovenskin.tracking.fingertips`)
and assigns them to the live tracks by least total distance from each track's predicted
position (its last position plus its smoothed velocity; Hungarian assignment, gated at
``gate_mm``).  A fingertip left over starts a new track with the next identity; identities
are never reused within a tracker's life, so a view or a ROS 2 listener can follow one.

Two fingertips closer than about two channel pitches share one peak.  A track that finds
no fingertip of its own but whose prediction lies inside a blob that holds another
track's fingertip is *merged*: it is kept, moving with that blob, for up to ``merge_s``
and takes its own fingertip again when the pair separates (so a pinch that closes and
opens keeps both identities).  A track that finds nothing for ``miss_s`` ends.

Each :class:`Track` carries its position (mm from the centre of channel ``[0, 0]``,
``y`` down the rows, ``x`` along the columns), its velocity (mm/s), its travel (path
length), its peak signal now and at landing, its age and whether it is merged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linear_sum_assignment

from wovenskin.errors import ConfigError
from wovenskin.tracking.fingertips import FrameContacts


@dataclass(frozen=True)
class TrackerSettings:
    """How fingertips are followed (see the module doc)."""

    gate_mm: float = 25.0
    velocity_smoothing: float = 0.3  # weight of the newest step in the velocity
    merge_s: float = 0.5
    miss_s: float = 0.02

    def __post_init__(self) -> None:
        for name in ("gate_mm", "merge_s", "miss_s"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value >= 0):
                raise ConfigError(f"{name} must be a number >= 0, got {value!r}")
        if not 0.0 < self.velocity_smoothing <= 1.0:
            raise ConfigError("velocity_smoothing must lie in (0, 1]")


@dataclass
class Track:
    """One fingertip from landing to lift (see the module doc)."""

    id: int
    y: float
    x: float
    born_frame: int
    vy: float = 0.0  # mm per frame
    vx: float = 0.0
    travel: float = 0.0
    amplitude: float = 0.0
    landing_amplitude: float = 0.0
    frames: int = 1
    missed: int = 0
    merged: bool = False
    path: list[tuple[float, float]] = field(default_factory=list)

    def speed_mm_s(self, sample_rate_hz: float) -> float:
        return math.hypot(self.vy, self.vx) * sample_rate_hz

    def to_dict(self, sample_rate_hz: float) -> dict:
        return {
            "id": self.id,
            "y_mm": round(self.y, 2),
            "x_mm": round(self.x, 2),
            "vy_mm_s": round(self.vy * sample_rate_hz, 1),
            "vx_mm_s": round(self.vx * sample_rate_hz, 1),
            "travel_mm": round(self.travel, 1),
            "amplitude": float(self.amplitude),
            "age_s": round(self.frames / sample_rate_hz, 3),
            "merged": self.merged,
        }


class ContactTracker:
    """Follows fingertips frame by frame (see the module doc)."""

    def __init__(
        self,
        sample_rate_hz: float,
        settings: TrackerSettings | None = None,
        keep_paths: bool = False,
    ) -> None:
        if not (math.isfinite(sample_rate_hz) and sample_rate_hz > 0):
            raise ConfigError(f"sample_rate_hz must be positive, got {sample_rate_hz!r}")
        self.rate = float(sample_rate_hz)
        self.settings = settings or TrackerSettings()
        self.keep_paths = keep_paths
        self._merge_frames = int(round(self.settings.merge_s * self.rate))
        self._miss_frames = max(1, int(round(self.settings.miss_s * self.rate)))
        self._next_id = 1
        self.frame = -1
        self.tracks: list[Track] = []

    def reset(self) -> None:
        """End every track (identities keep counting up)."""
        self.tracks = []

    def step(self, contacts: FrameContacts | None) -> list[Track]:
        """One frame's fingertips (``None`` or none: nothing touches); the live tracks."""
        self.frame += 1
        if contacts is None or len(contacts) == 0:
            self.tracks = []
            return []
        ys, xs = np.asarray(contacts.y), np.asarray(contacts.x)
        n = ys.size
        taken = np.zeros(n, dtype=bool)
        matched: set[int] = set()
        if self.tracks:
            py = np.array([t.y + t.vy for t in self.tracks])
            px = np.array([t.x + t.vx for t in self.tracks])
            cost = np.hypot(py[:, None] - ys[None, :], px[:, None] - xs[None, :])
            rows, cols = linear_sum_assignment(cost)
            for r, c in zip(rows.tolist(), cols.tolist(), strict=True):
                if cost[r, c] <= self.settings.gate_mm:
                    self._update(self.tracks[r], ys[c], xs[c], float(contacts.amplitude[c]))
                    taken[c] = True
                    matched.add(r)
        survivors = []
        for k, track in enumerate(self.tracks):
            if k in matched:
                survivors.append(track)
                continue
            host = self._host(track, contacts, taken)
            if host is not None and track.missed < self._merge_frames:
                self._follow(track, host, contacts)
                survivors.append(track)
            elif track.missed + 1 < self._miss_frames:
                track.missed += 1
                survivors.append(track)
        for c in np.flatnonzero(~taken).tolist():
            amp = float(contacts.amplitude[c])
            track = Track(self._next_id, float(ys[c]), float(xs[c]), self.frame, amplitude=amp,
                          landing_amplitude=amp)  # fmt: skip
            if self.keep_paths:
                track.path.append((track.y, track.x))
            self._next_id += 1
            survivors.append(track)
        self.tracks = survivors
        return list(self.tracks)

    def _update(self, track: Track, y: float, x: float, amplitude: float) -> None:
        a = self.settings.velocity_smoothing
        dy, dx = y - track.y, x - track.x
        track.vy = (1 - a) * track.vy + a * dy
        track.vx = (1 - a) * track.vx + a * dx
        track.travel += math.hypot(dy, dx)
        track.y, track.x = float(y), float(x)
        track.amplitude = amplitude
        track.frames += 1
        track.missed = 0
        track.merged = False
        if self.keep_paths:
            track.path.append((track.y, track.x))

    def _host(self, track: Track, contacts: FrameContacts, taken: np.ndarray) -> int | None:
        """The fingertip (taken by another track) whose blob holds this track's prediction."""
        py, px = track.y + track.vy, track.x + track.vx
        best, best_d = None, math.inf
        for c in np.flatnonzero(taken).tolist():
            blob = contacts.blobs[int(contacts.blob[c])]
            reach = 2.0 * max(blob.major_sd, 1.0) + 5.0
            d = math.hypot(py - blob.y, px - blob.x)
            if d <= reach and d < best_d:
                best, best_d = c, d
        return best

    def _follow(self, track: Track, host: int, contacts: FrameContacts) -> None:
        """A merged track keeps its offset from the host fingertip, shrinking toward it."""
        hy, hx = float(contacts.y[host]), float(contacts.x[host])
        track.y = hy + 0.9 * (track.y - hy)
        track.x = hx + 0.9 * (track.x - hx)
        track.vy *= 0.5
        track.vx *= 0.5
        track.missed += 1
        track.frames += 1
        track.merged = True
        if self.keep_paths:
            track.path.append((track.y, track.x))
