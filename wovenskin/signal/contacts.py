"""Contact detection: per-channel hysteresis, a debounced "touched" flag and contact blobs.

:class:`ContactDetector` turns the conditioned signal into

- ``active`` ``(n, R, C)``.  Detection first removes, frame by frame, the level shared
  by the whole skin (a low quantile of all channels, when positive), so fast common
  drift never looks like contact.  A channel then turns on when its signal rises above
  its on threshold and off when it falls below its (lower) off threshold.  Both are
  per-channel levels (from the calibrated noise, with absolute floors), raised frame by
  frame to a fraction of the frame's strongest signal (so the cross-talk of a firm press
  along its electrode lines stays inactive) and to a fraction of the channel's own
  recent peak (so a channel releases cleanly after a firm press and does not fire again
  on the relaxing fabric).  When the caller also passes a *fast* signal (a shorter
  moving average of the same input), a channel also releases as soon as its fast signal
  falls below the release level (a lifted finger stops counting within a few frames)
  and turns on early when its fast signal exceeds ``fast_on_factor`` times its on
  threshold.  Finally a channel is active only if its blob holds a *seed*,
  a channel above its plain on threshold in that frame, so a lone channel lingering just
  above its off threshold drops out (see :class:`DetectorSettings`);
- ``touched`` ``(n,)``: the skin counts as touched once some channel has been active for
  ``debounce_on_frames`` consecutive frames, and as released once none has been for
  ``debounce_off_frames``;
- contacts: connected blobs of active channels (4-connected by default: edge neighbours
  only; 8-connected adds diagonals), each a :class:`Contact` with its signal-weighted
  centroid, size, peak and strength, listed per frame in raster order of each blob's
  first channel.  Two fingertips closer than about two channel pitches share one blob.

Hysteresis is written as "index of the last on/off event" per channel, propagated with
``np.maximum.accumulate`` from carried state, so it vectorises over time; the recent-peak
envelope and the debounce are stepped once per frame.  Everything carries its state
between calls and gives identical results for any chunking.  Frame indices count from
the detector's creation (or last :meth:`ContactDetector.reset`).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from scipy import ndimage


@dataclass(frozen=True)
class Contact:
    """One connected blob of active channels in one frame."""

    row: float  # signal-weighted centroid, channel units (channel centres at integers)
    col: float
    size: int  # channels in the blob
    peak: float  # max conditioned value in the blob
    strength: float  # sum of conditioned values in the blob

    def to_dict(self) -> dict:
        return asdict(self)


def _labelling_structure(connectivity: int) -> np.ndarray:
    """3-D labelling structure that links channels within a frame, never across frames."""
    plane = ndimage.generate_binary_structure(2, 1 if connectivity == 4 else 2)
    structure = np.zeros((3, 3, 3), dtype=bool)
    structure[1] = plane
    return structure


_STRUCTURES = {4: _labelling_structure(4), 8: _labelling_structure(8)}

# On a skin this small one finger can cover most of it: no common-mode level is taken.
_MIN_CHANNELS_FOR_COMMON_MODE = 8


def extract_contacts(
    signal: np.ndarray,
    active: np.ndarray,
    connectivity: int = 4,
    labels: np.ndarray | None = None,
) -> list[list[Contact]]:
    """Contacts of every frame: connected blobs of ``active`` weighted by ``signal``.

    ``signal`` and ``active`` are ``(n, R, C)``.  ``labels``, when given, already
    numbers the blobs (any distinct positive id per blob, 0 outside ``active``) and saves
    labelling them again.  Blobs are listed per frame in raster order of their first
    channel, and the per-blob sums run over each blob's channels in raster order, so a
    frame gives bit-identical contacts whether it is processed alone or in a chunk.
    """
    if connectivity not in _STRUCTURES:
        raise ValueError(f"connectivity must be 4 or 8, got {connectivity!r}")
    n, rows, cols = active.shape
    out: list[list[Contact]] = [[] for _ in range(n)]
    pixels = np.flatnonzero(active)  # raster order of (frame, row, col)
    if pixels.size == 0:
        return out
    if labels is None:
        labels, _ = ndimage.label(active, structure=_STRUCTURES[connectivity])
    blob, first = _number_by_first_pixel(labels.ravel()[pixels])
    count = first.size
    weight = signal.ravel()[pixels].astype(np.float64, copy=False)
    per_frame = rows * cols
    within = pixels % per_frame
    row = within // cols
    col = within - row * cols
    size = np.bincount(blob, minlength=count)
    strength = np.bincount(blob, weights=weight, minlength=count)
    with np.errstate(invalid="ignore", divide="ignore"):
        row_mean = np.bincount(blob, weights=weight * row, minlength=count) / strength
        col_mean = np.bincount(blob, weights=weight * col, minlength=count) / strength
    peak = np.full(count, -np.inf)
    np.maximum.at(peak, blob, weight)
    frames = (pixels[first] // per_frame).tolist()
    for b, frame in enumerate(frames):
        out[frame].append(
            Contact(
                row=float(row_mean[b]),
                col=float(col_mean[b]),
                size=int(size[b]),
                peak=float(peak[b]),
                strength=float(strength[b]),
            )
        )
    return out


def _number_by_first_pixel(ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Renumber blob ``ids`` (one per active pixel, raster order) 0, 1, ... by first pixel.

    Returns the new id of every pixel and the index of each blob's first pixel.  A plain
    loop is fastest for the few pixels of a live frame; ``np.unique`` takes over for
    long chunks.  Both give the same numbering.
    """
    if ids.size <= 256:
        first_of: dict[int, int] = {}
        numbered = []
        first = []
        for i, label in enumerate(ids.tolist()):
            number = first_of.get(label)
            if number is None:
                number = first_of[label] = len(first)
                first.append(i)
            numbered.append(number)
        return np.array(numbered, dtype=np.intp), np.array(first, dtype=np.intp)
    _, first, inverse = np.unique(ids, return_index=True, return_inverse=True)
    order = np.argsort(first, kind="stable")
    rank = np.empty_like(order)
    rank[order] = np.arange(order.size)
    return rank[inverse.ravel()], first[order]


@dataclass(frozen=True)
class DetectorSettings:
    """The scalar rules of :class:`ContactDetector` (per-channel levels are separate).

    - ``debounce_on_frames`` / ``debounce_off_frames``: consecutive frames with / without
      an active channel before ``touched`` turns on / off.
    - ``connectivity``: 4 or 8, for contact blobs.
    - ``on_peak_fraction`` / ``off_peak_fraction``: raise the on / off threshold of every
      channel to this fraction of the frame's largest signal (electrode cross-talk).
    - ``rearm_fraction`` / ``release_fraction``: raise a channel's on / off threshold to
      this fraction of its own recent peak, an envelope that decays by ``peak_decay`` per
      frame.  A channel then releases when its signal falls well below what the finger
      gave it, and does not fire again on the slowly relaxing fabric (creep) or a small
      baseline offset left behind by a long press.
    - ``seeded_blobs``: a candidate channel (after hysteresis) is active only when its
      blob holds a channel above its plain on threshold in that frame.
    - ``common_mode_quantile``: detection works on the signal minus, frame by frame, this
      quantile of all live channels' signals when it is positive, so an offset shared by
      the whole skin (fast thermal drift) never looks like contact; 0 disables it, and so
      does a skin of fewer than 8 live channels.
    - ``fast_on_factor``: with a fast signal, a channel also turns on (and seeds its
      blob) when its fast signal exceeds this many times its on (seed) threshold; 0
      disables it.  A fast signal always releases a channel that falls below
      ``release_fraction`` of its recent peak.
    """

    debounce_on_frames: int = 1
    debounce_off_frames: int = 1
    connectivity: int = 4
    on_peak_fraction: float = 0.0
    off_peak_fraction: float = 0.0
    rearm_fraction: float = 0.0
    release_fraction: float = 0.0
    peak_decay: float = 0.0
    seeded_blobs: bool = False
    common_mode_quantile: float = 0.0
    fast_on_factor: float = 0.0

    def __post_init__(self) -> None:
        if self.debounce_on_frames < 1 or self.debounce_off_frames < 1:
            raise ValueError("debounce lengths must be at least 1 frame")
        if self.connectivity not in _STRUCTURES:
            raise ValueError(f"connectivity must be 4 or 8, got {self.connectivity!r}")
        if not 0 <= self.off_peak_fraction <= self.on_peak_fraction < 1:
            raise ValueError("peak fractions need 0 <= off_peak_fraction <= on_peak_fraction < 1")
        if not 0 <= self.release_fraction <= self.rearm_fraction < 1:
            raise ValueError("need 0 <= release_fraction <= rearm_fraction < 1")
        if not 0 <= self.common_mode_quantile < 1:
            raise ValueError("common_mode_quantile must be in [0, 1)")
        if not 0 <= self.peak_decay < 1:
            raise ValueError(f"peak_decay must be in [0, 1), got {self.peak_decay!r}")
        if not (self.fast_on_factor == 0 or self.fast_on_factor >= 1):
            raise ValueError(f"fast_on_factor must be 0 or >= 1, got {self.fast_on_factor!r}")

    @classmethod
    def from_config(cls, config) -> DetectorSettings:
        """Settings of a :class:`~wovenskin.signal.config.ConditioningConfig`."""
        return cls(
            debounce_on_frames=config.debounce_on_frames,
            debounce_off_frames=config.debounce_off_frames,
            connectivity=config.connectivity,
            on_peak_fraction=config.on_peak_fraction,
            off_peak_fraction=config.off_peak_fraction,
            rearm_fraction=config.rearm_fraction,
            release_fraction=config.release_fraction,
            peak_decay=config.peak_decay,
            seeded_blobs=config.seeded_blobs,
            common_mode_quantile=config.common_mode_quantile,
            fast_on_factor=config.fast_on_factor,
        )


class ContactDetector:
    """Hysteresis, debounce and blob extraction with state carried between calls.

    ``on_threshold``/``off_threshold`` are per-channel ``(R, C)`` signal levels (use
    ``+inf`` for both to disable a channel), raised frame by frame as ``settings`` say.
    Call :meth:`update_active` and :meth:`update_touched` on consecutive frames (each
    keeps its own state), or :meth:`process` to run all three steps on a chunk.
    """

    def __init__(
        self,
        on_threshold: np.ndarray,
        off_threshold: np.ndarray,
        settings: DetectorSettings | None = None,
    ) -> None:
        on = np.asarray(on_threshold, dtype=np.float64)
        off = np.asarray(off_threshold, dtype=np.float64)
        if on.ndim != 2 or on.shape != off.shape:
            raise ValueError(
                f"thresholds must be two equal (rows, cols) grids, got {on.shape} and {off.shape}"
            )
        if np.any(off > on):
            raise ValueError("off thresholds must not exceed on thresholds")
        self.on_threshold = on
        self.off_threshold = off
        self.settings = settings if settings is not None else DetectorSettings()
        self.shape: tuple[int, int] = (int(on.shape[0]), int(on.shape[1]))
        self.last_labels: np.ndarray | None = None  # blob labels of the last update_active
        self._live_index = np.flatnonzero(np.isfinite(on).ravel())
        quantile = self.settings.common_mode_quantile
        self._common_rank = (
            int(quantile * (self._live_index.size - 1))
            if quantile > 0 and self._live_index.size >= _MIN_CHANNELS_FOR_COMMON_MODE
            else None
        )
        self.reset()

    @classmethod
    def from_calibration(cls, noise: np.ndarray, dead: np.ndarray, config) -> ContactDetector:
        """Thresholds from per-channel ``noise`` and the config; dead channels never fire."""
        noise = np.asarray(noise, dtype=np.float64)
        on = np.maximum(config.contact_on_sigma * noise, config.min_contact_rel)
        off = np.maximum(config.contact_off_sigma * noise, config.min_release_rel)
        on = np.where(dead, np.inf, on)
        off = np.where(dead, np.inf, off)
        return cls(on, off, DetectorSettings.from_config(config))

    def reset(self) -> None:
        """Forget all state: nothing active, not touched, frame counts back to 0."""
        self._active_t = 0
        self._last_on = np.full(self.shape, -1, dtype=np.int64)
        self._last_off = np.full(self.shape, -1, dtype=np.int64)
        self._envelope = np.zeros(self.shape, dtype=np.float64)
        self._touched = False
        self._was_active = False
        self._run = self.settings.debounce_off_frames  # as if released long ago

    def update_active(self, signal: np.ndarray, fast: np.ndarray | None = None) -> np.ndarray:
        """Per-channel hysteresis on ``signal`` ``(n, R, C)``, then blob seeding.

        ``fast``, when given, is a shorter moving average of the same input, ``(n, R, C)``
        (see ``fast_on_factor`` and the module doc).

        A channel is a candidate at frame ``t`` when its last on event (signal above its
        on threshold) is more recent than its last off event (signal below its off
        threshold); between the thresholds it keeps its state.  With ``seeded_blobs``
        a candidate is active only when its blob of candidates holds a seed, a channel
        above its plain on threshold (noise and floor, frame-peak fraction) in that frame:
        a lone channel that stays a little above its off threshold (a small baseline
        offset) then drops out, and the baseline tracker can absorb the offset.
        """
        n = signal.shape[0]
        self.last_labels = None
        if n == 0:
            return np.zeros(signal.shape, dtype=bool)
        if fast is not None and fast.shape != signal.shape:
            raise ValueError(f"fast signal has shape {fast.shape}, signal has {signal.shape}")
        level = self._common_level(signal)
        if level is not None:
            signal = signal - level
            if fast is not None:
                fast = fast - level
        seed_threshold, on_threshold, off_threshold, release = self._thresholds(signal)
        below = signal < off_threshold
        above = signal > on_threshold
        if fast is not None:
            if release is not None:
                below |= fast < release
            if self.settings.fast_on_factor > 0:
                above |= fast > self.settings.fast_on_factor * on_threshold
        if n == 1:  # the same rule without the time axis (the live, frame-by-frame case)
            t = self._active_t
            last_on = np.where(above[0], t, self._last_on)
            last_off = np.where(below[0], t, self._last_off)
            self._last_on, self._last_off = last_on, last_off
            candidate = (last_on > last_off).reshape(signal.shape)
        else:
            t = (self._active_t + np.arange(n, dtype=np.int64)).reshape(n, 1, 1)
            last_on = np.where(above, t, -1)
            last_off = np.where(below, t, -1)
            np.maximum(last_on[0], self._last_on, out=last_on[0])
            np.maximum(last_off[0], self._last_off, out=last_off[0])
            np.maximum.accumulate(last_on, axis=0, out=last_on)
            np.maximum.accumulate(last_off, axis=0, out=last_off)
            self._last_on = last_on[-1].copy()
            self._last_off = last_off[-1].copy()
            candidate = last_on > last_off
        self._active_t += n
        self.last_labels = None
        if not self.settings.seeded_blobs or not candidate.any():
            return candidate
        seeds = candidate & (signal > seed_threshold)
        if fast is not None and self.settings.fast_on_factor > 0:
            seeds |= candidate & (fast > self.settings.fast_on_factor * seed_threshold)
        labels, count = ndimage.label(candidate, structure=_STRUCTURES[self.settings.connectivity])
        seeded = np.zeros(count + 1, dtype=bool)
        seeded[labels[seeds]] = True
        seeded[0] = False
        active = seeded[labels]
        labels[~active] = 0
        self.last_labels = labels
        return active

    def _common_level(self, signal: np.ndarray) -> np.ndarray | float | None:
        """Each frame's common-mode level to remove (see ``common_mode_quantile``).

        ``None`` when there is nothing to remove; a float for a single frame; else an
        ``(n, 1, 1)`` array.
        """
        if self._common_rank is None:
            return None
        n = signal.shape[0]
        values = signal.reshape(n, -1)
        if self._live_index.size < values.shape[1]:
            values = values[:, self._live_index]
        level = np.partition(values, self._common_rank, axis=1)[:, self._common_rank]
        if n == 1:  # the same arithmetic; subtracting 0.0 would change nothing
            return float(level[0]) if level[0] > 0 else None
        return np.maximum(level, 0.0).reshape(n, 1, 1)

    def _thresholds(
        self, signal: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
        """Seed, on and off thresholds and the release level per frame, broadcastable to
        ``signal`` ``(n, R, C)`` (the release level is ``None`` without a peak envelope)."""
        rules = self.settings
        n = signal.shape[0]
        if n == 1:
            return self._frame_thresholds(signal[0])
        on = self.on_threshold[None]
        off = self.off_threshold[None]
        if rules.on_peak_fraction > 0:
            peak = signal.reshape(n, -1).max(axis=1).reshape(n, 1, 1)
            on = np.maximum(on, rules.on_peak_fraction * peak)
            off = np.maximum(off, rules.off_peak_fraction * peak)
        seed, release = on, None
        if rules.rearm_fraction > 0:
            # Envelope of each channel's recent peak, stepped frame by frame (exact for any
            # chunking).  The on threshold uses the envelope before the current frame.
            envelope = np.empty((n + 1, *self.shape))
            envelope[0] = self._envelope
            for i in range(n):
                np.maximum(signal[i], envelope[i] * rules.peak_decay, out=envelope[i + 1])
            self._envelope = envelope[n].copy()
            on = np.maximum(on, rules.rearm_fraction * envelope[:n])
            release = rules.release_fraction * envelope[1:]
            off = np.maximum(off, release)
        return seed, on, off, release

    def _frame_thresholds(
        self, frame: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
        """:meth:`_thresholds` for a single frame ``(R, C)``: the same arithmetic, fewer steps."""
        rules = self.settings
        on = self.on_threshold
        off = self.off_threshold
        if rules.on_peak_fraction > 0:
            peak = float(frame.max())
            on = np.maximum(on, rules.on_peak_fraction * peak)
            off = np.maximum(off, rules.off_peak_fraction * peak)
        seed, release = on, None
        if rules.rearm_fraction > 0:
            before = self._envelope
            self._envelope = np.maximum(frame, before * rules.peak_decay)
            on = np.maximum(on, rules.rearm_fraction * before)
            release = rules.release_fraction * self._envelope
            off = np.maximum(off, release)
            release = release[None]
        return seed[None], on[None], off[None], release

    def update_touched(self, active: np.ndarray, lifted: np.ndarray | None = None) -> np.ndarray:
        """Debounced "something touches the skin" per frame of ``active`` ``(n, R, C)``.

        ``lifted`` ``(n,)``, when given, marks the frames in which the raw signal shows
        the hand lifted (:class:`~wovenskin.signal.lift.LiftDetector`): they are
        untouched whatever ``active`` says, and turn the debounced state off (touched
        again once a channel is active with ``lifted`` clear, after the usual
        ``debounce_on_frames``).

        A small state machine over frames (the per-frame work is a few integer steps, so
        a plain loop beats array code for short chunks and stays fast for long ones).
        """
        n = active.shape[0]
        if lifted is not None and lifted.shape != (n,):
            raise ValueError(f"lifted has shape {lifted.shape}, expected ({n},)")
        lift = [False] * n if lifted is None else lifted.tolist()
        any_active = [bool(active.any())] if n == 1 else active.reshape(n, -1).any(axis=1).tolist()
        touched = np.zeros(n, dtype=bool)
        state = self._touched
        run = self._run  # frames the current any/none state has lasted (capped)
        was_active = self._was_active
        need_on = self.settings.debounce_on_frames
        need_off = self.settings.debounce_off_frames
        cap = max(need_on, need_off)
        for i, now in enumerate(any_active):
            run = min(run + 1, cap) if now == was_active else 1
            was_active = now
            if now and run >= need_on:
                state = True
            elif not now and run >= need_off:
                state = False
            if lift[i]:
                state = False
            touched[i] = state
        self._touched = state
        self._run = run
        self._was_active = was_active
        return touched

    def contacts(
        self, signal: np.ndarray, active: np.ndarray, labels: np.ndarray | None = None
    ) -> list[list[Contact]]:
        """Contact blobs per frame (stateless; see :func:`extract_contacts`)."""
        return extract_contacts(signal, active, self.settings.connectivity, labels)

    def process(
        self, signal: np.ndarray, fast: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray, list[list[Contact]]]:
        """Run hysteresis, debounce and blob extraction on ``signal`` ``(n, R, C)``."""
        active = self.update_active(signal, fast)
        labels = self.last_labels
        return active, self.update_touched(active), self.contacts(signal, active, labels)
