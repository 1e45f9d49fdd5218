"""Touches that must never move the arm (``invalid``), as the independent generator makes them.

- ``palm``: the heel of a hand, a 40-80 mm by 30-55 mm patch, resting for 0.4-2 s with
  0-4 fingers draped beside it, drifting up to 10 mm;
- ``tap``: one fingertip on the skin for 30-90 ms in all (shorter than the dwell);
- ``grasp``: a hand grasping the link: four finger pads in a line along a side edge and a
  thumb pad, held 0.5-2.5 s with the grip shifting a little;
- ``brush``: a sleeve or the back of a hand brushing past: a light (0.05-0.3 N), wide
  (15-30 mm) patch crossing the skin at 300-800 mm/s in any direction.
"""

from __future__ import annotations

import numpy as np

from wovenskin.independent.performers import Trial
from wovenskin.independent.tracks import (
    EDGE_MARGIN_MM,
    Finger,
    Phases,
    Touch,
    envelope,
    fit_to_skin,
    frame_times,
    min_jerk,
)
from wovenskin.errors import ConfigError
from wovenskin.skin.layout import SkinLayout

INVALID_KINDS = ("palm", "tap", "grasp", "brush")


def _patch(
    t: np.ndarray,
    force: np.ndarray,
    length_mm: float,
    aspect: float,
    angle_deg: float,
    ref_force_n: float,
) -> Finger:
    return Finger(
        x=np.zeros(len(t)), y=np.zeros(len(t)), force=force, length_mm=length_mm, aspect=aspect,
        angle_deg=angle_deg, ref_force_n=ref_force_n, growth=0.1, min_mm=3.0, max_mm=120.0,
    )  # fmt: skip


def palm(trial: Trial, layout: SkinLayout) -> Touch:
    rng, fs = trial.rng, trial.fs
    hold = float(rng.uniform(0.4, 2.0))
    ramp = float(rng.uniform(0.03, 0.12))
    t = frame_times(hold + 2 * ramp + 0.1, fs)
    drift = np.deg2rad(rng.uniform(0, 360))
    travel = float(rng.uniform(0.0, 10.0)) * min_jerk(t / (hold + 2 * ramp))
    force = float(rng.uniform(2.0, 8.0))
    heel = _patch(
        t, force * envelope(t, 0.0, ramp, hold + ramp, ramp), float(rng.uniform(40.0, 80.0)),
        float(rng.uniform(1.1, 1.8)), float(rng.uniform(0.0, 180.0)), force,
    )  # fmt: skip
    heel.x, heel.y = travel * np.cos(drift), travel * np.sin(drift)
    patches = [heel]
    for _ in range(int(rng.integers(0, 5))):
        angle = np.deg2rad(rng.uniform(0, 360))
        dist = float(rng.uniform(25.0, 45.0))
        land = float(rng.uniform(0.0, 0.08))
        f = trial.force() * 0.5
        finger = trial.finger(t, f * envelope(t, land, ramp, hold + ramp, ramp))
        finger.x = heel.x + dist * np.cos(angle)
        finger.y = heel.y + dist * np.sin(angle)
        patches.append(finger)
    fit_to_skin(patches, layout, rng)
    return _touch("palm", patches, fs, {"hold_s": hold, "patches": len(patches)})


def tap(trial: Trial, layout: SkinLayout) -> Touch:
    rng, fs = trial.rng, trial.fs
    total = float(rng.uniform(0.03, 0.09))
    ramp = min(trial.ramp(), total / 3)
    t = frame_times(total + 0.02, fs)
    finger = trial.finger(t, trial.force() * envelope(t, 0.0, ramp, total - ramp, ramp))
    slide = np.deg2rad(rng.uniform(0, 360))
    d = float(rng.uniform(0.0, 2.0)) * np.clip(t / total, 0.0, 1.0)
    finger.x, finger.y = d * np.cos(slide), d * np.sin(slide)
    fit_to_skin([finger], layout, rng)
    return _touch("tap", [finger], fs, {"contact_s": total})


def grasp(trial: Trial, layout: SkinLayout) -> Touch:
    rng, fs = trial.rng, trial.fs
    hold = float(rng.uniform(0.5, 2.5))
    ramp = float(rng.uniform(0.02, 0.1))
    t = frame_times(hold + 2 * ramp + 0.1, fs)
    force = trial.force() * float(rng.uniform(1.0, 2.0))
    spacing = float(rng.uniform(16.0, 24.0))
    side = 1.0 if rng.random() < 0.5 else -1.0  # the fingers wrap in from the left or right
    pads = []
    shift = float(rng.uniform(0.0, 6.0)) * min_jerk(t / (hold + 2 * ramp))
    for k in range(5):
        thumb = k == 4
        land = float(rng.uniform(0.0, 0.1))
        env = envelope(t, land, ramp, hold + ramp + float(rng.uniform(0.0, 0.08)), ramp)
        pad = trial.finger(t, force * env, scale=1.4 if thumb else 1.2)
        pad.angle_deg = 0.0 + float(rng.normal(0.0, 10.0))  # pads lie across the link
        if thumb:
            pad.x = np.full(len(t), -side * float(rng.uniform(35.0, 55.0)))
            pad.y = np.full(len(t), 1.5 * spacing + float(rng.normal(0.0, 8.0)))
        else:
            pad.x = np.full(len(t), side * float(rng.normal(0.0, 3.0)))
            pad.y = np.full(len(t), k * spacing + float(rng.normal(0.0, 2.0)))
        pad.y = pad.y + shift
        pads.append(pad)
    fit_to_skin(pads, layout, rng)
    return _touch("grasp", pads, fs, {"hold_s": hold, "spacing_mm": spacing})


def brush(trial: Trial, layout: SkinLayout) -> Touch:
    rng, fs = trial.rng, trial.fs
    heading = np.deg2rad(rng.uniform(0, 360))
    room = (layout.width_mm - 2 * EDGE_MARGIN_MM, layout.height_mm - 2 * EDGE_MARGIN_MM)
    reach = min(
        room[0] / max(abs(np.cos(heading)), 1e-6), room[1] / max(abs(np.sin(heading)), 1e-6)
    )
    travel = float(rng.uniform(0.6, 1.0)) * reach  # across the skin, never shrunk to fit
    speed = float(rng.uniform(300.0, 800.0))
    duration = travel / speed
    ramp = float(rng.uniform(0.01, 0.04))
    t = frame_times(duration + 0.05, fs)
    force = float(rng.uniform(0.05, 0.3))
    patch = _patch(
        t, force * envelope(t, 0.0, ramp, duration - ramp, ramp), float(rng.uniform(15.0, 30.0)),
        float(rng.uniform(1.0, 2.0)), float(rng.uniform(0.0, 180.0)), force,
    )  # fmt: skip
    along = travel * np.clip(t / duration, 0.0, 1.0)
    patch.x, patch.y = along * np.cos(heading), along * np.sin(heading)
    fit_to_skin([patch], layout, rng)
    return _touch("brush", [patch], fs, {"speed_mm_s": speed, "force_n": force})


def _touch(kind: str, fingers: list[Finger], fs: float, params: dict) -> Touch:
    touch = Touch("invalid", kind, fingers, fs, Phases(0.0, None, None, 0.0, 0.0), params)
    touch.settle_phases()
    first, end = touch.contact_span()
    touch.phases.lift_start_s = max(first, end - 1) / fs
    return touch


INVALID = {"palm": palm, "tap": tap, "grasp": grasp, "brush": brush}


def perform_invalid(kind: str, trial: Trial, layout: SkinLayout) -> Touch:
    """An invalid touch of ``kind`` (one of :data:`INVALID_KINDS`)."""
    if kind not in INVALID:
        raise ConfigError(f"unknown invalid kind {kind!r}; known: {', '.join(INVALID_KINDS)}")
    return INVALID[kind](trial, layout)
