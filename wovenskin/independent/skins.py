"""The skins of the independent generator: from fingertip patches to raw integer counts.

A :class:`Skin` is drawn once per stream; :class:`SkinRenderer` turns it into channels.
The signal chain of channel ``[r, c]`` (its own, not :mod:`wovenskin.sim`'s):

1. *Patch.*  A fingertip is an ellipse whose length (5-20 mm, growing with force as
   ``force ** 0.22``) and aspect come from the person; it is drawn as five isotropic
   Gaussian blobs along its long axis, each of sd half the semi-minor axis.  A blob's
   share of a channel is the product of two ``erf`` differences over the channel's
   rectangle (the pitches of :class:`~wovenskin.skin.layout.SkinLayout`), so coverage is
   exact for any pitch and no point grid is sampled.
2. *Pressure term* ``(force / area / 13 kPa) ** gamma`` (``gamma`` 0.35-0.8 per skin)
   times the covered share of the channel, summed over fingers: ``s``.
3. *Saturation* ``s / (1 + s / s_sat)`` (``s_sat`` 1-4): a firm fingertip covering a whole
   channel changes it by the skin's ``gain`` (3.5-35 % of its baseline: 10x across skins)
   times the channel's own factor (0.7-1.3: +-30 % across channels).
4. *Fabric:* an asymmetric first-order lag, faster pressing (4-20 ms) than releasing
   (8-40 ms).
5. *Crosstalk along rows only:* each channel picks up a share (0-3 %) of the change of
   every other channel of its row and a larger share (0-12 %) of its two row neighbours.
6. *Dead channels:* 0-3 channels keep 3 % of their response.
7. *Baseline:* 15 000-60 000 counts, +-3-15 % per channel, with slow drift (a common
   linear trend of up to +-0.4 % a minute, a common wave of up to 0.3 % over 40-240 s, and
   per-channel trends of 0.1 % a minute), white noise of 0.01-0.08 % of the baseline
   (per channel x0.5-2), rounded to integer counts.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from scipy.special import erf

from wovenskin.independent.people import log_uniform
from wovenskin.independent.tracks import Finger
from wovenskin.skin.layout import SkinLayout

PATCH_BLOBS = 5
GAIN_RANGE = (0.035, 0.35)
"""The range :meth:`Skin.draw` draws a skin's gain from (log-uniform)."""
TYPICAL_GAIN = float(np.sqrt(GAIN_RANGE[0] * GAIN_RANGE[1]))
"""A typical skin's gain: the geometric middle of :data:`GAIN_RANGE` (about 0.111)."""
WEAK_GAIN = TYPICAL_GAIN / 5.0
"""A weak skin's gain: about a fifth of a typical skin's change (issue 23)."""
REFERENCE_PRESSURE_N_MM2 = 0.013  # a firm 1.5 N press on a 12 mm fingertip (13 kPa)
TAIL_S = 0.3  # frames rendered past a touch's last contact (the fabric relaxing)


@dataclass(frozen=True)
class Skin:
    """One skin's parameters (ranges: the module doc and :meth:`draw`)."""

    baseline_counts: float
    baseline_spread: float
    gain: float
    channel_spread: float
    saturation: float
    gamma: float
    tau_press_s: float
    tau_release_s: float
    row_crosstalk: float
    neighbour_crosstalk: float
    dead_channels: int
    noise: float
    drift_per_min: float
    drift_wave: float
    drift_period_s: float
    channel_drift_per_min: float
    channel_seed: int

    @classmethod
    def draw(cls, rng: np.random.Generator) -> Skin:
        return cls(
            baseline_counts=float(rng.uniform(15000.0, 60000.0)),
            baseline_spread=float(rng.uniform(0.03, 0.15)),
            gain=log_uniform(rng, *GAIN_RANGE),
            channel_spread=0.3,
            saturation=float(rng.uniform(1.0, 4.0)),
            gamma=float(rng.uniform(0.35, 0.8)),
            tau_press_s=float(rng.uniform(0.004, 0.02)),
            tau_release_s=float(rng.uniform(0.008, 0.04)),
            row_crosstalk=float(rng.uniform(0.0, 0.03)),
            neighbour_crosstalk=float(rng.uniform(0.0, 0.12)),
            dead_channels=int(rng.integers(0, 4)),
            noise=log_uniform(rng, 0.0001, 0.0008),
            drift_per_min=float(rng.uniform(-0.004, 0.004)),
            drift_wave=float(rng.uniform(0.0, 0.003)),
            drift_period_s=float(rng.uniform(40.0, 240.0)),
            channel_drift_per_min=0.001,
            channel_seed=int(rng.integers(2**31)),
        )

    def to_dict(self) -> dict:
        return asdict(self)


def _axis_shares(centres: np.ndarray, sigma: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """``(..., len(edges) - 1)``: the share of a 1-D Gaussian inside each interval."""
    z = (edges - centres[..., None]) / (np.sqrt(2.0) * sigma[..., None])
    return 0.5 * np.diff(erf(z), axis=-1)


def pressure_signal(fingers: list[Finger], layout: SkinLayout, gamma: float) -> np.ndarray:
    """``(n, rows, cols)``: covered share of each channel times the pressure term, summed."""
    n = len(fingers[0].x)
    col_edges = np.arange(layout.cols + 1) * layout.col_pitch_mm
    row_edges = np.arange(layout.rows + 1) * layout.row_pitch_mm
    channel_area = layout.col_pitch_mm * layout.row_pitch_mm
    out = np.zeros((n, layout.rows, layout.cols))
    offsets = np.linspace(-1.0, 1.0, PATCH_BLOBS)
    for f in fingers:
        on = np.flatnonzero(f.force > 0)
        if not on.size:
            continue
        a = f.lengths_mm()[on] / 2.0
        b = a / f.aspect
        area = np.pi * a * b
        pressure = f.force[on] / area
        weight = (pressure / REFERENCE_PRESSURE_N_MM2) ** gamma * area / PATCH_BLOBS / channel_area
        angle = np.deg2rad(f.angle_deg)
        reach = (a - b)[:, None] * offsets[None, :]  # (m, K) blob offsets along the long axis
        bx = f.x[on, None] + reach * np.cos(angle)
        by = f.y[on, None] + reach * np.sin(angle)
        sigma = np.repeat((b / 2.0)[:, None], PATCH_BLOBS, axis=1)
        px = _axis_shares(bx, sigma, col_edges)  # (m, K, cols)
        py = _axis_shares(by, sigma, row_edges)  # (m, K, rows)
        out[on] += weight[:, None, None] * np.einsum("mkr,mkc->mrc", py, px)
    return out


class SkinRenderer:
    """A drawn :class:`Skin` on a layout: per-channel maps and the signal chain.

    ``noise_seed`` (default: from the skin's ``channel_seed``) seeds the white noise, so
    the same skin in several streams need not repeat its noise."""

    def __init__(
        self, skin: Skin, layout: SkinLayout, fs: float, noise_seed: int | None = None
    ) -> None:
        self.skin, self.layout, self.fs = skin, layout, fs
        rng = np.random.default_rng(skin.channel_seed)
        shape = layout.shape
        self.channel_gain = rng.uniform(1 - skin.channel_spread, 1 + skin.channel_spread, shape)
        dead = rng.choice(
            layout.channels, size=min(skin.dead_channels, layout.channels), replace=False
        )
        self.channel_gain.reshape(-1)[dead] *= 0.03
        self.dead = sorted(int(k) for k in dead)
        self.baseline = skin.baseline_counts * np.exp(rng.normal(0.0, skin.baseline_spread, shape))
        self.noise_sd = skin.noise * skin.baseline_counts * np.exp(rng.normal(0.0, 0.35, shape))
        self.channel_drift = rng.normal(0.0, skin.channel_drift_per_min, shape)
        self.wave_phase = float(rng.uniform(0.0, 2 * np.pi))
        self.noise_rng = np.random.default_rng(rng.integers(2**31))
        if noise_seed is not None:
            self.noise_rng = np.random.default_rng([int(noise_seed), skin.channel_seed])

    def response(self, fingers: list[Finger]) -> np.ndarray:
        """``(n + tail, rows, cols)`` relative change of every channel during one touch."""
        s = pressure_signal(fingers, self.layout, self.skin.gamma)
        s = np.concatenate([s, np.zeros((int(TAIL_S * self.fs), *s.shape[1:]))])
        lagged, _ = self.lag(self.saturated(s))
        return self.couple(lagged)

    def saturated(self, s: np.ndarray) -> np.ndarray:
        """The change each channel heads for under pressure signal ``s`` (steps 2-3)."""
        skin = self.skin
        return skin.gain * self.channel_gain * s / (1.0 + s / skin.saturation)

    def lag(
        self, target: np.ndarray, state: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """The fabric's lag (step 4) of ``target`` from ``state`` (default: at rest), and
        the state after its last frame (to go on from, frame block by frame block)."""
        skin = self.skin
        lagged = np.empty_like(target)
        up = 1.0 - np.exp(-1.0 / (skin.tau_press_s * self.fs))
        down = 1.0 - np.exp(-1.0 / (skin.tau_release_s * self.fs))
        state = np.zeros(target.shape[1:]) if state is None else state
        for i in range(len(target)):
            step = target[i] - state
            state = state + np.where(step > 0, up, down) * step
            lagged[i] = state
        return lagged, state

    def couple(self, lagged: np.ndarray) -> np.ndarray:
        """Crosstalk along rows and the dead channels (steps 5-6) of lagged changes."""
        skin = self.skin
        row_total = lagged.sum(axis=2, keepdims=True)
        neighbours = np.zeros_like(lagged)
        neighbours[:, :, 1:] += lagged[:, :, :-1]
        neighbours[:, :, :-1] += lagged[:, :, 1:]
        coupled = (
            lagged
            + skin.row_crosstalk * (row_total - lagged)
            + skin.neighbour_crosstalk * neighbours
        )
        coupled.reshape(len(coupled), -1)[:, self.dead] *= 0.03
        return coupled

    def raw(self, change: np.ndarray, t: np.ndarray) -> np.ndarray:
        """Integer counts ``(T, rows, cols)`` of baseline, drift, ``change`` and noise."""
        skin = self.skin
        minutes = t[:, None, None] / 60.0
        common = skin.drift_per_min * minutes + skin.drift_wave * np.sin(
            2 * np.pi * t[:, None, None] / skin.drift_period_s + self.wave_phase
        )
        base = self.baseline * (1.0 + common + self.channel_drift * minutes)
        noise = self.noise_rng.normal(0.0, 1.0, change.shape) * self.noise_sd
        return np.rint(base * (1.0 + change) + noise).astype(np.int32)
