"""Detection benchmark: signal conditioning scored against the simulator's ground truth.

Each seed's stream (:func:`~wovenskin.sim.stream.simulate_stream`, a simulated person on a
simulated skin) is calibrated on its first ``calibration_s`` and conditioned whole
(:func:`~wovenskin.signal.conditioner.condition_recording`).  The debounced ``touched``
flag is then compared with the labelled events, each spanning first contact to last
lift-off:

- *phantom fraction*: the share of frames outside every event widened to
  ``[start - PHANTOM_LEAD_S, end + PHANTOM_TAIL_S]`` (a hovering hand is sensed a little
  before it lands; the flag needs a moment to clear after lift-off) that are touched;
- per valid gesture event: the share of its frames that are touched, and its peak
  conditioned signal (strongest channel) in units of the skin's median calibrated noise;
- *release latency*: from each event's last lift-off to the first untouched frame,
  counted for events followed by enough contact-free time;
- whether calibration was ``ok``, and whether the first ``calibration_s`` of the stream
  was in fact contact-free (it always is: streams start with >= 1 s of idle).

:func:`run_detection_benchmark` returns a :class:`DetectionReport` whose :meth:`lines`
are one summary line per seed and a total; ``python -m wovenskin.bench.detection 0 20``
prints them.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field

import numpy as np

from wovenskin.gestures import INVALID
from wovenskin.signal.conditioner import condition_recording
from wovenskin.signal.config import ConditioningConfig
from wovenskin.sim.skin_physics import TYPICAL_GAIN_PF, SkinPhysics
from wovenskin.sim.stream import simulate_stream

PHANTOM_LEAD_S = 0.05
"""Touched this long before an event's first contact is no phantom (hover)."""

PHANTOM_TAIL_S = 0.3
"""Touched this long after an event's last lift-off is no phantom (release)."""

RELEASE_WINDOW_S = 0.5
"""Release latency is measured only where this much contact-free time follows an event."""


def event_mask(t: np.ndarray, starts, ends, lead_s: float = 0.0, tail_s: float = 0.0):
    """Boolean mask of the times ``t`` inside any ``[start - lead_s, end + tail_s]``."""
    inside = np.zeros(t.shape, dtype=bool)
    for start, end in zip(starts, ends, strict=True):
        inside |= (t >= start - lead_s) & (t <= end + tail_s)
    return inside


def phantom_fraction(touched: np.ndarray, t: np.ndarray, starts, ends) -> float:
    """Share of the frames outside every widened event that are touched (0 if none)."""
    outside = ~event_mask(t, starts, ends, PHANTOM_LEAD_S, PHANTOM_TAIL_S)
    count = int(outside.sum())
    return float((touched & outside).sum() / count) if count else 0.0


def touched_fraction(touched: np.ndarray, t: np.ndarray, start: float, end: float) -> float:
    """Share of the frames in ``[start, end]`` that are touched (0 for an empty span)."""
    inside = (t >= start) & (t <= end)
    return float(touched[inside].mean()) if inside.any() else 0.0


def release_latencies(touched: np.ndarray, t: np.ndarray, starts, ends) -> list[float]:
    """Seconds from each event's end to the first untouched frame after it.

    Only events that were touched at their end and are followed by at least
    ``RELEASE_WINDOW_S`` without another event count; a flag still set after that
    window counts as the whole window.
    """
    out = []
    starts, ends = np.asarray(starts, dtype=float), np.asarray(ends, dtype=float)
    for i, end in enumerate(ends):
        following = starts[i + 1] if i + 1 < len(starts) else t[-1]
        if following - end < RELEASE_WINDOW_S:
            continue
        after = (t > end) & (t <= end + RELEASE_WINDOW_S)
        at_end = (t >= end - 0.02) & (t <= end)
        if not touched[at_end].any():
            continue
        free = np.flatnonzero(~touched[after])
        window = t[after]
        out.append(float(window[free[0]] - end) if free.size else RELEASE_WINDOW_S)
    return out


@dataclass
class SeedDetection:
    """Detection figures of one simulated stream."""

    seed: int
    calibration_ok: bool
    contact_free_start: bool
    phantom_fraction: float
    event_labels: list[str] = field(default_factory=list)  # valid gesture events only
    event_touched: list[float] = field(default_factory=list)
    event_peak_snr: list[float] = field(default_factory=list)  # peak / median noise
    release_latency_s: list[float] = field(default_factory=list)

    def line(self) -> str:
        touched = np.asarray(self.event_touched)
        weak = int((touched < 0.6).sum())
        release = np.median(self.release_latency_s) * 1000 if self.release_latency_s else 0.0
        return (
            f"seed {self.seed:2d} cal_ok {self.calibration_ok!s:5} phantom "
            f"{self.phantom_fraction:.3f} touched median {np.median(touched):.2f} min "
            f"{touched.min():.2f} below(.6) {weak}/{touched.size} release median "
            f"{release:.0f} ms"
        )


@dataclass
class DetectionReport:
    """Figures over several seeds (see the module doc)."""

    seeds: list[SeedDetection]

    @property
    def mean_phantom(self) -> float:
        return float(np.mean([s.phantom_fraction for s in self.seeds]))

    @property
    def worst_phantom(self) -> float:
        return float(max(s.phantom_fraction for s in self.seeds))

    @property
    def event_touched(self) -> np.ndarray:
        """Touched fraction of every valid gesture event, all seeds pooled."""
        return np.concatenate([np.asarray(s.event_touched, dtype=float) for s in self.seeds])

    @property
    def median_touched(self) -> float:
        return float(np.median(self.event_touched))

    @property
    def release_latency_s(self) -> np.ndarray:
        return np.concatenate([np.asarray(s.release_latency_s, dtype=float) for s in self.seeds])

    @property
    def calibration_ok_where_clean(self) -> bool:
        """Calibration ok on every seed whose calibration period was contact-free."""
        return all(s.calibration_ok for s in self.seeds if s.contact_free_start)

    def weak_events(self, below: float = 0.6) -> list[tuple[int, str, float, float]]:
        """``(seed, label, touched fraction, peak in noise units)`` of events below ``below``."""
        return [
            (s.seed, label, frac, snr)
            for s in self.seeds
            for label, frac, snr in zip(
                s.event_labels, s.event_touched, s.event_peak_snr, strict=True
            )
            if frac < below
        ]

    def lines(self) -> list[str]:
        release = self.release_latency_s * 1000
        total = (
            f"MEAN phantom {self.mean_phantom:.4f}  worst {self.worst_phantom:.4f}  "
            f"median-touched {self.median_touched:.3f}  worst-event "
            f"{self.event_touched.min():.3f}  release median {np.median(release):.0f} ms "
            f"p90 {np.percentile(release, 90):.0f} ms"
        )
        return [s.line() for s in self.seeds] + [total]


DETECTION_GAIN_PF = TYPICAL_GAIN_PF
"""Skin gains (pF) the contact detection is scored on: the range it was tuned for (a firm
press changes a channel by 2-12 %).  The simulator draws far duller and far more
sensitive skins for the recogniser's training; on those a light touch can sit at the
contact threshold, or a hovering hand cross it.  ``wovenskin bench recognition`` measures
what that costs end to end (``response_x0.1`` ... ``response_x10``)."""


def evaluate_seed(
    seed: int, seconds: float = 60.0, config: ConditioningConfig | None = None
) -> SeedDetection:
    """Simulate ``seconds`` of stream ``seed``, condition it and score the detection."""
    config = config if config is not None else ConditioningConfig()
    physics = SkinPhysics.sample_typical(np.random.default_rng(seed))
    stream = simulate_stream(seconds, seed, physics=physics)
    calibration, out = condition_recording(stream.frames.astype(np.float32), config)
    t = stream.t
    starts, ends = stream.event_start_s, stream.event_end_s
    noise = float(np.median(calibration.noise[~calibration.dead]))
    result = SeedDetection(
        seed=int(seed),
        calibration_ok=calibration.ok,
        contact_free_start=not bool(starts.size and starts[0] < config.calibration_s),
        phantom_fraction=phantom_fraction(out.touched, t, starts, ends),
        release_latency_s=release_latencies(out.touched, t, starts, ends),
    )
    for start, end, label in zip(starts, ends, stream.event_labels, strict=True):
        if label == INVALID:
            continue
        inside = (t >= start) & (t <= end)
        result.event_labels.append(str(label))
        result.event_touched.append(touched_fraction(out.touched, t, start, end))
        result.event_peak_snr.append(float(out.signal[inside].max()) / noise)
    return result


def run_detection_benchmark(
    seeds=range(20), seconds: float = 60.0, config: ConditioningConfig | None = None
) -> DetectionReport:
    """:func:`evaluate_seed` for every seed of ``seeds``."""
    return DetectionReport([evaluate_seed(int(s), seconds, config) for s in seeds])


def main(argv: list[str]) -> int:
    """``python -m wovenskin.bench.detection [FIRST LAST]``: seeds FIRST..LAST-1."""
    first, last = (int(argv[0]), int(argv[1])) if len(argv) >= 2 else (0, 20)
    report = run_detection_benchmark(range(first, last))
    print("\n".join(report.lines()))
    for seed, label, frac, snr in report.weak_events():
        print(f"weak event: seed {seed} {label} touched {frac:.2f} peak {snr:.0f} x noise")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
