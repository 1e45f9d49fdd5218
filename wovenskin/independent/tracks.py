"""Fingertip tracks of the independent generator: where each fingertip is and how hard it
presses, frame by frame, and the phases of one touch.

A :class:`Finger` holds per-frame position (mm, ``x`` right and ``y`` down from the
top-left corner of the sensing area, as in :mod:`wovenskin.skin.layout`) and force (N, 0
off the skin) plus its patch shape; a :class:`Touch` is the fingers of one gesture or
invalid touch on a common clock with its :class:`Phases` and drawn parameters.  The
helpers build strokes from a minimum-jerk profile (:func:`min_jerk`), raised-cosine
landing and lift ramps (:func:`envelope`), a slow wander (:func:`wander`), and place a
touch on the skin (:func:`fit_to_skin`).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np
from scipy.signal import lfilter

from wovenskin.skin.layout import SkinLayout

EDGE_MARGIN_MM = 4.0
"""Fingertip centres stay at least this far inside the sensing area."""


def min_jerk(tau: np.ndarray) -> np.ndarray:
    """The minimum-jerk position profile 0 -> 1 over ``tau`` in [0, 1] (clipped outside)."""
    tau = np.clip(tau, 0.0, 1.0)
    return tau**3 * (10.0 - 15.0 * tau + 6.0 * tau**2)


def raised_cosine(tau: np.ndarray) -> np.ndarray:
    """0 -> 1 over ``tau`` in [0, 1] with zero slope at both ends (clipped outside)."""
    return 0.5 - 0.5 * np.cos(np.pi * np.clip(tau, 0.0, 1.0))


def envelope(t: np.ndarray, land_s: float, in_s: float, lift_s: float, out_s: float) -> np.ndarray:
    """A force envelope: 0 before ``land_s``, rising over ``in_s``, 1 until ``lift_s``,
    falling to 0 over ``out_s`` (each ramp a raised cosine)."""
    rise = raised_cosine((t - land_s) / max(in_s, 1e-6))
    fall = 1.0 - raised_cosine((t - lift_s) / max(out_s, 1e-6))
    return np.where(t < land_s, 0.0, rise * np.where(t < lift_s, 1.0, fall))


def wander(rng: np.random.Generator, n: int, sd_mm: float, fs: float, tau_s: float = 0.4):
    """``(n, 2)`` slow random displacement of sd about ``sd_mm`` (a hand holding still):
    white noise through a first-order low-pass of time constant ``tau_s``."""
    alpha = 1.0 / max(1.0, tau_s * fs)
    steps = rng.normal(0.0, np.sqrt(2.0 / alpha) * alpha, size=(n, 2))
    return sd_mm * lfilter([1.0], [1.0, alpha - 1.0], steps, axis=0)


@dataclass
class Finger:
    """One fingertip over the touch's frames."""

    x: np.ndarray  # (n,) mm
    y: np.ndarray  # (n,) mm
    force: np.ndarray  # (n,) N, 0 while off the skin
    length_mm: float  # patch length at ``ref_force_n``
    aspect: float  # length / width
    angle_deg: float  # direction of the patch's long axis (0: along +x)
    ref_force_n: float  # the force at which the patch is ``length_mm`` long
    growth: float = 0.22  # length grows as (force / ref) ** growth
    min_mm: float = 5.0  # a fingertip patch is 5-20 mm long
    max_mm: float = 20.0

    def lengths_mm(self) -> np.ndarray:
        """Patch length per frame (grows with force, within ``[min_mm, max_mm]``)."""
        ratio = np.maximum(self.force, 1e-9) / self.ref_force_n
        return np.clip(self.length_mm * ratio**self.growth, self.min_mm, self.max_mm)

    def contact(self) -> np.ndarray:
        return self.force > 0


@dataclass
class Phases:
    """Times of one touch in seconds from its frame 0 (``None``: not part of this touch)."""

    landing_s: float  # first contact of any finger
    motion_start_s: float | None  # the characteristic motion (a push: its press) begins
    motion_end_s: float | None
    lift_start_s: float  # the first finger starts to lift
    lift_end_s: float  # the last finger has left the skin

    def shifted(self, seconds: float) -> Phases:
        return Phases(**{k: (None if v is None else v + seconds) for k, v in asdict(self).items()})

    def to_dict(self) -> dict[str, float | None]:
        return asdict(self)


@dataclass
class Touch:
    """One gesture or invalid touch: its fingers on a common clock, its phases and label."""

    label: str
    kind: str  # "flick", "held_swipe", "push_smooth", "palm", ...
    fingers: list[Finger]
    fs: float
    phases: Phases
    params: dict = field(default_factory=dict)

    @property
    def n_frames(self) -> int:
        return len(self.fingers[0].x) if self.fingers else 0

    def contact_span(self) -> tuple[int, int]:
        """First frame with any contact and one past the last (the labelled event)."""
        any_contact = np.zeros(self.n_frames, dtype=bool)
        for f in self.fingers:
            any_contact |= f.contact()
        idx = np.flatnonzero(any_contact)
        return int(idx[0]), int(idx[-1]) + 1

    def settle_phases(self) -> None:
        """Set landing and last lift-off from the forces actually rendered."""
        first, end = self.contact_span()
        self.phases.landing_s = first / self.fs
        self.phases.lift_end_s = end / self.fs
        if self.phases.motion_start_s is not None:  # a press that starts with the contact
            self.phases.motion_start_s = max(self.phases.motion_start_s, self.phases.landing_s)


def frame_times(duration_s: float, fs: float) -> np.ndarray:
    """The frame times of a touch lasting ``duration_s`` (plus one frame)."""
    return np.arange(int(np.ceil(duration_s * fs)) + 1) / fs


def fit_to_skin(fingers: list[Finger], layout: SkinLayout, rng: np.random.Generator) -> float:
    """Place fingers drawn around the origin on the skin: shrink the touch about its centre
    if it is larger than the sensing area (minus :data:`EDGE_MARGIN_MM`), then shift it to a
    random place where it fits.  Returns the shrink factor (1.0: none)."""
    on = [f.contact() for f in fingers]
    xs = np.concatenate([f.x[m] for f, m in zip(fingers, on, strict=True)])
    ys = np.concatenate([f.y[m] for f, m in zip(fingers, on, strict=True)])
    x0, x1, y0, y1 = xs.min(), xs.max(), ys.min(), ys.max()
    room_x = layout.width_mm - 2 * EDGE_MARGIN_MM
    room_y = layout.height_mm - 2 * EDGE_MARGIN_MM
    scale = min(1.0, room_x / max(x1 - x0, 1e-9), room_y / max(y1 - y0, 1e-9))
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    half_x, half_y = scale * (x1 - x0) / 2, scale * (y1 - y0) / 2
    low_x, low_y = EDGE_MARGIN_MM + half_x, EDGE_MARGIN_MM + half_y
    px = rng.uniform(low_x, max(low_x, layout.width_mm - EDGE_MARGIN_MM - half_x))
    py = rng.uniform(low_y, max(low_y, layout.height_mm - EDGE_MARGIN_MM - half_y))
    for f in fingers:
        f.x = px + scale * (f.x - cx)
        f.y = py + scale * (f.y - cy)
    return float(scale)
