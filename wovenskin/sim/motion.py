"""Building blocks of simulated performances: profiles, hand assembly and placement.

Owns the :class:`Performance` record (what a simulated person did: contact tracks, phase
boundaries, event start/end) and the tools every performer shares:

- speed profiles (:func:`minimum_jerk`, a bell-shaped speed with an optional skew),
  smooth band-limited noise for tremor, sway and force wobble, contact ramps;
- :func:`assemble_hand`, which turns per-finger motion paths into complete fingertip
  :class:`~wovenskin.sim.physics.ContactTrack` objects with landing, settling, the
  characteristic motion, resting and lift-off, finger asynchrony, tremor, force wobble and
  patches that grow with force;
- :func:`fit_onto_skin` and :func:`largest_fitting_scale`, which keep valid gestures on the
  skin with a margin for the patch (shrinking a motion only where the skin is too small).

Positions are millimetres, x right and y down from the top-left corner of the sensing area.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from wovenskin.io import to_jsonable
from wovenskin.sim import spec
from wovenskin.sim.contact import ContactTrack, NoiseBurst
from wovenskin.sim.person import Trial
from wovenskin.skin.layout import SkinLayout

LEAD_S = 0.12
"""Hovering time before the first contact and after the last lift-off of a performance."""

FIT_MARGIN_MM = spec.SKIN_MARGIN_MM + 1.5
"""Margin used when fitting a planned motion: the patch radius plus room for tremor/sway."""


@dataclass
class Phases:
    """Phase boundaries of a performance, in seconds from its frame 0."""

    landing_s: float  # first contact
    motion_start_s: float
    motion_end_s: float
    rest_start_s: float  # fingers resting after the motion (== motion end)
    lift_start_s: float  # first finger starts to lift
    lift_end_s: float  # last lift-off

    def to_dict(self) -> dict[str, float]:
        return asdict(self)

    def shifted(self, seconds: float) -> Phases:
        return Phases(**{k: v + seconds for k, v in asdict(self).items()})


@dataclass
class Performance:
    """One simulated gesture or invalid touch, ready to render.

    ``contacts`` share frame 0 and the sample rate; ``event_start_s``/``event_end_s`` are
    the first contact and the last lift-off (for a noise burst: its start and end).
    ``params`` records the trial's drawn parameters (travel, speed, radius, ...).
    """

    label: str
    invalid_kind: str | None
    contacts: list[ContactTrack]
    sample_rate_hz: float
    phases: Phases
    bursts: list[NoiseBurst] = field(default_factory=list)
    params: dict = field(default_factory=dict)

    @property
    def n_frames(self) -> int:
        n = max((c.n_frames for c in self.contacts), default=0)
        for b in self.bursts:
            n = max(n, int(round((b.start_s + b.duration_s + LEAD_S) * self.sample_rate_hz)))
        return n

    @property
    def duration_s(self) -> float:
        return self.n_frames / self.sample_rate_hz

    @property
    def event_start_s(self) -> float:
        return self.phases.landing_s

    @property
    def event_end_s(self) -> float:
        return self.phases.lift_end_s

    def fingertips(self) -> list[ContactTrack]:
        return [c for c in self.contacts if c.kind == "fingertip"]

    def touching(self) -> np.ndarray:
        """Boolean ``(n_frames,)``: any contact touching."""
        mask = np.zeros(self.n_frames, dtype=bool)
        for c in self.contacts:
            mask[: c.n_frames] |= c.touching
        return mask

    def summary(self) -> dict:
        """JSON-friendly description (label, kind, phases, parameters) for stream metadata."""
        return {
            "label": self.label,
            "invalid_kind": self.invalid_kind,
            "phases": self.phases.to_dict(),
            "fingers": [c.finger or c.kind for c in self.contacts],
            "params": to_jsonable(self.params),
            "bursts": [b.to_dict() for b in self.bursts],
        }


# -- profiles ----------------------------------------------------------------------------------
def minimum_jerk(n: int, skew: float = 0.0) -> np.ndarray:
    """Progress 0 -> 1 over ``n`` samples with a bell-shaped speed profile.

    ``skew`` warps time (``tau ** exp(skew)``): negative values peak early, positive late.
    """
    if n <= 1:
        return np.ones(max(n, 0))
    tau = np.linspace(0.0, 1.0, n) ** float(np.exp(skew))
    return tau**3 * (10.0 - 15.0 * tau + 6.0 * tau**2)


def peak_speed_factor(skew: float, n: int = 2001) -> float:
    """Peak speed of :func:`minimum_jerk` relative to its mean speed (1.875 unskewed)."""
    s = minimum_jerk(n, skew)
    return float(np.max(np.diff(s)) * (n - 1))


def contact_envelope(n: int, land: int, ramp_in: int, lift: int, ramp_out: int) -> np.ndarray:
    """0..1 envelope: 0 before ``land``, ramps up, 1, ramps down from ``lift``, then 0.

    A lift that begins before the landing ramp has finished cuts the ramp short.
    """
    t = np.arange(n)
    up = np.clip(t - land + 1, 0, ramp_in + 1) / (ramp_in + 1)
    down = np.clip(lift + ramp_out - t, 0, ramp_out + 1) / (ramp_out + 1)
    return 0.5 - 0.5 * np.cos(np.pi * np.minimum(up, down))


def smooth_noise(
    rng: np.random.Generator, n: int, fs: float, band_hz: tuple[float, float], sd: float
) -> np.ndarray:
    """Band-limited Gaussian noise of ``n`` samples with standard deviation ``sd``."""
    if n == 0 or sd == 0:
        return np.zeros(n)
    length = max(n, int(2 * fs / max(band_hz[0], 0.05)))  # long enough to resolve the band
    spectrum = np.fft.rfft(rng.standard_normal(length))
    freq = np.fft.rfftfreq(length, 1.0 / fs)
    spectrum[(freq < band_hz[0]) | (freq > band_hz[1])] = 0.0
    signal = np.fft.irfft(spectrum, length)
    std = signal.std()  # of the whole realisation: a short slice keeps its slow offset
    if std == 0:
        return np.zeros(n)
    return signal[:n] / std * sd


def smooth_noise_2d(rng, n: int, fs: float, band_hz: tuple[float, float], sd: float) -> np.ndarray:
    return np.stack([smooth_noise(rng, n, fs, band_hz, sd) for _ in range(2)], axis=1)


def rotate(v: np.ndarray, angle_rad: float) -> np.ndarray:
    """Rotate vectors ``(..., 2)`` by ``angle_rad`` (clockwise on screen: x right, y down)."""
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    return np.stack([v[..., 0] * c - v[..., 1] * s, v[..., 0] * s + v[..., 1] * c], axis=-1)


def resample_path(path: np.ndarray, n: int) -> np.ndarray:
    """Linear resampling of a ``(m, 2)`` path to ``n`` samples."""
    m = path.shape[0]
    if m == n:
        return path
    src = np.linspace(0.0, 1.0, m)
    dst = np.linspace(0.0, 1.0, n)
    return np.stack([np.interp(dst, src, path[:, i]) for i in range(2)], axis=1)


# -- placement ---------------------------------------------------------------------------------
def available_box(layout: SkinLayout, margin: float = FIT_MARGIN_MM) -> tuple[np.ndarray, ...]:
    """``(low, high)`` corners of where fingertip centres may go."""
    low = np.array([margin, margin])
    high = np.array([layout.width_mm - margin, layout.height_mm - margin])
    return low, np.maximum(high, low)


def largest_fitting_scale(
    unit_path: np.ndarray, fixed_extent: np.ndarray, layout: SkinLayout
) -> float:
    """Largest ``k`` such that a path ``k * unit_path`` plus a fixed finger layout fits.

    ``unit_path`` is ``(m, 2)``; ``fixed_extent`` the ``(2,)`` bounding-box size of the
    finger offsets that do not scale (e.g. a pair's spacing).
    """
    low, high = available_box(layout)
    room = np.maximum(high - low - fixed_extent, 0.0)
    size = unit_path.max(axis=0) - unit_path.min(axis=0)
    with np.errstate(divide="ignore"):
        ratios = np.where(size > 1e-9, room / np.maximum(size, 1e-12), np.inf)
    return float(np.min(ratios))


def fit_onto_skin(
    paths: list[np.ndarray], layout: SkinLayout, centre: np.ndarray
) -> tuple[list[np.ndarray], float]:
    """Move (and if it cannot fit, shrink) finger paths so that all stay on the skin.

    The group's bounding-box centre goes as close to ``centre`` as the skin allows.
    Returns the placed paths and the shrink factor applied (1.0 = none).
    """
    stacked = np.concatenate(paths, axis=0)
    lo, hi = stacked.min(axis=0), stacked.max(axis=0)
    mid = (lo + hi) / 2
    low, high = available_box(layout)
    room = high - low
    size = hi - lo
    scale = float(min(1.0, *(room / np.maximum(size, 1e-9))))
    half = size * scale / 2
    target = np.clip(centre, low + half, np.maximum(high - half, low + half))
    placed = [(p - mid) * scale + target for p in paths]
    return placed, scale


def place_on_skin(
    trial: Trial, paths: list[np.ndarray], layout: SkinLayout
) -> tuple[list[np.ndarray], float]:
    """:func:`fit_onto_skin` around where ``trial`` centres its gesture."""
    centre = trial.location(layout.width_mm, layout.height_mm)
    return fit_onto_skin(paths, layout, centre)


def lagging_progress(trial: Trial, m: int, fs: float, max_lag_s: float) -> np.ndarray:
    """:func:`minimum_jerk` progress over ``m`` samples that starts up to ``max_lag_s``
    late (one finger of several setting off after the others)."""
    lag = int(round(trial.uniform(0.0, max_lag_s) * fs))
    return np.concatenate([np.zeros(lag), minimum_jerk(m - lag, trial.skew())])


# -- hand assembly -----------------------------------------------------------------------------
@dataclass
class FingerMotion:
    """One finger's characteristic motion: ``path`` ``(m, 2)`` absolute mm (m >= 1).

    ``force_gain`` (``(m,)``, optional) multiplies the finger's force during the motion;
    its last value holds afterwards (a push's press).  ``force_n`` overrides the trial's
    typical force of that finger.
    """

    finger: str
    path: np.ndarray
    force_gain: np.ndarray | None = None
    force_n: float | None = None
    delay_s: float = 0.0  # the finger's motion starts this much after the hand's


def assemble_hand(
    trial: Trial,
    fingers: list[FingerMotion],
    fs: float,
    *,
    label: str,
    invalid_kind: str | None = None,
    settle_s: float | None = None,
    rest_s: float | None = None,
    flick_s: float = 0.0,
    sway_scale: float = 1.0,
    wobble_scale: float = 1.0,
    params: dict | None = None,
) -> Performance:
    """Turn per-finger motions into a complete fingertip :class:`Performance`.

    Timeline: hover ``LEAD_S``; fingers land (asynchronously, 10-50 ms ramps); a pause of
    ``settle_s``; the characteristic motion (``path`` samples at ``fs``); resting
    ``rest_s``; lift-off (asynchronous ramps), starting ``flick_s`` before the motion ends
    when the finger flicks off; hover ``LEAD_S``.
    """
    rng = trial.rng
    k = len(fingers)
    settle_s = trial.settle_s() if settle_s is None else settle_s
    rest_s = trial.rest_s() if rest_s is None else rest_s
    lead = int(round(LEAD_S * fs))
    land = lead + np.round(trial.finger_delays_s(k) * fs).astype(int)
    ramp_in = [max(1, int(round(trial.landing_ramp_s() * fs))) for _ in range(k)]
    all_down = max(int(land[i] + ramp_in[i]) for i in range(k))
    motion_start = all_down + int(round(settle_s * fs))
    starts = [motion_start + int(round(f.delay_s * fs)) for f in fingers]
    motion_end = max(s + f.path.shape[0] - 1 for s, f in zip(starts, fingers, strict=True))
    lift_base = motion_end + 1 + int(round(rest_s * fs)) - int(round(flick_s * fs))
    lift_base = max(lift_base, all_down)
    lift = lift_base + np.round(trial.finger_delays_s(k) * fs).astype(int)
    ramp_out = [max(1, int(round(trial.lift_ramp_s() * fs))) for _ in range(k)]
    n = max(int(lift[i] + ramp_out[i]) for i in range(k)) + lead

    person = trial.person
    t = np.arange(n)
    in_motion = (t >= motion_start) & (t <= motion_end)
    steady = 0.35 + 0.65 * in_motion  # force and position are steadier when not sliding
    sway = smooth_noise_2d(rng, n, fs, (0.1, 1.0), person.sway_mm * sway_scale)
    tremor_band = (person.tremor_hz - 1.5, person.tremor_hz + 1.5)
    tremor = smooth_noise_2d(rng, n, fs, tremor_band, person.tremor_mm * sway_scale)

    contacts = []
    for i, f in enumerate(fingers):
        m = f.path.shape[0]
        idx = np.clip(t - starts[i], 0, m - 1)
        pos = f.path[idx] + sway + tremor
        pos = pos + smooth_noise_2d(rng, n, fs, (0.3, 4.0), 0.3 * person.tremor_mm * sway_scale)
        skid = rng.normal(0.0, 0.35 * sway_scale, 2)
        env = contact_envelope(n, int(land[i]), ramp_in[i], int(lift[i]), ramp_out[i])
        landing = (t >= land[i]) & (t < land[i] + ramp_in[i])
        pos[landing] += skid * (1.0 - env[landing])[:, None]
        gain = np.ones(n)
        if f.force_gain is not None:
            gain = f.force_gain[idx]
        base = trial.finger_force(f.finger) if f.force_n is None else f.force_n
        wobble = smooth_noise(rng, n, fs, (0.8, 6.0), person.force_wobble * wobble_scale)
        force = base * gain * env * np.clip(1.0 + wobble * steady, 0.3, None)
        contacts.append(fingertip_track(trial, f.finger, pos, force))
    performance = Performance(
        label=label,
        invalid_kind=invalid_kind,
        contacts=contacts,
        sample_rate_hz=fs,
        phases=Phases(0, motion_start / fs, (motion_end + 1) / fs, 0, 0, 0),
        params=dict(params or {}),
    )
    return with_phases_from_contacts(
        performance, rest_start_s=(motion_end + 1) / fs, lift_start_s=int(lift.min()) / fs
    )


def fingertip_track(trial: Trial, finger: str, pos: np.ndarray, force: np.ndarray) -> ContactTrack:
    """A fingertip contact: the patch grows with force and is elongated along the finger."""
    major, minor = trial.pad(finger).axes_mm(force)
    angle = np.radians(trial.hand_angle_deg - 90.0)
    return ContactTrack(pos[:, 0], pos[:, 1], force, major, minor, angle, "fingertip", finger)


def fold_into_box(path: np.ndarray, low: np.ndarray, high: np.ndarray) -> np.ndarray:
    """Mirror a path at the box walls (continuous, like a finger turning at the edge)."""
    span = np.maximum(high - low, 1e-9)
    shifted = np.mod(path - low, 2 * span)
    return low + span - np.abs(shifted - span)


def with_phases_from_contacts(
    performance: Performance,
    *,
    rest_start_s: float | None = None,
    lift_start_s: float | None = None,
) -> Performance:
    """Set landing / lift phases from the contact forces (first contact, last lift-off).

    Without ``lift_start_s`` the first finger's lift is taken as the last frame at which it
    still pressed with at least half its peak force.
    """
    fs = performance.sample_rate_hz
    firsts, last_firm, ends = [], [], []
    for c in performance.contacts:
        on = np.flatnonzero(c.touching)
        if on.size == 0:
            continue
        firsts.append(on[0])
        ends.append(on[-1] + 1)
        firm = np.flatnonzero(c.force_n >= 0.5 * c.force_n.max())
        last_firm.append(firm[-1] + 1)
    ph = performance.phases
    if firsts:
        ph.landing_s = float(min(firsts) / fs)
        ph.lift_end_s = float(max(ends) / fs)
        ph.lift_start_s = min(last_firm) / fs if lift_start_s is None else lift_start_s
        ph.lift_start_s = float(min(max(ph.lift_start_s, ph.landing_s), ph.lift_end_s))
    elif performance.bursts:
        b = performance.bursts[0]
        ph.landing_s, ph.lift_end_s = b.start_s, b.start_s + b.duration_s
        ph.lift_start_s = ph.lift_end_s
    ph.rest_start_s = float(ph.motion_end_s if rest_start_s is None else rest_start_s)
    ph.motion_start_s = float(max(ph.motion_start_s, ph.landing_s))
    ph.motion_end_s = float(ph.motion_end_s)
    return performance


def zero_force_off_skin(contact: ContactTrack, layout: SkinLayout) -> ContactTrack:
    """No force while the contact ellipse lies entirely outside the sensing area."""
    a = contact.semi_major_mm
    off = (
        (contact.x_mm < -a)
        | (contact.x_mm > layout.width_mm + a)
        | (contact.y_mm < -a)
        | (contact.y_mm > layout.height_mm + a)
    )
    if off.any():
        contact.force_n = np.where(off, 0.0, contact.force_n)
    return contact
