"""The contacts a simulated skin feels: elliptical contact tracks and interference bursts.

A :class:`ContactTrack` is one elliptical contact over time (fingertip, palm, forearm,
sleeve) with the Hertz-like pressure profile of :func:`hertz_pressure_kpa`; a
:class:`NoiseBurst` is electrical interference over many electrode lines.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

CONTACT_KINDS = ("fingertip", "finger", "palm", "forearm", "sleeve", "hand_back")


@dataclass
class ContactTrack:
    """One elliptical contact over time, one value per frame at the sample rate.

    ``x_mm``/``y_mm`` place the centre (x right, y down from the top-left corner of the
    sensing area); ``force_n`` is the normal force (0 = not touching: the position is then
    where the hand hovers); ``semi_major_mm``/``semi_minor_mm`` are the semi-axes of the
    contact ellipse and ``angle_rad`` the direction of its major axis, measured from +x
    toward +y.  Shape arguments may be scalars; they are broadcast to the track length.
    ``presence`` (0..1 per frame, optional) is how near the finger is for the fringe field:
    by default it is derived from the force (1 in contact, decaying with the hover time
    constant before landing and after lift-off, within the track); a track rendered piece
    by piece as it happens (the dashboard's fingertips) gives its own.
    """

    x_mm: np.ndarray
    y_mm: np.ndarray
    force_n: np.ndarray
    semi_major_mm: np.ndarray | float
    semi_minor_mm: np.ndarray | float
    angle_rad: np.ndarray | float = 0.0
    kind: str = "fingertip"
    finger: str = ""
    presence: np.ndarray | None = None

    def __post_init__(self) -> None:
        force = np.asarray(self.force_n, dtype=np.float64)
        if force.ndim != 1:
            raise ValueError(f"contact force must be a 1-D array, got shape {force.shape}")
        n = force.shape[0]
        self.force_n = force
        for name in ("x_mm", "y_mm", "semi_major_mm", "semi_minor_mm", "angle_rad"):
            value = np.asarray(getattr(self, name), dtype=np.float64)
            if value.ndim == 0:
                value = np.full(n, float(value))
            if value.shape != (n,):
                raise ValueError(f"contact {name} has shape {value.shape}, expected ({n},)")
            setattr(self, name, value)
        arrays = (self.x_mm, self.y_mm, force, self.semi_major_mm, self.semi_minor_mm)
        if not all(np.isfinite(a).all() for a in (*arrays, self.angle_rad)):
            raise ValueError("contact track contains NaN or infinite values")
        if (force < 0).any():
            raise ValueError("contact force must be >= 0")
        if (self.semi_minor_mm <= 0).any() or (self.semi_major_mm < self.semi_minor_mm).any():
            raise ValueError("contact semi-axes must satisfy 0 < semi_minor <= semi_major")
        if self.kind not in CONTACT_KINDS:
            raise ValueError(f"unknown contact kind {self.kind!r}; known: {CONTACT_KINDS}")
        if self.presence is not None:
            presence = np.asarray(self.presence, dtype=np.float64)
            if presence.shape != (n,) or not np.isfinite(presence).all():
                raise ValueError(f"contact presence must be ({n},) finite values")
            if (presence < 0).any() or (presence > 1).any():
                raise ValueError("contact presence must lie in [0, 1]")
            self.presence = presence

    @property
    def n_frames(self) -> int:
        return int(self.force_n.shape[0])

    @property
    def touching(self) -> np.ndarray:
        """Boolean mask of the frames in contact."""
        return self.force_n > 0

    def padded(self, before: int, after: int) -> ContactTrack:
        """The same contact with ``before``/``after`` extra frames of hovering (no force)."""

        def pad(a: np.ndarray, zero: bool = False) -> np.ndarray:
            if zero:
                return np.pad(a, (before, after))
            return np.pad(a, (before, after), mode="edge")

        return ContactTrack(
            pad(self.x_mm),
            pad(self.y_mm),
            pad(self.force_n, zero=True),
            pad(self.semi_major_mm),
            pad(self.semi_minor_mm),
            pad(self.angle_rad),
            self.kind,
            self.finger,
            None if self.presence is None else pad(self.presence, zero=True),
        )


@dataclass(frozen=True)
class NoiseBurst:
    """Electrical interference over many electrode lines for a short time.

    ``start_s`` is relative to frame 0 of the tracks it is rendered with; ``strength``
    scales the skin's own :attr:`SkinPhysics.burst_pf`; ``line_fraction`` is the share of
    rows and of columns that pick it up; ``frequency_hz`` the (aliased) interference tone.
    """

    start_s: float
    duration_s: float
    strength: float = 1.0
    line_fraction: float = 0.6
    frequency_hz: float = 30.0

    def to_dict(self) -> dict[str, float]:
        return asdict(self)


def hertz_pressure_kpa(
    dx: np.ndarray, dy: np.ndarray, a: np.ndarray, b: np.ndarray, angle: np.ndarray, force
):
    """Pressure (kPa) of an elliptical Hertz-like contact at offsets ``dx, dy`` (mm).

    ``a, b, angle, force`` broadcast against ``dx, dy``; the profile integrates to ``force``.
    """
    cos, sin = np.cos(angle), np.sin(angle)
    u = (dx * cos + dy * sin) / a
    v = (dy * cos - dx * sin) / b
    inside = np.maximum(1.0 - u * u - v * v, 0.0)
    p0_kpa = 1.5e3 * force / (np.pi * a * b)  # N/mm^2 = MPa -> kPa
    return p0_kpa * np.sqrt(inside)
