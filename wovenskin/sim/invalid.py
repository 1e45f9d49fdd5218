"""How a simulated person produces touches that must be classified ``invalid``.

Owns :data:`INVALID_KINDS` and :func:`perform_invalid`.  The kinds follow the ``invalid``
row of ``docs/gestures.md``:

- ``short_tap``: one or two fingertips, single or double tap, each contact shorter than
  the 0.1 s dwell time;
- ``palm``: heel, thenar and hypothenar pads (sometimes with the fingers' proximal pads),
  large, low-pressure, slowly sliding;
- ``forearm``: a long ellipse wider than the skin, often preceded by the sleeve;
- ``grasp``: a hand grasping the link: four fingers along one edge, the thumb on the other;
- ``brush``: brushing past: fast, light, partial, often entering from off the skin;
- ``three_fingers`` / ``four_fingers``: static presses or moving strokes;
- ``scribble``: a random wandering path with one or two fingers;
- ``noise_burst``: electrical interference over many channels for 50-300 ms, no contact;
- ``partial_gesture``: a valid gesture cut off right after it starts (contact < dwell).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from wovenskin.errors import ConfigError
from wovenskin.gestures import GESTURE_NAMES, INVALID
from wovenskin.sim import spec
from wovenskin.sim.contact import ContactTrack, NoiseBurst
from wovenskin.sim.motion import (
    LEAD_S,
    FingerMotion,
    Performance,
    Phases,
    assemble_hand,
    available_box,
    contact_envelope,
    fingertip_track,
    fold_into_box,
    minimum_jerk,
    place_on_skin,
    rotate,
    smooth_noise,
    smooth_noise_2d,
    with_phases_from_contacts,
    zero_force_off_skin,
)
from wovenskin.sim.person import Person, Trial
from wovenskin.sim.valid import perform_valid
from wovenskin.skin.layout import SkinLayout

INVALID_KINDS = (
    "short_tap",
    "palm",
    "forearm",
    "grasp",
    "brush",
    "three_fingers",
    "four_fingers",
    "scribble",
    "noise_burst",
    "partial_gesture",
)


_ATTEMPTS = 50
"""How often a touch that misses the skin altogether is tried again."""


def perform_invalid(
    person: Person,
    rng: np.random.Generator,
    layout: SkinLayout,
    kind: str | None = None,
    sample_rate_hz: float = 200.0,
) -> Performance:
    """One invalid touch of ``kind`` (random when ``None``) by ``person``.

    Contacts carry no force while entirely off the skin; contacts that never reach the
    skin are dropped, and a touch that misses the skin altogether is performed again.
    """
    if kind is None:
        kind = str(rng.choice(INVALID_KINDS))
    if kind not in _PERFORMERS:
        raise ConfigError(f"unknown invalid kind {kind!r}; known: {', '.join(INVALID_KINDS)}")
    for _ in range(_ATTEMPTS):
        performance = _PERFORMERS[kind](person, rng, layout, sample_rate_hz)
        for c in performance.contacts:
            zero_force_off_skin(c, layout)
        performance.contacts = [c for c in performance.contacts if c.touching.any()]
        if performance.contacts or performance.bursts:
            break
    else:
        raise RuntimeError(f"could not place an invalid {kind!r} touch on a {layout.shape} skin")
    performance.label = INVALID
    performance.invalid_kind = kind
    return with_phases_from_contacts(
        performance,
        rest_start_s=performance.phases.rest_start_s,
        lift_start_s=performance.phases.lift_start_s if performance.contacts else None,
    )


# -- helpers -----------------------------------------------------------------------------------
def _anywhere(trial: Trial, layout: SkinLayout, overhang_mm: float = 0.0) -> np.ndarray:
    """A uniformly random point on the skin, optionally up to ``overhang_mm`` beyond it."""
    return np.array(
        [
            trial.uniform(-overhang_mm, layout.width_mm + overhang_mm),
            trial.uniform(-overhang_mm, layout.height_mm + overhang_mm),
        ]
    )


@dataclass(frozen=True)
class BodyPart:
    """One elliptical contact of a hand or arm, placed around the body's pivot."""

    kind: str  # a ContactTrack kind
    name: str  # "heel", "thumb", ...
    offset: np.ndarray  # (2,) mm from the pivot
    force_n: float
    semi_major_mm: float
    semi_minor_mm: float
    angle_rad: float


def _body_part_performance(
    trial: Trial,
    fs: float,
    parts: list[BodyPart],
    *,
    ramp_s: tuple[float, float],
    hold_s: float,
    slide: np.ndarray,
    turn_rad: float,
    pivot: np.ndarray,
    lead_delays_s: list[float] | None = None,
) -> Performance:
    """Large contacts (palm, forearm, grasp) that land, slide/turn a little and lift.

    Every part follows the same slide and rotation of the body about ``pivot``.
    """
    rng = trial.rng
    lead = int(round(LEAD_S * fs))
    delays = lead_delays_s or [0.0] * len(parts)
    land = [lead + int(round(d * fs)) for d in delays]
    ramps_in = [max(1, int(round(trial.uniform(*ramp_s) * fs))) for _ in parts]
    down = max(a + b for a, b in zip(land, ramps_in, strict=True))
    hold = max(1, int(round(hold_s * fs)))
    lift = [down + hold + int(round(abs(rng.normal(0, 0.03)) * fs)) for _ in parts]
    ramps_out = [max(1, int(round(trial.uniform(*ramp_s) * fs))) for _ in parts]
    n = max(a + b for a, b in zip(lift, ramps_out, strict=True)) + lead
    t = np.arange(n)
    progress = minimum_jerk(hold + 1)[np.clip(t - down, 0, hold)]
    contacts = []
    for i, part in enumerate(parts):
        turned = rotate(np.broadcast_to(part.offset, (n, 2)), turn_rad * progress)
        pos = pivot + turned + progress[:, None] * slide
        pos = pos + smooth_noise_2d(rng, n, fs, (0.2, 2.0), 0.4)
        env = contact_envelope(n, land[i], ramps_in[i], lift[i], ramps_out[i])
        wobble = 1 + smooth_noise(rng, n, fs, (0.3, 4.0), 0.1)
        contacts.append(
            ContactTrack(
                pos[:, 0],
                pos[:, 1],
                part.force_n * env * np.clip(wobble, 0.5, None),
                part.semi_major_mm,
                min(part.semi_minor_mm, part.semi_major_mm),
                part.angle_rad + turn_rad * progress,
                part.kind,
                part.name,
            )
        )
    moving = float(np.linalg.norm(slide)) > 1.0 or abs(turn_rad) > 0.05
    phases = Phases(0, down / fs, (down + hold if moving else down) / fs, 0, min(lift) / fs, 0)
    return Performance(INVALID, None, contacts, fs, phases)


# -- kinds -------------------------------------------------------------------------------------
def _short_tap(person: Person, rng, layout: SkinLayout, fs: float) -> Performance:
    trial = Trial(person, rng)
    fingers = ["index"] if rng.random() < 0.75 else ["index", "middle"]
    taps = 1 if rng.random() < 0.7 else 2
    lead = int(round(LEAD_S * fs))
    max_contact = int(math.floor((spec.DWELL_S - 0.005) * fs))
    schedule = []
    start = lead
    for _ in range(taps):
        ramp_in = max(1, int(round(trial.uniform(0.01, 0.025) * fs)))
        ramp_out = max(1, int(round(trial.uniform(0.01, 0.025) * fs)))
        hold = int(round(trial.uniform(0.0, 0.05) * fs))
        hold = max(0, min(hold, max_contact - ramp_in - ramp_out - 2))
        schedule.append((start, ramp_in, start + ramp_in + hold, ramp_out))
        start += ramp_in + hold + ramp_out + int(round(trial.uniform(0.08, 0.2) * fs))
    n = start + lead
    low, high = available_box(layout)
    centre = np.array([trial.uniform(low[0], high[0]), trial.uniform(low[1], high[1])])
    across = rotate(trial.finger_direction(), math.pi / 2)
    spacing = trial.spacing(spec.PAIR_SPACING_MM)
    contacts = []
    for i, finger in enumerate(fingers):
        offset = across * spacing * (i - (len(fingers) - 1) / 2)
        env = np.zeros(n)
        for land, ramp_in, lift, ramp_out in schedule:
            jitter = int(rng.integers(0, 2)) if i else 0
            env = np.maximum(env, contact_envelope(n, land + jitter, ramp_in, lift, ramp_out))
        pos = centre + offset + smooth_noise_2d(rng, n, fs, (1.0, 8.0), 0.2)
        contacts.append(fingertip_track(trial, finger, pos, trial.finger_force(finger) * env))
    first_lift = schedule[-1][2]
    phases = Phases(0, lead / fs, lead / fs, 0, first_lift / fs, 0)
    perf = Performance(INVALID, None, contacts, fs, phases, params={"taps": taps})
    return with_phases_from_contacts(perf, lift_start_s=first_lift / fs)


def _palm(person: Person, rng, layout: SkinLayout, fs: float) -> Performance:
    trial = Trial(person, rng)
    along = trial.finger_direction()
    across = rotate(along, math.pi / 2) * trial.mirror()
    axis = math.atan2(along[1], along[0])
    u = trial.uniform
    pads = [  # (name, offset, share of the force, semi-axes, tilt)
        ("heel", -22 * along, 0.35, u(14, 20), u(10, 15), 0.0),
        ("thenar", -4 * along - 17 * across, 0.35, u(16, 22), u(10, 14), 0.3),
        ("hypothenar", -6 * along + 18 * across, 0.3, u(16, 22), u(9, 12), -0.2),
    ]
    keep = [p for p in pads if rng.random() < 0.8] or [pads[0]]
    parts = [("palm", *p) for p in keep]
    if rng.random() < 0.4:  # the proximal finger pads touch too
        for j, finger in enumerate(("index", "middle", "ring", "little")):
            offset = u(22, 30) * along + (j - 1.5) * 17 * across
            parts.append(("finger", finger, offset, 0.08, u(10, 14), u(6, 8), 0.0))
    total = u(3.0, 15.0)
    share = sum(p[3] for p in parts)
    body = [
        BodyPart(kind, name, off, total * w / share, a, b, axis + tilt)
        for kind, name, off, w, a, b, tilt in parts
    ]
    slide = rotate(np.array([1.0, 0.0]), u(0, 2 * np.pi)) * u(0, 25)
    return _body_part_performance(
        trial,
        fs,
        body,
        ramp_s=(0.04, 0.15),
        hold_s=u(0.3, 2.5),
        slide=slide,
        turn_rad=rng.normal(0, 0.1),
        pivot=_anywhere(trial, layout) - 0.5 * slide,
        lead_delays_s=list(np.abs(rng.normal(0, 0.04, len(body)))),
    )


def _forearm(person: Person, rng, layout: SkinLayout, fs: float) -> Performance:
    trial = Trial(person, rng)
    along = trial.finger_direction()
    angle = math.atan2(along[1], along[0]) + rng.normal(0, 0.5)
    major, minor = trial.uniform(50, 110), trial.uniform(22, 35)
    parts = [BodyPart("forearm", "forearm", np.zeros(2), trial.uniform(4, 25), major, minor, angle)]
    delays = [0.0]
    if rng.random() < 0.5:  # the sleeve brushes the skin first and leaves last
        force = trial.uniform(0.3, 1.5)
        sleeve = BodyPart("sleeve", "sleeve", np.zeros(2), force, major + 10, minor + 8, angle)
        parts.insert(0, sleeve)
        delays = [0.0, trial.uniform(0.1, 0.6)]
    slide = rotate(np.array([1.0, 0.0]), trial.uniform(0, 2 * np.pi)) * trial.uniform(0, 30)
    return _body_part_performance(
        trial,
        fs,
        parts,
        ramp_s=(0.05, 0.2),
        hold_s=trial.uniform(0.5, 4.0),
        slide=slide,
        turn_rad=rng.normal(0, 0.08),
        pivot=_anywhere(trial, layout, overhang_mm=15.0) - 0.5 * slide,
        lead_delays_s=delays,
    )


def _grasp(person: Person, rng, layout: SkinLayout, fs: float) -> Performance:
    trial = Trial(person, rng)
    w, h = layout.width_mm, layout.height_mm
    edge = str(rng.choice(["left", "right", "top", "bottom"]))
    inward = np.array({"left": (1, 0), "right": (-1, 0), "top": (0, 1), "bottom": (0, -1)}[edge])
    inward = inward.astype(float)
    along_edge = np.abs(rotate(inward, math.pi / 2))
    edge_point = {"left": (0, h / 2), "right": (w, h / 2), "top": (w / 2, 0), "bottom": (w / 2, h)}
    length, across_link = (h, w) if edge in ("left", "right") else (w, h)
    base = np.array(edge_point[edge], dtype=float)
    spacing = trial.uniform(16, 22)
    slack = max(0.0, length / 2 - 1.5 * spacing - 6.0)  # keep the grip mostly on the skin
    centre_along = trial.uniform(-slack, slack)
    angle = math.atan2(inward[1], inward[0])
    parts = []
    for j, finger in enumerate(("index", "middle", "ring", "little")):
        pos = base + inward * trial.uniform(2, 12)
        pos = pos + along_edge * (centre_along + (j - 1.5) * spacing * trial.mirror())
        a, b = trial.uniform(9, 14), trial.uniform(5, 7)
        parts.append(BodyPart("finger", finger, pos, trial.uniform(1.5, 6.0), a, b, angle))
    # The thumb sits on the opposite edge, roughly across from the index finger.
    thumb_along = centre_along - 1.5 * spacing * trial.mirror() + trial.uniform(-15, 15)
    thumb_along = float(np.clip(thumb_along, -length / 2 + 6, length / 2 - 6))
    opposite = base + inward * across_link
    thumb = opposite - inward * trial.uniform(3, 12) + along_edge * thumb_along
    a = trial.uniform(8, 12)
    parts.append(BodyPart("finger", "thumb", thumb, trial.uniform(2, 7), a, 6.5, angle + math.pi))
    pivot = np.mean([p.offset for p in parts], axis=0)
    parts = [
        BodyPart(
            p.kind,
            p.name,
            p.offset - pivot,
            p.force_n,
            p.semi_major_mm,
            p.semi_minor_mm,
            p.angle_rad,
        )
        for p in parts
    ]
    return _body_part_performance(
        trial,
        fs,
        parts,
        ramp_s=(0.02, 0.08),
        hold_s=trial.uniform(0.5, 3.0),
        slide=rng.normal(0, 1.0, 2),
        turn_rad=rng.normal(0, 0.02),
        pivot=pivot,
        lead_delays_s=list(np.abs(rng.normal(0, 0.05, len(parts)))),
    )


def _brush(person: Person, rng, layout: SkinLayout, fs: float) -> Performance:
    trial = Trial(person, rng)
    direction = rotate(np.array([1.0, 0.0]), trial.uniform(0, 2 * np.pi))
    through = _anywhere(trial, layout)
    length = trial.uniform(40, 220)
    start = through - direction * trial.uniform(0.2, 0.8) * length
    speed = trial.uniform(350, 900)
    m = max(3, int(round(length / speed * fs)) + 1)
    progress = np.linspace(0, 1, m) + 0.05 * np.sin(np.pi * np.linspace(0, 1, m))
    centreline = start + progress[:, None] * direction * length
    lead = int(round(LEAD_S * fs))
    n = m + 2 * lead
    t = np.arange(n)
    idx = np.clip(t - lead, 0, m - 1)
    back_of_hand = rng.random() < 0.3
    count = 1 if back_of_hand else int(rng.integers(1, 5))
    across = rotate(direction, math.pi / 2)
    spacing = trial.spacing(spec.PAIR_SPACING_MM)
    # Only part of the sweep touches: the hand dips onto the skin and off again.
    touch_from = lead + int(trial.uniform(0.0, 0.3) * m)
    ramp = max(1, int(round(trial.uniform(0.01, 0.04) * fs)))
    touch_to = lead + int(trial.uniform(0.7, 1.0) * m) - ramp  # off before the hand slows
    touch_to = max(touch_to, touch_from + 1)
    contacts = []
    for j in range(count):
        pos = centreline[idx] + across * spacing * (j - (count - 1) / 2)
        pos = pos + smooth_noise_2d(rng, n, fs, (1.0, 6.0), 0.5)
        env = contact_envelope(n, touch_from + int(rng.integers(0, 3)), ramp, touch_to, ramp)
        force = trial.uniform(0.05, 0.5) * env
        if back_of_hand:
            a, b = trial.uniform(12, 25), trial.uniform(8, 15)
            angle = math.atan2(direction[1], direction[0])
            contacts.append(
                ContactTrack(pos[:, 0], pos[:, 1], force, a, min(a, b), angle, "hand_back")
            )
        else:
            contacts.append(
                fingertip_track(trial, ("index", "middle", "ring", "little")[j], pos, force)
            )
    phases = Phases(0, touch_from / fs, touch_to / fs, 0, touch_to / fs, 0)
    perf = Performance(INVALID, None, contacts, fs, phases, params={"speed_mm_s": speed})
    return with_phases_from_contacts(perf, lift_start_s=touch_to / fs)


def _several_fingers(count: int):
    def performer(person: Person, rng, layout: SkinLayout, fs: float) -> Performance:
        trial = Trial(person, rng)
        names = ("index", "middle", "ring", "little")[:count]
        reach = {"index": 0.0, "middle": 6.0, "ring": 2.0, "little": -9.0}
        across = rotate(trial.finger_direction(), math.pi / 2) * trial.mirror()
        spacing = trial.uniform(15, 22)
        offsets = [
            across * spacing * (j - (count - 1) / 2) + trial.finger_direction() * reach[f]
            for j, f in enumerate(names)
        ]
        moving = rng.random() < 0.55
        if moving:
            direction = rotate(np.array([1.0, 0.0]), trial.uniform(0, 2 * np.pi))
            travel, speed = trial.uniform(20, 70), trial.paced(spec.SWIPE_MEAN_SPEED_MM_S)
            m = max(2, int(round(travel / speed * fs)) + 1)
            centreline = minimum_jerk(m, trial.skew())[:, None] * direction * travel
        else:
            m = max(2, int(round(trial.uniform(0.2, 1.5) * fs)))
            centreline = np.zeros((m, 2))
        paths, _ = place_on_skin(trial, [centreline + o for o in offsets], layout)
        motions = [FingerMotion(f, p) for f, p in zip(names, paths, strict=True)]
        return assemble_hand(
            trial,
            motions,
            fs,
            label=INVALID,
            sway_scale=1.0 if moving else 0.6,
            params={"fingers": count, "moving": moving},
        )

    return performer


def _scribble(person: Person, rng, layout: SkinLayout, fs: float) -> Performance:
    trial = Trial(person, rng)
    m = max(4, int(round(trial.uniform(0.8, 2.5) * fs)))
    velocity = smooth_noise_2d(rng, m, fs, (0.3, 2.5), trial.uniform(60, 180))
    low, high = available_box(layout)
    start = np.array([trial.uniform(low[0], high[0]), trial.uniform(low[1], high[1])])
    path = fold_into_box(start + np.cumsum(velocity, axis=0) / fs, low, high)
    motions = [FingerMotion("index", path)]
    if rng.random() < 0.2:
        offset = rotate(trial.finger_direction(), math.pi / 2) * trial.spacing((15, 26))
        second = fold_into_box(path + offset, low, high)
        motions.append(FingerMotion("middle", second))
    return assemble_hand(trial, motions, fs, label=INVALID, params={"fingers": len(motions)})


def _noise_burst(person: Person, rng, layout: SkinLayout, fs: float) -> Performance:
    duration = float(rng.uniform(0.05, 0.3))
    burst = NoiseBurst(
        start_s=LEAD_S,
        duration_s=duration,
        strength=float(rng.uniform(0.5, 2.5)),
        line_fraction=float(rng.uniform(0.3, 1.0)),
        frequency_hz=float(rng.uniform(3.0, 95.0)),
    )
    end = LEAD_S + duration
    phases = Phases(LEAD_S, LEAD_S, end, end, end, end)
    return Performance(INVALID, None, [], fs, phases, bursts=[burst])


def _partial_gesture(person: Person, rng, layout: SkinLayout, fs: float) -> Performance:
    name = str(rng.choice(GESTURE_NAMES))
    trial = Trial(person, rng, quick_start=True)
    full = perform_valid(name, trial, layout, fs)
    first = int(round(full.phases.landing_s * fs))
    lift = first + int(round(trial.uniform(0.03, 0.065) * fs))
    ramp_out = max(1, int(round(trial.uniform(0.01, 0.03) * fs)))
    lead = int(round(LEAD_S * fs))
    n = lift + ramp_out + lead
    cut = contact_envelope(n, 0, 0, lift, ramp_out)
    contacts = []
    for c in full.contacts:
        force = c.force_n[:n] * cut
        if not force.any():
            continue  # this finger would have landed after the hand lifted again
        contacts.append(
            ContactTrack(
                c.x_mm[:n],
                c.y_mm[:n],
                force,
                c.semi_major_mm[:n],
                c.semi_minor_mm[:n],
                c.angle_rad[:n],
                c.kind,
                c.finger,
            )
        )
    ph = full.phases
    end = (lift + ramp_out) / fs
    phases = Phases(0, ph.motion_start_s, min(ph.motion_end_s, end), 0, lift / fs, 0)
    perf = Performance(INVALID, None, contacts, fs, phases, params={"gesture": name})
    return with_phases_from_contacts(perf, lift_start_s=lift / fs)


_PERFORMERS = {
    "short_tap": _short_tap,
    "palm": _palm,
    "forearm": _forearm,
    "grasp": _grasp,
    "brush": _brush,
    "three_fingers": _several_fingers(3),
    "four_fingers": _several_fingers(4),
    "scribble": _scribble,
    "noise_burst": _noise_burst,
    "partial_gesture": _partial_gesture,
}
assert set(_PERFORMERS) == set(INVALID_KINDS), "every invalid kind needs a performer"
