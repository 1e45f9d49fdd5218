"""Touches that must never move the arm (``invalid``), as the independent generator makes them.

- ``palm``: the heel of a hand, a 40-80 mm by 30-55 mm patch, resting for 0.4-2 s with
  0-4 fingers draped beside it, drifting up to 10 mm;
- ``tap``: one fingertip on the skin for 30-90 ms in all (shorter than the dwell);
- ``grasp``: a hand grasping the link: four finger pads in a line along a side edge and a
  thumb pad, held 0.5-2.5 s with the grip shifting a little;
- ``brush``: a sleeve or the back of a hand brushing past: a light (0.05-0.3 N), wide
  (15-30 mm) patch crossing the skin at 300-800 mm/s in any direction;
- ``rub``: one fingertip rubbed back and forth along a line, 2-6 strokes of 8-30 mm at
  1.5-4 strokes a second, the line drifting and the strokes uneven;
- ``scribble``: one fingertip wandering for 0.5-2 s along a smooth random path at
  40-200 mm/s, bending every 0.1-0.4 s and staying within 10-25 mm of where it landed;
- ``slide3``: three fingertips 14-24 mm apart sliding about together for 0.5-2 s: the
  hand drifts, turns and opens or closes a little, and the fingers land and lift apart;
- ``rest4``: four fingertips resting in a row, 0.5-2.5 s, with tremor and a slow roll of
  the pressure from one end of the row to the other.
"""

from __future__ import annotations

import numpy as np

from wovenskin.errors import ConfigError
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
    wander,
)
from wovenskin.skin.layout import SkinLayout

INVALID_KINDS = ("palm", "tap", "grasp", "brush", "rub", "scribble", "slide3", "rest4")


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


def _moving_finger(trial: Trial, t: np.ndarray, ramp: float, motion: float) -> Finger:
    """One fingertip down from the first frame, moving for ``motion`` s, its force wobbling."""
    force = trial.force() * envelope(t, 0.0, ramp, motion + ramp, ramp)
    return trial.finger(t, force * trial.modulation(len(t)))


def rub(trial: Trial, layout: SkinLayout) -> Touch:
    rng, fs = trial.rng, trial.fs
    strokes = int(rng.integers(2, 7))
    rate = float(rng.uniform(1.5, 4.0))  # strokes a second
    amplitude = float(rng.uniform(8.0, 30.0))
    ramp = trial.ramp()
    motion = strokes / rate
    t = frame_times(motion + 2 * ramp + 0.05, fs)
    finger = _moving_finger(trial, t, ramp, motion)
    tau = np.clip((t - ramp) / motion, 0.0, 1.0)
    uneven = 1.0 + 0.25 * rng.standard_normal(strokes + 1)
    k = np.minimum((tau * strokes).astype(int), strokes - 1)
    phase = tau * strokes - k  # 0 -> 1 within each stroke
    ends = np.concatenate(
        [[0.0], amplitude * np.clip(uneven[1:], 0.4, 1.6) * (np.arange(strokes) % 2 == 0)]
    )
    along = ends[k] + (ends[k + 1] - ends[k]) * min_jerk(phase)
    heading = np.deg2rad(rng.uniform(0, 360)) + np.deg2rad(rng.normal(0.0, 8.0)) * tau
    drift = trial.still(len(t), 1.2) + float(rng.uniform(0.0, 6.0)) * tau[:, None]
    finger.x = along * np.cos(heading) + drift[:, 0]
    finger.y = along * np.sin(heading) + drift[:, 1]
    fit_to_skin([finger], layout, rng)
    return _touch("rub", [finger], fs, {"strokes": strokes, "amplitude_mm": amplitude})


def scribble(trial: Trial, layout: SkinLayout) -> Touch:
    rng, fs = trial.rng, trial.fs
    motion = float(rng.uniform(0.5, 2.0))
    ramp = trial.ramp()
    t = frame_times(motion + 2 * ramp + 0.05, fs)
    speed = float(rng.uniform(40.0, 200.0))
    heading = float(rng.uniform(0, 2 * np.pi))
    reach = float(rng.uniform(10.0, 25.0))  # how far from where it began the finger wanders
    turn_rate = 0.0
    next_turn = 0.0
    x = np.zeros(len(t))
    y = np.zeros(len(t))
    for i in range(1, len(t)):
        if t[i] >= next_turn:  # a new bend: turning rate up to 1.5 turns a second either way
            turn_rate = float(rng.uniform(-3.0, 3.0)) * np.pi
            next_turn = t[i] + float(rng.uniform(0.1, 0.4))
        moving = ramp <= t[i] <= ramp + motion
        heading += turn_rate / fs
        if np.hypot(x[i - 1], y[i - 1]) > reach:  # the hand stays put: bend back inwards
            inward = np.arctan2(-y[i - 1], -x[i - 1])
            heading += 0.2 * np.angle(np.exp(1j * (inward - heading)))
        step = speed / fs if moving else 0.0
        x[i], y[i] = x[i - 1] + step * np.cos(heading), y[i - 1] + step * np.sin(heading)
    finger = _moving_finger(trial, t, ramp, motion)
    finger.x, finger.y = x, y
    fit_to_skin([finger], layout, rng)
    return _touch("scribble", [finger], fs, {"speed_mm_s": speed, "motion_s": motion})


def slide3(trial: Trial, layout: SkinLayout) -> Touch:
    rng, fs = trial.rng, trial.fs
    motion = float(rng.uniform(0.5, 2.0))
    ramp = trial.ramp()
    t = frame_times(motion + 2 * ramp + 0.15, fs)
    tau = np.clip((t - ramp) / motion, 0.0, 1.0)
    spacing = float(rng.uniform(14.0, 24.0))
    open_by = float(rng.uniform(-0.3, 0.3))  # the hand opens (+) or closes (-) by this much
    turn = np.deg2rad(rng.uniform(-60.0, 60.0)) * min_jerk(tau)
    base = np.deg2rad(rng.uniform(0, 360))
    path = wander(rng, len(t), float(rng.uniform(4.0, 15.0)), fs, tau_s=0.25)
    path = path - path[0]
    fingers = []
    for k in (-1, 0, 1):
        land = float(rng.uniform(0.0, 0.06))
        lift = motion + ramp + float(rng.uniform(0.0, 0.08))
        f = trial.finger(t, trial.force() * envelope(t, land, ramp, lift, ramp))
        r = k * spacing * (1.0 + open_by * min_jerk(tau)) + float(rng.normal(0.0, 2.0))
        bend = abs(k) * float(rng.uniform(0.0, 8.0))  # the outer fingers sit a little back
        angle = base + turn
        f.x = r * np.cos(angle) - bend * np.sin(angle) + path[:, 0]
        f.y = r * np.sin(angle) + bend * np.cos(angle) + path[:, 1]
        fingers.append(f)
    fit_to_skin(fingers, layout, rng)
    return _touch("slide3", fingers, fs, {"spacing_mm": spacing, "motion_s": motion})


def rest4(trial: Trial, layout: SkinLayout) -> Touch:
    rng, fs = trial.rng, trial.fs
    hold = float(rng.uniform(0.5, 2.5))
    ramp = trial.ramp()
    t = frame_times(hold + 2 * ramp + 0.15, fs)
    spacing = float(rng.uniform(15.0, 22.0))
    angle = np.deg2rad(rng.uniform(0, 360))
    roll = float(rng.uniform(0.0, 0.5)) * np.sin(2 * np.pi * t / max(hold, 0.5))
    fingers = []
    for k in range(4):
        land = float(rng.uniform(0.0, 0.1))
        lift = hold + ramp + float(rng.uniform(0.0, 0.1))
        weight = np.clip(1.0 + roll * (k - 1.5) / 1.5, 0.3, 1.7)
        f = trial.finger(t, trial.force() * weight * envelope(t, land, ramp, lift, ramp))
        r = (k - 1.5) * spacing
        arc = float(rng.uniform(0.0, 6.0)) * (
            1.0 - abs(k - 1.5) / 1.5
        )  # the middle fingers reach further
        shake = trial.still(len(t))
        f.x = r * np.cos(angle) - arc * np.sin(angle) + shake[:, 0]
        f.y = r * np.sin(angle) + arc * np.cos(angle) + shake[:, 1]
        fingers.append(f)
    fit_to_skin(fingers, layout, rng)
    return _touch("rest4", fingers, fs, {"hold_s": hold, "spacing_mm": spacing})


def _touch(kind: str, fingers: list[Finger], fs: float, params: dict) -> Touch:
    touch = Touch("invalid", kind, fingers, fs, Phases(0.0, None, None, 0.0, 0.0), params)
    touch.settle_phases()
    first, end = touch.contact_span()
    touch.phases.lift_start_s = max(first, end - 1) / fs
    return touch


INVALID = {
    "palm": palm, "tap": tap, "grasp": grasp, "brush": brush, "rub": rub, "scribble": scribble,
    "slide3": slide3, "rest4": rest4,
}  # fmt: skip


def perform_invalid(kind: str, trial: Trial, layout: SkinLayout) -> Touch:
    """An invalid touch of ``kind`` (one of :data:`INVALID_KINDS`)."""
    if kind not in INVALID:
        raise ConfigError(f"unknown invalid kind {kind!r}; known: {', '.join(INVALID_KINDS)}")
    return INVALID[kind](trial, layout)
