"""The 14 gestures of ``docs/gestures.md`` as the independent generator's people make them.

Each performer returns a :class:`~wovenskin.independent.tracks.Touch` placed on the
skin, its frame 0 the first finger's landing.  Straight from the gesture table:

- one-finger swipes travel 35-90 mm toward their edge with a minimum-jerk profile at a
  mean speed of 70-200 mm/s times the person's speed factor, up to 12 degrees off axis and
  bowed by up to 8 % of their travel; ``rest_s`` 0 is a *flick* (the finger starts to lift
  while the motion ends), more keeps the finger still on the skin (a *held swipe*);
- pushes press over 0.15-0.4 s and then hold within 3 mm, either as one smooth press
  from first contact or landing lightly, pausing 0.1-0.5 s and then pressing;
- two-finger swipes: a pair 15-26 mm apart at any angle to the motion (side by side, one
  behind the other, diagonal) travels 30-70 mm;
- circles: a pair 13-20 mm apart, its centre on a 14-26 mm radius, 1-2.5 turns at
  1-2.6 turns/s, the pair turning with the hand or keeping its direction;
- two-finger pinch: 45-75 mm converging to 10-20 mm, the thumb moving 30-70 % of it;
- five-finger pinches: a thumb opposite four fingers spread over 100-200 degrees, on a
  28-42 mm radius converging to 6-12 mm (``pinch_out_5f`` the reverse).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from wovenskin.errors import ConfigError
from wovenskin.independent.people import Person, log_uniform
from wovenskin.independent.tracks import (
    Finger,
    Phases,
    Touch,
    envelope,
    fit_to_skin,
    frame_times,
    min_jerk,
    raised_cosine,
    wander,
)
from wovenskin.skin.layout import SkinLayout

DIRECTIONS: dict[str, tuple[float, float]] = {
    "up": (0.0, -1.0),  # toward row 0
    "down": (0.0, 1.0),
    "right": (1.0, 0.0),  # toward higher columns
    "left": (-1.0, 0.0),
}


class Trial:
    """What one performance draws from its person: ramps, force, patch, pauses."""

    def __init__(self, person: Person, rng: np.random.Generator, fs: float) -> None:
        self.person, self.rng, self.fs = person, rng, fs

    def ramp(self) -> float:
        return float(np.clip(self.person.jitter(self.rng, self.person.ramp_s, 0.3), 0.006, 0.09))

    def force(self) -> float:
        return float(np.clip(self.person.jitter(self.rng, self.person.force_n, 0.25), 0.2, 4.5))

    def pause(self) -> float:
        return float(np.clip(self.rng.uniform(0.0, 2.0 * self.person.pause_s), 0.0, 0.3))

    def finger(self, t: np.ndarray, force: np.ndarray, scale: float = 1.0) -> Finger:
        p, rng = self.person, self.rng
        return Finger(
            x=np.zeros(len(t)),
            y=np.zeros(len(t)),
            force=force,
            length_mm=float(np.clip(scale * p.jitter(rng, p.fingertip_mm, 0.1), 5.0, 20.0)),
            aspect=float(np.clip(p.jitter(rng, p.fingertip_aspect, 0.08), 1.0, 1.9)),
            angle_deg=90.0 + p.hand_angle_deg + float(rng.normal(0.0, 8.0)),
            ref_force_n=p.force_n,
        )

    def modulation(self, n: int) -> np.ndarray:
        """A slow +-10 % wobble of a finger's force."""
        return np.clip(1.0 + wander(self.rng, n, 0.08, self.fs, tau_s=0.15)[:, 0], 0.6, 1.4)

    def still(self, n: int, sd_mm: float | None = None) -> np.ndarray:
        """``(n, 2)`` tremor of a finger holding still (at most 1.2 mm sd)."""
        return wander(self.rng, n, min(sd_mm or self.person.tremor_mm, 1.2), self.fs)


def _stroke(tau_motion: np.ndarray, travel: float, bow: float) -> tuple[np.ndarray, np.ndarray]:
    """Along-axis and lateral displacement of a bowed minimum-jerk stroke."""
    s = min_jerk(tau_motion)
    return travel * s, bow * travel * 4.0 * s * (1.0 - s)


def _rotate(along: np.ndarray, lateral: np.ndarray, angle: float) -> tuple[np.ndarray, np.ndarray]:
    c, s = np.cos(angle), np.sin(angle)
    return along * c - lateral * s, along * s + lateral * c


def swipe(
    trial: Trial,
    layout: SkinLayout,
    direction: str,
    rest_s: float = 0.0,
    fingers: int = 1,
    kind: str | None = None,
) -> Touch:
    """A one- or two-finger swipe toward ``direction``; ``rest_s`` after the motion.

    ``kind`` names it in the metadata (default: ``flick`` without a rest, ``held_swipe``
    for 2 s or more, ``swipe_rest`` between, ``swipe_2f`` for two fingers)."""
    rng, p, fs = trial.rng, trial.person, trial.fs
    dx, dy = DIRECTIONS[direction]
    travel = float(rng.uniform(35.0, 90.0) if fingers == 1 else rng.uniform(30.0, 70.0))
    speed = p.speed_factor * log_uniform(rng, 70.0, 200.0)
    duration = float(np.clip(travel / speed, 0.12, 1.3))
    heading = np.arctan2(dy, dx) + np.deg2rad(np.clip(rng.normal(0.0, 5.0), -12.0, 12.0))
    bow = float(rng.uniform(-0.08, 0.08))
    ramp_in, ramp_out = trial.ramp(), trial.ramp()
    stagger = [0.0] + [float(rng.uniform(0.0, 0.04)) for _ in range(fingers - 1)]
    motion_start = max(stagger) + 0.6 * ramp_in + trial.pause()
    motion_end = motion_start + duration
    # A flick's finger starts to lift while the motion ends; otherwise it rests.
    lift = motion_end + rest_s if rest_s > 0 else motion_end - float(rng.uniform(0.0, 0.03))
    lift_stagger = [float(rng.uniform(0.0, 0.04)) for _ in range(fingers)]
    t = frame_times(lift + max(lift_stagger) + ramp_out + 0.01, fs)
    along, lateral = _stroke((t - motion_start) / duration, travel, bow)
    cx, cy = _rotate(along, lateral, heading)
    separation = p.in_range(rng, 15.0, 26.0) if fingers == 2 else 0.0
    pair_angle = heading + float(rng.uniform(0.0, np.pi))  # any angle to the motion
    force = trial.force()
    out = []
    for k in range(fingers):
        side = (k - (fingers - 1) / 2) * separation
        env = envelope(t, stagger[k], ramp_in, lift + lift_stagger[k], ramp_out)
        finger = trial.finger(t, force * env * trial.modulation(len(t)))
        shake = trial.still(len(t))
        moving = (t >= motion_start) & (t <= motion_end)
        shake[moving] *= 0.3
        finger.x = cx + side * np.cos(pair_angle) + shake[:, 0]
        finger.y = cy + side * np.sin(pair_angle) + shake[:, 1]
        out.append(finger)
    shrink = fit_to_skin(out, layout, rng)
    name = f"swipe_{direction}" + ("_2f" if fingers == 2 else "")
    if kind is None:
        kind = "flick" if rest_s <= 0 else "held_swipe" if rest_s >= 2.0 else "swipe_rest"
        kind = "swipe_2f" if fingers == 2 else kind
    touch = Touch(
        name,
        kind,
        out,
        fs,
        Phases(0.0, motion_start, motion_end, lift, lift + max(lift_stagger) + ramp_out),
        {
            "travel_mm": travel * shrink,
            "mean_speed_mm_s": travel * shrink / duration,
            "rest_s": rest_s,
            "pair_angle_to_motion_deg": float(np.rad2deg(pair_angle - heading)),
            "separation_mm": separation * shrink,
        },
    )
    touch.settle_phases()
    return touch


def push(trial: Trial, layout: SkinLayout, smooth: bool = True) -> Touch:
    """A push: one smooth press from first contact, or land lightly, pause, then press."""
    rng, fs = trial.rng, trial.fs
    press_s = float(rng.uniform(0.15, 0.4))
    peak = trial.force() * float(rng.uniform(1.3, 2.5))
    hold_s = float(rng.uniform(0.3, 1.0))
    ramp_out = trial.ramp()
    if smooth:
        land_force, motion_start = 0.0, 0.0
    else:
        land_force = peak * float(rng.uniform(0.2, 0.45))
        motion_start = trial.ramp() + float(rng.uniform(0.1, 0.5))
    lift = motion_start + press_s + hold_s
    t = frame_times(lift + ramp_out + 0.01, fs)
    press = raised_cosine((t - motion_start) / press_s)
    level = land_force + (peak - land_force) * press
    if not smooth:
        level = np.where(t < motion_start, land_force * raised_cosine(t / trial.ramp()), level)
    level = level * envelope(t, 0.0, 1.0 / fs, lift, ramp_out)
    finger = trial.finger(t, level * trial.modulation(len(t)))
    shake = trial.still(len(t), sd_mm=min(trial.person.tremor_mm, 0.7))
    finger.x, finger.y = shake[:, 0], shake[:, 1]
    fit_to_skin([finger], layout, rng)
    touch = Touch(
        "push",
        "push_smooth" if smooth else "push_land_press",
        [finger],
        fs,
        Phases(0.0, motion_start, motion_start + press_s, lift, lift + ramp_out),
        {"press_s": press_s, "peak_force_n": peak, "hold_s": hold_s},
    )
    touch.settle_phases()
    return touch


def circle(trial: Trial, layout: SkinLayout, clockwise: bool) -> Touch:
    """Two fingers tracing a circle, clockwise as the user sees it (``y`` grows downward)."""
    rng, p, fs = trial.rng, trial.person, trial.fs
    radius = p.in_range(rng, 14.0, 26.0)
    turns = float(rng.uniform(1.0, 2.5))
    rate = float(rng.uniform(1.0, 2.6))
    separation = p.in_range(rng, 13.0, 20.0)
    turning_pair = bool(rng.random() < 0.5)
    duration = turns / rate
    ramp_in, ramp_out = trial.ramp(), trial.ramp()
    stagger = float(rng.uniform(0.0, 0.04))
    motion_start = stagger + 0.6 * ramp_in + trial.pause()
    rest = float(rng.uniform(0.0, 0.3))
    lift = motion_start + duration + rest
    t = frame_times(lift + ramp_out + 0.05, fs)
    tau = np.clip((t - motion_start) / duration, 0.0, 1.0)
    progress = 0.6 * tau + 0.4 * (tau - np.sin(2 * np.pi * tau) / (2 * np.pi))
    sign = 1.0 if clockwise else -1.0  # +angle runs clockwise on screen (y down)
    theta0 = float(rng.uniform(0.0, 2 * np.pi))
    theta = theta0 + sign * 2 * np.pi * turns * progress
    cx, cy = radius * (np.cos(theta) - np.cos(theta0)), radius * (np.sin(theta) - np.sin(theta0))
    pair = np.deg2rad(p.hand_angle_deg) + float(rng.uniform(0.0, np.pi))
    pair_angle = pair + (theta - theta0 if turning_pair else 0.0)
    force = trial.force()
    out = []
    for k, side in enumerate((-0.5, 0.5)):
        land = stagger if k else 0.0
        env = envelope(t, land, ramp_in, lift + float(rng.uniform(0.0, 0.04)), ramp_out)
        finger = trial.finger(t, force * env * trial.modulation(len(t)))
        finger.x = cx + side * separation * np.cos(pair_angle)
        finger.y = cy + side * separation * np.sin(pair_angle)
        out.append(finger)
    shrink = fit_to_skin(out, layout, rng)
    touch = Touch(
        "circle_cw_2f" if clockwise else "circle_ccw_2f",
        "circle",
        out,
        fs,
        Phases(0.0, motion_start, motion_start + duration, lift, lift),
        {
            "radius_mm": radius * shrink,
            "turns": turns,
            "turns_per_s": rate,
            "separation_mm": separation * shrink,
            "pair_turns_with_hand": turning_pair,
        },
    )
    touch.settle_phases()
    return touch


def _converge(
    trial: Trial,
    layout: SkinLayout,
    angles: np.ndarray,
    r_from: np.ndarray,
    r_to: np.ndarray,
    speed_mm_s: tuple[float, float],
    sizes: np.ndarray,
) -> tuple[list[Finger], float, float, float, float]:
    """Fingers at ``angles`` moving radially from ``r_from`` to ``r_to`` (mm from a fixed
    centre) with a minimum-jerk profile, patch sizes scaled by ``sizes``.

    Returns the fingers, the motion's start and end, the lift's start and end."""
    rng, p, fs = trial.rng, trial.person, trial.fs
    closing = float(np.max(np.abs(r_from - r_to)))
    duration = float(np.clip(closing / (p.speed_factor * log_uniform(rng, *speed_mm_s)), 0.15, 0.9))
    ramp_in, ramp_out = trial.ramp(), trial.ramp()
    stagger = rng.uniform(0.0, 0.06, size=len(angles))
    stagger[int(rng.integers(len(angles)))] = 0.0
    motion_start = float(stagger.max()) + 0.6 * ramp_in + trial.pause()
    lift = motion_start + duration + float(rng.uniform(0.0, 0.4))
    lift_stagger = rng.uniform(0.0, 0.05, size=len(angles))
    lift_end = lift + float(lift_stagger.max()) + ramp_out
    t = frame_times(lift_end + 0.01, fs)
    s = min_jerk((t - motion_start) / duration)
    force = trial.force()
    out = []
    for k, angle in enumerate(angles):
        radius = r_from[k] + (r_to[k] - r_from[k]) * s
        env = envelope(t, float(stagger[k]), ramp_in, lift + float(lift_stagger[k]), ramp_out)
        finger = trial.finger(t, force * env * trial.modulation(len(t)), scale=float(sizes[k]))
        finger.x = radius * np.cos(angle)
        finger.y = radius * np.sin(angle)
        out.append(finger)
    fit_to_skin(out, layout, rng)
    return out, motion_start, motion_start + duration, lift, lift_end


def pinch_2f(trial: Trial, layout: SkinLayout) -> Touch:
    """Two fingertips 45-75 mm apart converging to 10-20 mm."""
    rng, p = trial.rng, trial.person
    start, end = p.in_range(rng, 45.0, 75.0), p.in_range(rng, 10.0, 20.0)
    angle = float(rng.uniform(0.0, np.pi))
    thumb = float(rng.uniform(0.3, 0.7))
    # Radii from the final midpoint: finger k moves by its share of the closing.
    r_to = np.array([end / 2, end / 2])
    moves = np.array([thumb, 1.0 - thumb]) * (start - end)
    r_from = r_to + moves
    fingers, m0, m1, lift, lift_end = _converge(
        trial, layout, np.array([angle, angle + np.pi]), r_from, r_to, (80.0, 220.0),
        np.array([1.15, 1.0]),
    )  # fmt: skip
    touch = Touch(
        "pinch_in_2f",
        "pinch_2f",
        fingers,
        trial.fs,
        Phases(0.0, m0, m1, lift, lift_end),
        {"start_mm": start, "end_mm": end, "thumb_share": thumb},
    )
    touch.settle_phases()
    return touch


def pinch_5f(trial: Trial, layout: SkinLayout, inward: bool) -> Touch:
    """Five fingertips: a thumb opposite four fingers, converging (or spreading)."""
    rng, p = trial.rng, trial.person
    wide, narrow = p.in_range(rng, 28.0, 42.0), p.in_range(rng, 6.0, 12.0)
    base = np.deg2rad(p.hand_angle_deg - 90.0)  # the fingers point toward the top edge
    arc = np.deg2rad(rng.uniform(100.0, 200.0))
    angles = np.concatenate(
        [base + np.linspace(-arc / 2, arc / 2, 4), [base + np.pi + np.deg2rad(rng.normal(0, 20))]]
    )
    angles = angles + np.deg2rad(rng.normal(0.0, 6.0, size=5))
    spread = np.exp(rng.normal(0.0, 0.1, size=5))
    r_wide, r_narrow = wide * spread, narrow * spread
    r_from, r_to = (r_wide, r_narrow) if inward else (r_narrow, r_wide)
    sizes = np.array([0.95, 1.0, 0.95, 0.85, 1.2])  # index .. little finger, thumb
    fingers, m0, m1, lift, lift_end = _converge(
        trial, layout, angles, r_from, r_to, (50.0, 150.0), sizes
    )
    touch = Touch(
        "pinch_in_5f" if inward else "pinch_out_5f",
        "pinch_5f",
        fingers,
        trial.fs,
        Phases(0.0, m0, m1, lift, lift_end),
        {"wide_mm": wide, "narrow_mm": narrow, "finger_arc_deg": float(np.rad2deg(arc))},
    )
    touch.settle_phases()
    return touch


Performer = Callable[[Trial, SkinLayout], Touch]


def perform(name: str, trial: Trial, layout: SkinLayout, rest_s: float | None = None) -> Touch:
    """Gesture ``name`` (a class of docs/gestures.md).  ``rest_s`` (swipes only): time the
    fingers stay still after the motion; ``None`` draws it as people do (40 % flicks, else
    0.2-1.5 s, sometimes 2.5 s)."""
    rng = trial.rng
    if rest_s is None:
        u = rng.random()
        rest_s = 0.0 if u < 0.4 else 2.5 if u > 0.85 else float(rng.uniform(0.2, 1.5))
    for direction in DIRECTIONS:
        if name == f"swipe_{direction}":
            return swipe(trial, layout, direction, rest_s)
        if name == f"swipe_{direction}_2f":
            return swipe(trial, layout, direction, min(rest_s, 1.5), fingers=2)
    if name == "push":
        return push(trial, layout, smooth=bool(rng.random() < 0.5))
    if name in ("circle_cw_2f", "circle_ccw_2f"):
        return circle(trial, layout, clockwise=name == "circle_cw_2f")
    if name == "pinch_in_2f":
        return pinch_2f(trial, layout)
    if name in ("pinch_in_5f", "pinch_out_5f"):
        return pinch_5f(trial, layout, inward=name == "pinch_in_5f")
    raise ConfigError(f"the independent generator cannot perform {name!r}")
