"""Custom gestures' stroke scripts as the independent generator's people make them.

A :class:`~wovenskin.custom_gestures.CustomGesture` with ``strokes`` (polylines of
``(x, y)`` mm offsets from the touch centre, x right, y down; one point: a tap) is performed
here without :mod:`wovenskin.sim` (its own choices, not a copy of ``wovenskin.sim.strokes``):

- the drawing is scaled by a log-uniform 0.75-1.3, turned with the person's hand
  (``hand_angle_deg`` / 4, +-5 degrees) and each vertex moved by up to 2 mm;
- a stroke is one continuous movement along its polyline, parametrised by arc length with
  one minimum-jerk profile over the whole stroke, its corners rounded over 3 mm (the finger
  does not stop at a corner), at the gesture's ``speed_mm_s`` (+-15 %) or 60-200 mm/s times
  the person's speed factor;
- a tap's fingertip stays down 30-160 ms, pressing harder in the middle;
- between strokes the hand is off the skin for the gesture's ``pause_s`` (+-20 %) or
  0.06-0.4 s (times 1 / the speed factor); each stroke lands on its own ramp;
- several fingers make the strokes side by side at 14-24 mm (across the hand), landing
  within 40 ms of each other.
"""

from __future__ import annotations

import numpy as np

from wovenskin.custom_gestures import CustomGesture
from wovenskin.errors import ConfigError
from wovenskin.independent.people import log_uniform
from wovenskin.independent.performers import Trial
from wovenskin.independent.tracks import (
    Finger,
    Phases,
    Touch,
    envelope,
    fit_to_skin,
    frame_times,
    min_jerk,
)
from wovenskin.skin.layout import SkinLayout

TAP_DOWN_S = (0.03, 0.16)
PAUSE_S = (0.06, 0.4)
SPEED_MM_S = (60.0, 200.0)
CORNER_MM = 3.0
SPACING_MM = (14.0, 24.0)


def perform_strokes(gesture: CustomGesture, trial: Trial, layout: SkinLayout) -> Touch:
    """One performance of ``gesture``'s stroke script; no strokes: one ConfigError line."""
    if not gesture.strokes:
        raise ConfigError(
            f"custom gesture {gesture.name!r} has no strokes: the independent generator "
            "cannot perform it"
        )
    rng, p, fs = trial.rng, trial.person, trial.fs
    scale = log_uniform(rng, 0.75, 1.3)
    turn = np.deg2rad(p.hand_angle_deg / 4.0 + float(rng.normal(0.0, 5.0)))
    rotation = np.array([[np.cos(turn), -np.sin(turn)], [np.sin(turn), np.cos(turn)]])
    drawn = [
        (np.asarray(stroke, dtype=float) * scale) @ rotation.T
        + rng.uniform(-2.0, 2.0, (len(stroke), 2))
        for stroke in gesture.strokes
    ]
    if gesture.speed_mm_s is not None:
        speed = gesture.speed_mm_s * float(np.exp(rng.normal(0.0, 0.15)))
    else:
        speed = p.speed_factor * log_uniform(rng, *SPEED_MM_S)
    # Each stroke's own timeline: (times, path, land, motion start, motion end, lift, end).
    plans = [_plan(points, speed, trial) for points in drawn]
    starts = [0.0]
    for before in plans[:-1]:
        if gesture.pause_s is not None:
            pause = gesture.pause_s * float(np.exp(rng.normal(0.0, 0.2)))
        else:
            pause = float(rng.uniform(*PAUSE_S)) / p.speed_factor
        starts.append(starts[-1] + before["end"] + pause)
    duration = starts[-1] + plans[-1]["end"] + 0.02
    t = frame_times(duration, fs)
    count = gesture.fingers
    spacing = p.in_range(rng, *SPACING_MM)
    across = np.deg2rad(p.hand_angle_deg)  # fingers side by side across the hand
    side = np.array([np.cos(across), np.sin(across)])
    stagger = [0.0] + [float(rng.uniform(0.0, 0.04)) for _ in range(count - 1)]
    force = trial.force()
    fingers = []
    for k in range(count):
        x, y = np.zeros(len(t)), np.zeros(len(t))
        level = np.zeros(len(t))
        offset = side * spacing * (k - (count - 1) / 2)
        for start, plan in zip(starts, plans, strict=True):
            local = t - start - stagger[k]
            path = plan["path"](local)
            inside = (local >= -0.05) & (local <= plan["end"] + 0.05)
            x = np.where(inside, path[:, 0] + offset[0], x)
            y = np.where(inside, path[:, 1] + offset[1], y)
            env = envelope(local, 0.0, plan["ramp_in"], plan["lift"], plan["ramp_out"])
            level = level + env * plan["press"](local)
        finger = trial.finger(t, force * np.clip(level, 0.0, None) * trial.modulation(len(t)))
        finger.x, finger.y = x, y
        fingers.append(finger)
    _hover_between(fingers)
    shrink = fit_to_skin(fingers, layout, rng)
    first, last = plans[0], plans[-1]
    touch = Touch(
        gesture.name,
        "custom",
        fingers,
        fs,
        Phases(
            0.0,
            first["motion_start"],
            starts[-1] + last["motion_end"],
            starts[-1] + last["lift"],
            starts[-1] + last["end"],
        ),
        {
            "strokes": len(plans),
            "scale": scale * shrink,
            "speed_mm_s": speed,
            "stroke_starts_s": starts,
        },
    )
    touch.settle_phases()
    return touch


def _plan(points: np.ndarray, speed: float, trial: Trial) -> dict:
    """One stroke: its path as a function of time from landing, its phases and pressure."""
    rng = trial.rng
    ramp_in, ramp_out = trial.ramp(), trial.ramp()
    if len(points) == 1:  # a tap: land, press a little harder, lift
        down = float(rng.uniform(*TAP_DOWN_S))
        point = points[0]
        bump = float(rng.uniform(0.1, 0.4))

        def tap_path(local: np.ndarray) -> np.ndarray:
            return np.broadcast_to(point, (len(local), 2)).copy()

        def tap_press(local: np.ndarray) -> np.ndarray:
            middle = np.clip(local / max(ramp_in + down, 1e-6), 0.0, 1.0)
            return 1.0 + bump * np.sin(np.pi * middle)

        return {
            "path": tap_path,
            "press": tap_press,
            "ramp_in": ramp_in,
            "ramp_out": ramp_out,
            "motion_start": 0.0,
            "motion_end": ramp_in + down,
            "lift": ramp_in + down,
            "end": ramp_in + down + ramp_out,
        }
    dense = _rounded(points)
    lengths = np.linalg.norm(np.diff(dense, axis=0), axis=1)
    arc = np.concatenate([[0.0], np.cumsum(lengths)])
    total = max(float(arc[-1]), 1e-6)
    move = float(np.clip(total / speed, 0.1, 3.0))
    motion_start = 0.6 * ramp_in + trial.pause()
    hold = float(rng.uniform(0.0, 0.2))
    lift = motion_start + move + hold

    def stroke_path(local: np.ndarray) -> np.ndarray:
        s = min_jerk((local - motion_start) / move) * total
        return np.stack([np.interp(s, arc, dense[:, i]) for i in range(2)], axis=1)

    def steady(local: np.ndarray) -> np.ndarray:
        return np.ones(len(local))

    return {
        "path": stroke_path,
        "press": steady,
        "ramp_in": ramp_in,
        "ramp_out": ramp_out,
        "motion_start": motion_start,
        "motion_end": motion_start + move,
        "lift": lift,
        "end": lift + ramp_out,
    }


def _rounded(points: np.ndarray) -> np.ndarray:
    """The polyline densely sampled with each inner corner cut by a quadratic arc of up to
    :data:`CORNER_MM` (less on short segments)."""
    out = [points[0]]
    for i in range(1, len(points) - 1):
        a, b, c = points[i - 1], points[i], points[i + 1]
        r_in = min(CORNER_MM, np.linalg.norm(b - a) / 2)
        r_out = min(CORNER_MM, np.linalg.norm(c - b) / 2)
        p0 = b + (a - b) / max(np.linalg.norm(a - b), 1e-9) * r_in
        p2 = b + (c - b) / max(np.linalg.norm(c - b), 1e-9) * r_out
        u = np.linspace(0.0, 1.0, 8)[:, None]
        out.extend((1 - u) ** 2 * p0 + 2 * (1 - u) * u * b + u**2 * p2)
    out.append(points[-1])
    dense = [out[0]]
    for a, b in zip(out[:-1], out[1:], strict=True):
        n = max(2, int(np.ceil(np.linalg.norm(b - a) / 0.5)) + 1)
        dense.extend(a + np.linspace(0.0, 1.0, n)[1:, None] * (b - a))
    return np.asarray(dense)


def _hover_between(fingers: list[Finger]) -> None:
    """Off the skin between strokes the finger travels from one stroke's end to the next
    one's start in a straight line (positions only matter where it touches)."""
    for f in fingers:
        on = np.flatnonzero(f.force > 0)
        if on.size < 2:
            continue
        gaps = np.flatnonzero(np.diff(on) > 1)
        for g in gaps:
            a, b = on[g], on[g + 1]
            u = np.linspace(0.0, 1.0, b - a + 1)
            f.x[a : b + 1] = f.x[a] + u * (f.x[b] - f.x[a])
            f.y[a : b + 1] = f.y[a] + u * (f.y[b] - f.y[a])
