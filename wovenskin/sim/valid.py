"""How a simulated person performs the 14 valid gestures of ``docs/gestures.md``.

Owns the performers of the valid gestures and :func:`perform_valid`;
:func:`wovenskin.sim.performances.perform` dispatches to them, and
:mod:`wovenskin.sim.invalid` builds its partial gestures on them.  Every quantitative
range comes from :mod:`wovenskin.sim.spec`, and every trial parameter is drawn around
the person's habits by :class:`~wovenskin.sim.person.Trial`, so two people (and two
trials of one person) differ in speed, size, location, hand orientation, force, timing
and finger asynchrony.

Conventions (``wovenskin.skin.layout``): x right, y down; "up" is -y; clockwise is
clockwise as the user sees the skin, which with y down is an *increasing* angle
``atan2(y, x)`` (positive cross product ``r x v``).
"""

from __future__ import annotations

import math

import numpy as np

from wovenskin.gestures import GESTURE_NAMES
from wovenskin.sim import spec
from wovenskin.sim.motion import (
    FingerMotion,
    Performance,
    assemble_hand,
    lagging_progress,
    largest_fitting_scale,
    minimum_jerk,
    peak_speed_factor,
    place_on_skin,
    rotate,
    smooth_noise,
)
from wovenskin.sim.person import Trial
from wovenskin.skin.layout import SkinLayout

DIRECTIONS = {
    "up": np.array([0.0, -1.0]),
    "down": np.array([0.0, 1.0]),
    "right": np.array([1.0, 0.0]),
    "left": np.array([-1.0, 0.0]),
}


def perform_valid(name: str, trial: Trial, layout: SkinLayout, fs: float) -> Performance:
    """Performer of a valid gesture with an explicit trial (used for partial gestures)."""
    return _VALID[name](trial, layout, fs, name)


# -- swipes ------------------------------------------------------------------------------------
def _swipe(trial: Trial, layout: SkinLayout, fs: float, name: str) -> Performance:
    two = name.endswith("_2f")
    direction = DIRECTIONS[name.removeprefix("swipe_").removesuffix("_2f")]
    aim = trial.aim_deg()
    skew = trial.skew()
    # Horizontal strokes curve with the wrist; the sign depends on direction and hand.
    bow = trial.bow(direction_sign=1.0 if direction[0] + direction[1] > 0 else -1.0)
    unit_dir = rotate(direction, math.radians(aim))
    normal = rotate(unit_dir, math.pi / 2)
    peak_factor = peak_speed_factor(skew)
    speed = min(trial.paced(spec.SWIPE_MEAN_SPEED_MM_S), spec.SWIPE_PEAK_SPEED_MM_S / peak_factor)
    travel_wanted = trial.sized(spec.SWIPE_TRAVEL_MM)

    offsets = [np.zeros(2)]
    fingers = ["index"]
    if two:
        spacing = trial.spacing(spec.PAIR_SPACING_MM)
        across = rotate(trial.finger_direction(), math.pi / 2)
        offsets = [-across * spacing / 2, across * spacing / 2]
        # For a right hand pointing up, the index is on the left of the middle finger.
        fingers = ["index", "middle"] if trial.mirror() > 0 else ["middle", "index"]
    fixed = np.ptp(np.stack(offsets), axis=0)

    def shape(progress: np.ndarray, travel: float) -> np.ndarray:
        along = progress[:, None] * travel * unit_dir
        side = (bow * travel * np.sin(np.pi * progress))[:, None] * normal
        return along + side

    unit = shape(np.linspace(0, 1, 101), 1.0)
    travel = min(travel_wanted, largest_fitting_scale(unit, fixed, layout))
    m = max(2, int(round(travel / speed * fs)) + 1)
    centreline = shape(minimum_jerk(m, skew), travel)
    centreline -= centreline.mean(axis=0)
    paths, scale = place_on_skin(trial, [centreline + o for o in offsets], layout)
    motions = []
    for i, (finger, path) in enumerate(zip(fingers, paths, strict=True)):
        if i > 0:  # the second finger follows the first imperfectly
            path = path + _finger_jitter(trial, path.shape[0], fs, 0.4)
        motions.append(FingerMotion(finger, path))
    flick = trial.uniform(*spec.SWIPE_FLICK_LIFT_S) if trial.flick() else 0.0
    return assemble_hand(
        trial,
        motions,
        fs,
        label=name,
        rest_s=0.0 if flick else None,
        flick_s=flick,
        params={
            "travel_mm": travel * scale,
            "mean_speed_mm_s": travel * scale / ((m - 1) / fs),
            "off_axis_deg": aim,
            "bow": bow,
            "skew": skew,
            "pair_spacing_mm": float(np.linalg.norm(offsets[-1] - offsets[0])) * scale,
            "hand_angle_deg": trial.hand_angle_deg,
            "flick_s": flick,
        },
    )


def _finger_jitter(trial: Trial, n: int, fs: float, sd_mm: float) -> np.ndarray:
    """Slow independent wander of one finger relative to the hand."""
    return np.stack([smooth_noise(trial.rng, n, fs, (0.2, 3.0), sd_mm) for _ in range(2)], 1)


# -- push --------------------------------------------------------------------------------------
def _push(trial: Trial, layout: SkinLayout, fs: float, name: str) -> Performance:
    m = max(2, int(round(trial.paced_duration(spec.PUSH_RAMP_S) * fs)))
    # One draw decides both the landing style and, for a push that lands, its force: a
    # share of people press in one smooth motion (no distinct landing, the force rising
    # from nearly zero at first contact over the whole ramp).
    style = trial.uniform(0.0, 1.0)
    smooth = style < spec.PUSH_SMOOTH_SHARE
    landing_share = 0.6 + 0.4 * max(style - spec.PUSH_SMOOTH_SHARE, 0.0) / (
        1.0 - spec.PUSH_SMOOTH_SHARE
    )
    landing_force = trial.finger_force("index") * landing_share
    held_force = max(landing_force * trial.person.press_ratio, trial.uniform(1.2, 1.8))
    held_force = min(held_force, 8.0)
    if smooth:
        landing_force = held_force * spec.PUSH_SMOOTH_START
    # The press rises smoothly over the whole ramp, some people front-loading it.
    progress = minimum_jerk(m, skew=trial.uniform(-0.3, 0.3))
    gain = 1.0 + (held_force / landing_force - 1.0) * progress
    creep = trial.uniform(0.0, 1.0) * rotate(np.array([1.0, 0.0]), trial.uniform(0, 2 * np.pi))
    path = minimum_jerk(m)[:, None] * creep  # the fingertip rolls slightly as it presses
    (path,), _ = place_on_skin(trial, [path], layout)
    hold = max(trial.rest_s(), trial.uniform(0.1, 0.5))
    return assemble_hand(
        trial,
        [FingerMotion("index", path, force_gain=gain, force_n=landing_force)],
        fs,
        label=name,
        settle_s=0.0 if smooth else None,
        rest_s=hold,
        sway_scale=0.35,  # a pressing finger is held by friction
        wobble_scale=0.5,
        params={
            "ramp_s": m / fs,
            "landing_force_n": landing_force,
            "held_force_n": held_force,
            "hold_s": hold,
            "smooth_press": smooth,
        },
    )


# -- circles -----------------------------------------------------------------------------------
def _circle(trial: Trial, layout: SkinLayout, fs: float, name: str) -> Performance:
    clockwise = name == "circle_cw_2f"
    turns = trial.uniform(*spec.CIRCLE_TURNS)
    rate = trial.paced(spec.CIRCLE_RATE_HZ)
    radius_wanted = trial.sized(spec.CIRCLE_RADIUS_MM)
    spacing = trial.spacing(spec.CIRCLE_PAIR_SPACING_MM, squeeze_mm=2.5)  # held together
    m = max(8, int(round(turns / rate * fs)) + 1)
    duration = (m - 1) / fs

    # Angular speed: smooth start and stop, nearly constant in between, slightly uneven.
    ramp = min(trial.uniform(0.08, 0.18), 0.25 * duration)
    tt = np.linspace(0.0, duration, m)
    speed = np.minimum(1.0, np.minimum(tt, duration - tt) / ramp)
    speed = (0.5 - 0.5 * np.cos(np.pi * speed)) * (
        1 + smooth_noise(trial.rng, m, fs, (0.5, 3), 0.06)
    )
    angle = np.concatenate([[0.0], np.cumsum((speed[1:] + speed[:-1]) / 2)])
    angle *= 2 * np.pi * turns / angle[-1]
    theta = trial.uniform(0, 2 * np.pi) + (angle if clockwise else -angle)

    ellipticity = trial.uniform(-0.08, 0.08)
    tilt = trial.uniform(0, np.pi)
    wobble = 1 + smooth_noise(trial.rng, m, fs, (0.3, 2.5), 0.03)
    unit = np.stack([(1 + ellipticity) * np.cos(theta), (1 - ellipticity) * np.sin(theta)], 1)
    unit = rotate(unit * wobble[:, None], tilt)
    unit += _finger_jitter(trial, m, fs, 0.04)  # the circle's centre wanders a little

    across = rotate(trial.finger_direction(), math.pi / 2)
    turn_of_hand = smooth_noise(trial.rng, m, fs, (0.2, 2.0), math.radians(3.0))
    pair = rotate(np.broadcast_to(across * spacing / 2, (m, 2)), turn_of_hand)
    radius = min(radius_wanted, largest_fitting_scale(unit, np.abs(pair[0]) * 2, layout))
    centroid = unit * radius
    (path_a, path_b), scale = place_on_skin(trial, [centroid - pair, centroid + pair], layout)
    fingers = ["index", "middle"] if trial.mirror() > 0 else ["middle", "index"]
    motions = [FingerMotion(fingers[0], path_a), FingerMotion(fingers[1], path_b)]
    return assemble_hand(
        trial,
        motions,
        fs,
        label=name,
        params={
            "radius_mm": radius * scale,
            "turns": turns,
            "rate_hz": turns / duration,
            "pair_spacing_mm": spacing * scale,
            "clockwise": clockwise,
            "hand_angle_deg": trial.hand_angle_deg,
        },
    )


# -- pinches -----------------------------------------------------------------------------------
def _pinch_2f(trial: Trial, layout: SkinLayout, fs: float, name: str) -> Performance:
    start = trial.sized(spec.PINCH_2F_START_MM)
    end = trial.uniform(*spec.PINCH_2F_END_MM)
    axis_angle = math.radians(trial.hand_angle_deg) + trial.rng.normal(0.0, math.radians(50))
    axis = rotate(np.array([0.0, -1.0]), axis_angle)
    room = 0.95 * largest_fitting_scale(np.stack([-axis / 2, axis / 2]), np.zeros(2), layout)
    start = max(min(start, room), end + 5.0)  # a very small skin shrinks the whole pinch
    share = trial.uniform(0.15, 0.85)  # how much of the closing the first finger does
    closing = start - end
    mean_speed = trial.paced((60.0, 220.0))
    m = max(4, int(round(closing / mean_speed * fs)) + 1)
    twist = trial.rng.normal(0.0, math.radians(6))
    paths = []
    for sign, portion in ((-1.0, share), (1.0, 1.0 - share)):
        progress = lagging_progress(trial, m, fs, 0.04)
        begin = sign * axis * start / 2
        travel = -sign * axis * closing * portion
        curve = rotate(axis, math.pi / 2) * trial.rng.normal(0.0, 0.05) * closing * portion
        point = begin[None] + progress[:, None] * travel + np.sin(np.pi * progress)[:, None] * curve
        paths.append(rotate(point, twist * progress))
    paths, scale = place_on_skin(trial, paths, layout)
    motions = [FingerMotion("thumb", paths[0]), FingerMotion("index", paths[1])]
    return assemble_hand(
        trial,
        motions,
        fs,
        label=name,
        params={
            "start_distance_mm": start * scale,
            "end_distance_mm": end * scale,
            "share": share,
            "duration_s": (m - 1) / fs,
            "axis_deg": math.degrees(axis_angle),
        },
    )


# Fingertip directions around the hand's centre, degrees clockwise from the finger
# direction, for a right hand (a left hand mirrors them), and relative reach.
_HAND_ANGLES = {"thumb": -150.0, "index": -45.0, "middle": -12.0, "ring": 20.0, "little": 52.0}
_HAND_REACH = {"thumb": 0.95, "index": 1.0, "middle": 1.05, "ring": 1.0, "little": 0.88}


def five_finger_layout(trial: Trial, radius: float, spread: float) -> dict[str, np.ndarray]:
    """Fingertip offsets of a hand-like layout (thumb opposing) with mean radius ``radius``."""
    pointing = math.radians(trial.hand_angle_deg)
    offsets = {}
    for finger, angle in _HAND_ANGLES.items():
        a = pointing + trial.mirror() * math.radians(angle * spread + trial.rng.normal(0, 6))
        r = _HAND_REACH[finger] * (1 + trial.rng.normal(0.0, 0.05))
        offsets[finger] = r * np.array([math.sin(a), -math.cos(a)])
    stacked = np.stack(list(offsets.values()))
    stacked -= stacked.mean(axis=0)
    stacked *= radius / np.linalg.norm(stacked, axis=1).mean()
    return dict(zip(offsets, stacked, strict=True))


def _pinch_5f(trial: Trial, layout: SkinLayout, fs: float, name: str) -> Performance:
    inward = name == "pinch_in_5f"
    spread_r = trial.sized(spec.PINCH_5F_SPREAD_MM)
    bunched_r = trial.uniform(*spec.PINCH_5F_BUNCHED_MM)
    angular = trial.uniform(0.85, 1.15)
    unit_spread = five_finger_layout(trial, 1.0, angular)
    stacked = np.stack(list(unit_spread.values()))
    spread_r = min(spread_r, largest_fitting_scale(stacked, np.zeros(2), layout))
    bunched = five_finger_layout(trial, bunched_r, angular * trial.uniform(0.8, 1.0))
    m = max(4, int(round(trial.paced_duration((0.3, 0.9)) * fs)) + 1)
    drift = rotate(np.array([1.0, 0.0]), trial.uniform(0, 2 * np.pi)) * trial.uniform(0, 4)
    paths = []
    for finger, far in unit_spread.items():
        a, b = far * spread_r, bunched[finger]
        if not inward:
            a, b = b, a
        progress = lagging_progress(trial, m, fs, 0.05)
        paths.append(a + progress[:, None] * (b - a) + progress[:, None] * drift)
    paths, scale = place_on_skin(trial, paths, layout)
    motions = [FingerMotion(f, p) for f, p in zip(unit_spread, paths, strict=True)]
    return assemble_hand(
        trial,
        motions,
        fs,
        label=name,
        params={
            "spread_radius_mm": spread_r * scale,
            "bunched_radius_mm": bunched_r * scale,
            "duration_s": (m - 1) / fs,
            "hand_angle_deg": trial.hand_angle_deg,
        },
    )


_VALID = {
    **{n: _swipe for n in GESTURE_NAMES if n.startswith("swipe_")},
    "push": _push,
    "circle_cw_2f": _circle,
    "circle_ccw_2f": _circle,
    "pinch_in_2f": _pinch_2f,
    "pinch_in_5f": _pinch_5f,
    "pinch_out_5f": _pinch_5f,
}
assert set(_VALID) == set(GESTURE_NAMES), "every gesture needs a performer"
