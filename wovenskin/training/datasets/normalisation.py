"""Robust per-capture scaling of labelled captures (raw sensor values, not conditioned)."""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace

import numpy as np

from wovenskin.errors import ConfigError
from wovenskin.recording.formats import LabelledCaptures
from wovenskin.settings import from_dict


@dataclass(frozen=True)
class CaptureNormalisation:
    """Robust scaling of labelled captures, which are raw sensor values, not conditioned.

    Capture files hold raw values, larger = more pressure, with an untouched reading near
    a constant (HAART: ``1023 - ADC``, no touch ~0-5), and a capture need not start
    contact-free, so the conditioner's baseline-from-a-quiet-start does not apply.  Each
    capture's valid frames become ``(x - offset) / scale``:

    - ``offset``: the ``offset_quantile`` (5 %) of all the capture's values, channels and
      frames together.  A hand never covers the whole grid for the whole capture, so this
      is an untouched reading.  One scalar per capture, not per channel, so a channel
      pressed for the entire capture (a sustained press) keeps its signal.
    - the capture's *spread*: the ``scale_quantile`` (99 %) of ``x - offset``, its strong
      readings.  ``reference_scale`` is the median spread of the file's captures (set
      from the file when ``None``: a statistic of raw values, labels unused; the value
      used is stored with the data set so evaluation can apply the same).
    - ``per_capture=True`` (default): ``scale = max(spread, floor_fraction *
      reference_scale)``.  Scaling every capture by its own strong readings removes the
      large differences of force between people; the floor keeps a capture without
      touch from being blown up to look like one.  ``per_capture=False``: every capture
      is divided by ``reference_scale``, keeping absolute levels (and force differences).
    - ``per_group=True``: every capture is divided by its group's (participant's) median
      spread instead, floored the same way: differences of force between people go, the
      differences between one person's gestures stay.  The group's spread comes from all
      the group's captures at hand, raw values only (at test time: the new person's
      unlabelled captures); :meth:`group_spreads` computes it, :meth:`apply` takes it.
    """

    offset_quantile: float = 0.05
    scale_quantile: float = 0.99
    per_capture: bool = True
    floor_fraction: float = 0.5
    reference_scale: float | None = None
    per_group: bool = False

    def __post_init__(self) -> None:
        if not 0.0 <= self.offset_quantile < self.scale_quantile <= 1.0:
            raise ConfigError(
                "need 0 <= offset_quantile < scale_quantile <= 1, got "
                f"{self.offset_quantile} and {self.scale_quantile}"
            )
        if self.reference_scale is not None and not (
            np.isfinite(self.reference_scale) and self.reference_scale > 0
        ):
            raise ConfigError(f"reference_scale must be positive, got {self.reference_scale}")
        if not (np.isfinite(self.floor_fraction) and self.floor_fraction > 0):
            raise ConfigError(f"floor_fraction must be positive, got {self.floor_fraction}")
        if not isinstance(self.per_capture, bool):
            raise ConfigError(f"per_capture must be true or false, got {self.per_capture!r}")
        if not isinstance(self.per_group, bool):
            raise ConfigError(f"per_group must be true or false, got {self.per_group!r}")

    def offset_and_spread(self, frames: np.ndarray) -> tuple[float, float]:
        """``(offset, spread)`` of one capture's valid frames."""
        x = np.asarray(frames, dtype=np.float64).ravel()
        offset, high = np.quantile(x, [self.offset_quantile, self.scale_quantile])
        return float(offset), float(high - offset)

    def resolved(self, captures: LabelledCaptures) -> CaptureNormalisation:
        """This normalisation with ``reference_scale`` taken from ``captures`` if ``None``."""
        if self.reference_scale is not None:
            return self
        spreads = [
            self.offset_and_spread(captures.frames[i, : captures.lengths[i]])[1]
            for i in range(len(captures.lengths))
        ]
        reference = float(np.median(spreads))
        return replace(self, reference_scale=reference if reference > 0 else 1.0)

    def group_spreads(self, captures: LabelledCaptures) -> dict[str, float]:
        """The median spread of every group's captures (``per_group``; labels unused)."""
        spreads = np.array(
            [
                self.offset_and_spread(captures.frames[i, : captures.lengths[i]])[1]
                for i in range(len(captures.lengths))
            ]
        )
        groups = np.asarray(captures.groups).astype(str)
        return {g: float(np.median(spreads[groups == g])) for g in sorted(set(groups.tolist()))}

    def scale(self, spread: float, group_spread: float | None = None) -> float:
        """The divisor for a capture of this ``spread`` (of this ``group_spread``)."""
        if self.reference_scale is None:
            raise ValueError("resolve the reference scale first (CaptureNormalisation.resolved)")
        if self.per_group:
            if group_spread is None:
                raise ValueError("per-group normalisation needs the group's spread")
            return max(group_spread, self.floor_fraction * self.reference_scale)
        if not self.per_capture:
            return self.reference_scale
        return max(spread, self.floor_fraction * self.reference_scale)

    def apply(self, frames: np.ndarray, group_spread: float | None = None) -> np.ndarray:
        """One capture's valid frames ``(T, R, C)``, normalised, as float32
        (``group_spread``: its group's, from :meth:`group_spreads`, for ``per_group``)."""
        offset, spread = self.offset_and_spread(frames)
        scale = self.scale(spread, group_spread)
        return ((np.asarray(frames, dtype=np.float64) - offset) / scale).astype(np.float32)

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> CaptureNormalisation:
        return from_dict(cls, d, "capture normalisation")
