"""``wovenskin bench tracking``: contact tracks against the simulator's ground-truth fingertips.

Each trial is one gesture performed by a simulated person on a simulated skin
(:mod:`wovenskin.sim`; person and skin drawn from the trial's seed), rendered after a
contact-free lead, conditioned as live (:class:`~wovenskin.signal.conditioner.LiveConditioner`
with the shipped model's settings) and tracked by the touch reader's
:class:`~wovenskin.tracking.tracker.ContactTracker` on the short moving average.  On every
frame where at least one fingertip of the performance presses the skin (after the first
``settle_s`` of the touch), the bench compares:

- *count*: the live tracks (merged ones included) against the fingertips pressing;
- *position*: where the counts agree, tracks matched to fingertips by least total
  distance, and the distance of each pair (mm, on the skin's plane);
- *identity*: for every fingertip, the distinct track identities it was matched to over
  the touch (1 is perfect; each extra one is an identity switch).

Figures are given per finger count (1, 2 and 5), since two fingertips a channel apart
share one peak and the tracker keeps them apart by their history alone.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from rich.table import Table
from scipy.optimize import linear_sum_assignment

from wovenskin.bench.results import BenchResult
from wovenskin.errors import ConfigError
from wovenskin.gestures import GESTURES
from wovenskin.recognition.pipeline import conditioning_for_model, load_recognizer
from wovenskin.signal.conditioner import LiveConditioner
from wovenskin.signal.config import ConditioningConfig
from wovenskin.sim.performances import perform
from wovenskin.sim.person import Person
from wovenskin.sim.physics import SkinModel
from wovenskin.sim.skin_physics import SkinPhysics
from wovenskin.skin.layout import SkinLayout
from wovenskin.tracking.touch import TouchReader

DEFAULT_TRIALS = 3  # per gesture
DEFAULT_SEED = 31000
SETTLE_S = 0.05  # the landing's first frames are left out (fingers ramp in over 10-50 ms)
LEAD_S = 0.8  # contact-free frames before the performance (calibration needs 0.5 s)

Progress = Callable[[str], None]


@dataclass
class TrackingBenchResult(BenchResult):
    trials: int
    seed: int
    by_fingers: dict[str, dict[str, Any]] = field(default_factory=dict)
    wall_s: float = 0.0

    def table(self) -> Table:
        table = Table(
            "fingers",
            "frames",
            "count right",
            "position error mm (median / p90)",
            "identities per fingertip (mean / max)",
            title=f"wovenskin bench tracking: {self.trials} simulated performances (seed "
            f"{self.seed}), tracks against the simulator's fingertips",
        )
        for fingers, m in self.by_fingers.items():
            table.add_row(
                fingers,
                str(m["frames"]),
                f"{100 * m['count_right']:.1f} %",
                f"{m['error_median_mm']:.1f} / {m['error_p90_mm']:.1f}"
                if m["error_median_mm"] is not None
                else "-",
                f"{m['identities_mean']:.2f} / {m['identities_max']}",
            )
        return table


def _truth(performance, layout: SkinLayout, n: int) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per frame, the (x, y) mm of the fingertips pressing the skin, and their indices."""
    tips = performance.fingertips()
    out = []
    for i in range(n):
        xs, idx = [], []
        for k, tip in enumerate(tips):
            if i < tip.n_frames and float(np.asarray(tip.force_n)[i]) > 0:
                xs.append((float(np.asarray(tip.x_mm)[i]), float(np.asarray(tip.y_mm)[i])))
                idx.append(k)
        out.append((np.array(xs).reshape(-1, 2), np.array(idx, dtype=int)))
    return out


def run_trial(
    name: str, seed: int, config: ConditioningConfig, layout: SkinLayout | None = None
) -> dict[str, Any]:
    """One performance of gesture ``name``: per-frame counts, errors and identities."""
    layout = layout or SkinLayout()
    rng = np.random.default_rng(seed)
    physics = SkinPhysics.sample(rng)
    person = Person.sample(rng)
    fs = config.sample_rate_hz
    model = SkinModel(physics, layout, seed=int(rng.integers(2**31)), sample_rate_hz=fs)
    performance = perform(name, person, rng, layout, sample_rate_hz=fs)
    lead = int(round(LEAD_S * fs))
    frames = np.concatenate(
        [
            model.render_idle(lead),
            model.render(performance.contacts, performance.n_frames, performance.bursts),
            model.render_idle(int(0.2 * fs)),
        ]
    )
    conditioner = LiveConditioner(config, layout.rows, layout.cols)
    out = conditioner.feed(frames)
    offset = len(frames) - len(out)  # frames the calibration kept
    truth = _truth(performance, layout, performance.n_frames)
    reader = TouchReader(layout.rows, layout.cols, layout.row_pitch_mm, layout.col_pitch_mm, fs)
    settle = int(round(SETTLE_S * fs))
    counts, errors = [], []
    identities: dict[int, set[int]] = {}
    first = None
    for j in range(len(out)):
        i = j + offset - lead  # frame of the performance
        state = reader.step(out.fast[j], out.active[j], bool(out.touched[j]))
        if not (0 <= i < performance.n_frames):
            continue
        true_xy, true_idx = truth[i]
        if len(true_idx) == 0:
            continue
        first = i if first is None else first
        if i - first < settle:
            continue
        tracks = [] if state is None else state.tracks
        counts.append(len(tracks) == len(true_idx))
        if tracks and len(tracks) == len(true_idx):
            tx, ty = layout.rc_to_mm(
                np.array([t.y / layout.row_pitch_mm for t in tracks]),
                np.array([t.x / layout.col_pitch_mm for t in tracks]),
            )
            cost = np.hypot(tx[:, None] - true_xy[None, :, 0], ty[:, None] - true_xy[None, :, 1])
            rows, cols = linear_sum_assignment(cost)
            for r, c in zip(rows.tolist(), cols.tolist(), strict=True):
                errors.append(float(cost[r, c]))
                identities.setdefault(int(true_idx[c]), set()).add(tracks[r].id)
    fingers = max((len(t[1]) for t in truth), default=0)
    return {
        "gesture": name,
        "fingers": fingers,
        "counts": counts,
        "errors": errors,
        "identities": [len(v) for v in identities.values()],
    }


def run_tracking_benchmark(
    trials: int = DEFAULT_TRIALS,
    seed: int = DEFAULT_SEED,
    gestures: Sequence[str] | None = None,
    config: ConditioningConfig | None = None,
    progress: Progress | None = None,
) -> TrackingBenchResult:
    """``trials`` performances of every gesture (or of ``gestures``), scored per finger count."""
    if trials < 1:
        raise ConfigError(f"--trials must be at least 1, got {trials}")
    if config is None:
        config = conditioning_for_model(load_recognizer())
    names = list(gestures) if gestures else [g.name for g in GESTURES]
    started = time.perf_counter()
    pooled: dict[str, dict[str, list]] = {}
    total = len(names) * trials
    for k, name in enumerate(names):
        for trial in range(trials):
            if progress is not None:
                progress(f"{name} {trial + 1}/{trials} ({k * trials + trial + 1} of {total})")
            row = run_trial(name, seed + 1000 * k + trial, config)
            into = pooled.setdefault(
                str(row["fingers"]), {"counts": [], "errors": [], "identities": []}
            )
            for key in ("counts", "errors", "identities"):
                into[key].extend(row[key])
    result = TrackingBenchResult(trials=total, seed=seed)
    for fingers in sorted(pooled, key=int):
        p = pooled[fingers]
        errors = np.array(p["errors"])
        ids = np.array(p["identities"]) if p["identities"] else np.array([0])
        result.by_fingers[fingers] = {
            "frames": len(p["counts"]),
            "count_right": float(np.mean(p["counts"])) if p["counts"] else 0.0,
            "error_median_mm": float(np.median(errors)) if errors.size else None,
            "error_p90_mm": float(np.percentile(errors, 90)) if errors.size else None,
            "identities_mean": float(ids.mean()),
            "identities_max": int(ids.max()),
        }
    result.wall_s = time.perf_counter() - started
    return result
