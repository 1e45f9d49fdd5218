"""How a simulated person performs a custom gesture's stroke script (``docs/custom-gestures.md``).

A :class:`~wovenskin.custom_gestures.CustomGesture` may carry ``strokes``: polylines of
``(x, y)`` offsets in mm from the touch centre (x right, y down), one point being a tap.
:func:`perform_strokes` makes one performance of such a script by one person, with the same
randomisation as the built-in gestures (:class:`~wovenskin.sim.person.Trial`): the whole
drawing is scaled (0.8-1.2, following the person's reach), turned a little (+-6 degrees),
each vertex displaced by about 1.5 mm, placed where the person centres gestures and fitted
onto the skin; every stroke is made by :func:`~wovenskin.sim.motion.assemble_hand` (landing,
tremor, sway, force wobble, finger asynchrony, lift-off), its segments each a minimum-jerk
movement (a finger slows at a corner) at the gesture's ``speed_mm_s`` (+-10 % per trial) or
the person's own swipe pace (``spec.SWIPE_MEAN_SPEED_MM_S``).  A tap holds its fingertip
briefly (:data:`TAP_HOLD_S`).  Between strokes the hand is off the skin for the gesture's
``pause_s`` (+-15 %) or the person's own :data:`STROKE_PAUSE_S`.  Several fingers make the
strokes side by side, across the direction the fingers point, at a two-finger swipe's
spacing (five fingers: a hand-like layout).
"""

from __future__ import annotations

import math

import numpy as np

from wovenskin.custom_gestures import CustomGesture
from wovenskin.errors import ConfigError
from wovenskin.sim import spec
from wovenskin.sim.motion import (
    FingerMotion,
    Performance,
    Phases,
    assemble_hand,
    minimum_jerk,
    place_on_skin,
    rotate,
    with_phases_from_contacts,
)
from wovenskin.sim.person import Trial
from wovenskin.sim.valid import five_finger_layout
from wovenskin.skin.layout import SkinLayout

TAP_HOLD_S = (0.04, 0.14)
"""How long a tap's fingertip stays down between landing and lifting (s)."""

STROKE_PAUSE_S = (0.08, 0.35)
"""Time off the skin between two strokes when the gesture does not fix it (s)."""

SCALE_RANGE = (0.8, 1.2)
TURN_SD_DEG = 6.0
VERTEX_SD_MM = 1.5
_FINGERS = ("index", "middle", "ring", "little")


def perform_strokes(
    gesture: CustomGesture, trial: Trial, layout: SkinLayout, fs: float
) -> Performance:
    """One performance of ``gesture``'s stroke script by ``trial``'s person; a gesture
    without strokes is one :class:`ConfigError` line."""
    if not gesture.strokes:
        raise ConfigError(
            f"custom gesture {gesture.name!r} has no strokes: the simulated person cannot "
            f"perform it (add strokes under [custom_gestures.{gesture.name}], or record it "
            "on a real skin)"
        )
    scale = trial.sized(SCALE_RANGE)
    turn = math.radians(float(trial.rng.normal(0.0, TURN_SD_DEG)))
    drawn = [
        rotate(np.asarray(stroke, dtype=float) * scale, turn)
        + trial.rng.normal(0.0, VERTEX_SD_MM, (len(stroke), 2))
        for stroke in gesture.strokes
    ]
    if gesture.speed_mm_s is not None:
        speed = gesture.speed_mm_s * float(np.exp(trial.rng.normal(0.0, 0.1)))
    else:
        speed = trial.paced(spec.SWIPE_MEAN_SPEED_MM_S)
    paths = [_centreline(points, speed, fs, trial) for points in drawn]
    hand = _finger_offsets(trial, gesture.fingers)
    # Place the whole drawing at once, so its strokes keep their places relative to each other.
    placed, fitted = place_on_skin(
        trial, [path + offset for path in paths for offset in hand.values()], layout
    )
    k = len(hand)
    pieces = []
    for i in range(len(paths)):
        motions = [
            FingerMotion(f, p) for f, p in zip(hand, placed[i * k : (i + 1) * k], strict=True)
        ]
        tap = len(gesture.strokes[i]) == 1
        pieces.append(
            assemble_hand(
                trial,
                motions,
                fs,
                label=gesture.name,
                settle_s=trial.uniform(0.0, 0.03) if tap else min(trial.settle_s(), 0.15),
                rest_s=trial.uniform(*TAP_HOLD_S) if tap else trial.uniform(0.0, 0.15),
                sway_scale=0.5 if tap else 1.0,
            )
        )
    pauses = [_pause(gesture, trial) for _ in pieces[1:]]
    return _in_sequence(gesture, pieces, pauses, fs, scale * fitted, speed)


def _centreline(points: np.ndarray, speed: float, fs: float, trial: Trial) -> np.ndarray:
    """``(m, 2)`` fingertip path through ``points``: one minimum-jerk movement per segment
    (a tap: the point itself)."""
    pieces = [points[:1]]
    for a, b in zip(points[:-1], points[1:], strict=True):
        length = float(np.linalg.norm(b - a))
        m = max(2, int(round(length / speed * fs)) + 1)
        progress = minimum_jerk(m, trial.skew())[1:, None]
        pieces.append(a + progress * (b - a))
    return np.concatenate(pieces, axis=0)


def _finger_offsets(trial: Trial, count: int) -> dict[str, np.ndarray]:
    """Each finger's place relative to the drawing point (one finger: on it)."""
    if count == 1:
        return {"index": np.zeros(2)}
    if count == 5:
        return five_finger_layout(trial, 2.0 * trial.sized(spec.PINCH_5F_BUNCHED_MM), 1.0)
    spacing = trial.spacing(spec.PAIR_SPACING_MM)
    across = rotate(trial.finger_direction(), math.pi / 2) * trial.mirror()
    return {
        finger: across * spacing * (i - (count - 1) / 2)
        for i, finger in enumerate(_FINGERS[:count])
    }


def _pause(gesture: CustomGesture, trial: Trial) -> float:
    if gesture.pause_s is not None:
        return gesture.pause_s * float(np.exp(trial.rng.normal(0.0, 0.15)))
    return trial.paced_duration(STROKE_PAUSE_S)


def _in_sequence(
    gesture: CustomGesture,
    pieces: list[Performance],
    pauses: list[float],
    fs: float,
    scale: float,
    speed: float,
) -> Performance:
    """The strokes on one clock: each lands ``pause`` after the previous one's last lift-off."""
    offsets = [0]
    for before, after, pause in zip(pieces[:-1], pieces[1:], pauses, strict=True):
        lift_end = offsets[-1] + int(round(before.event_end_s * fs))
        landing = int(round(after.event_start_s * fs))
        offsets.append(max(lift_end + int(round(pause * fs)) - landing, offsets[-1] + 1))
    total = max(o + p.n_frames for o, p in zip(offsets, pieces, strict=True))
    contacts = [
        contact.padded(offset, total - offset - contact.n_frames)
        for offset, piece in zip(offsets, pieces, strict=True)
        for contact in piece.contacts
    ]
    first, last = pieces[0], pieces[-1]
    motion_start = first.phases.motion_start_s
    motion_end = offsets[-1] / fs + last.phases.motion_end_s
    performance = Performance(
        label=gesture.name,
        invalid_kind=None,
        contacts=contacts,
        sample_rate_hz=fs,
        phases=Phases(0.0, motion_start, motion_end, 0.0, 0.0, 0.0),
        params={
            "strokes": len(pieces),
            "fingers": gesture.fingers,
            "scale": scale,
            "speed_mm_s": speed,
            "pauses_s": pauses,
        },
    )
    return with_phases_from_contacts(
        performance,
        rest_start_s=motion_end,
        lift_start_s=offsets[-1] / fs + last.phases.lift_start_s,
    )
