"""Capacitive physics of the woven skin: from contact ellipses to raw channel capacitances.

:class:`SkinModel` renders the contacts of :mod:`wovenskin.sim.contact` on a skin of
:class:`~wovenskin.sim.skin_physics.SkinPhysics` into raw frames ``(T, rows, cols)``
float32 in pF, ``[row, col]`` as in :mod:`wovenskin.skin.layout`, vectorised over time
and in consecutive chunks that share one continuous state (filters, drift, mains phase).

Signal chain of the channel at ``[r, c]``, frame ``n``:

1. *Pressure.*  Each contact is an ellipse (centre, semi-axes ``a >= b``, angle, force
   ``F``) with the Hertz-like profile ``p = p0 sqrt(1 - rho^2)``, ``p0 = 1.5 F / (pi a b)``,
   which integrates to ``F``.  Pressures of all contacts add.
2. *Local response* ``1 - exp(-p / pressure_scale_kpa)`` (saturating toward ~100 kPa),
   spread laterally by a Gaussian of sd ``field_spread_mm`` (fringe field and cover: on
   some skins a fingertip reaches 3-4 channels), weighted by the in-channel sensitivity
   (lower near the channel border) and averaged over ``S x S`` supersample points of the
   channel rectangle (``col_pitch x row_pitch``); the default ``S = 8`` keeps the sampling
   ripple of a sliding fingertip's total signal under 2 % (4 x 4 points give ~6 %).
3. *Fabric mechanics:* a fast first-order lag plus a slow viscoelastic creep component.
4. *Proximity:* a small fringe-field response around each contact, present before landing
   (the hand approaching: ``hover_tau_s``) and for a few milliseconds after lift-off
   (:data:`LIFT_HOVER_TAU_S`).
5. *Gain:* per-skin gain (pF at full coverage and saturation) times a per-channel gain.
6. *Crosstalk* along the electrode lines: a fraction of each channel's change appears on
   every other channel of its row and of its column.
7. Per-channel *baseline* with thermal *drift* (common mode and per channel,
   Ornstein-Uhlenbeck, smoothed by the thermal time constant :data:`DRIFT_SMOOTHING_S`:
   temperature changes slowly, so drift is smooth on the scale of seconds), *mains*
   pickup sampled at a per-channel scan-time offset (stronger where a hand touches: the
   body is an antenna), white *noise*, electrical noise *bursts* and rare one-frame
   single-channel *glitches* of the converter.
8. Optional firmware moving average (it turns a glitch into a rectangular pulse as long
   as its window) and ADC quantisation.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from scipy.signal import lfilter

from wovenskin.errors import ConfigError
from wovenskin.sim.contact import ContactTrack, NoiseBurst, hertz_pressure_kpa
from wovenskin.sim.skin_physics import SkinPhysics
from wovenskin.skin.layout import DEFAULT_SAMPLE_RATE_HZ, SkinLayout

DRIFT_SMOOTHING_S = 10.0
"""Thermal time constant of the skin (s): the drift processes pass through a first-order
low-pass of this time constant.  Temperature (and with it the drift) cannot change
faster than the fabric and the readout warm up or cool down, which takes seconds to
minutes; a raw Ornstein-Uhlenbeck process would instead wander like a random walk on
every time scale, i.e. add noise at the frame rate.  It barely changes the rms change
over a minute (``drift_*_per_min``) and makes the change over 0.1 s about 50x smaller."""


LIFT_HOVER_TAU_S = 0.005
"""Time constant (s) with which a lifted fingertip's fringe-field coupling fades.

A hand is sensed longer before it lands (``SkinPhysics.hover_tau_s``, 10-60 ms) than after
it lifts: a finger slows down as it approaches a surface, but a lifting finger accelerates
away from it, at 50-200 mm/s within a few milliseconds.  The coupling of a fingertip to a
woven electrode under its cover falls off within about a millimetre of height (it is a
small share of a press's change even at the surface: ``proximity_fraction``), which a
lifting fingertip leaves behind in about 5 ms; so its tail fades with this constant,
whatever the skin's approach constant.  The same fingertip hovering for tens of
milliseconds after a lift would keep a fraction of a contact's signal on the skin after
every release, which a capacitive skin does not show."""


def _presence(touching: np.ndarray, hover_frames: float, lift_frames: float) -> np.ndarray:
    """Presence (0..1) per frame of a contact ``touching`` in some frames: 1 in contact,
    ``exp(-d / hover_frames)`` ``d`` frames before its next contact (approaching) and
    ``exp(-d / lift_frames)`` ``d`` frames after its last one (lifted), the larger where
    both apply."""
    n = touching.shape[0]
    frames = np.arange(n, dtype=np.float64)
    last = np.maximum.accumulate(np.where(touching, frames, -np.inf))
    upcoming = np.minimum.accumulate(np.where(touching, frames, np.inf)[::-1])[::-1]
    with np.errstate(over="ignore", invalid="ignore"):
        after = np.exp(-(frames - last) / max(lift_frames, 1e-9))
        before = np.exp(-(upcoming - frames) / max(hover_frames, 1e-9))
    return np.maximum(np.nan_to_num(after), np.nan_to_num(before))


def _spread_matrix(
    channels: int, supersample: int, step_mm: float, sigma_mm: float, profile: np.ndarray
) -> np.ndarray:
    """``(channels, channels * supersample)``: Gaussian lateral spread of sd ``sigma_mm``
    along one axis of the supersampled image (zero beyond the skin's edge), then the
    channel's sensitivity ``profile`` and the mean over its ``supersample`` points.

    The 2-D spread is separable, so channel values are ``R @ image @ C.T``; with
    ``sigma_mm -> 0`` this tends to the plain weighted channel average."""
    n = channels * supersample
    offsets = np.arange(n)[:, None] - np.arange(n)[None, :]
    sigma = sigma_mm / step_mm
    reach = int(np.ceil(4 * sigma))
    kernel_sum = np.exp(-0.5 * (np.arange(-reach, reach + 1) / sigma) ** 2).sum()
    blur = np.exp(-0.5 * (offsets / sigma) ** 2) / kernel_sum  # (n, n): out point <- in point
    average = np.kron(np.eye(channels), profile[None, :] / supersample)  # (channels, n)
    return average @ blur


def _ou_sigma(rms_change_per_min: float, tau_s: float) -> float:
    """Stationary sd of an Ornstein-Uhlenbeck process with the given rms change over 60 s."""
    return rms_change_per_min / math.sqrt(2.0 * (1.0 - math.exp(-60.0 / tau_s)))


class SkinModel:
    """Renders contacts into raw frames of one simulated skin with a continuous state.

    The skin's static properties (per-channel baselines, gains, mains pickup, scan
    offsets) are drawn once from ``seed``; every call to :meth:`render` continues the
    previous one (filters, drift, mains phase, firmware average), so a long stream can be
    rendered chunk by chunk.  Rendering is deterministic for a seed and call sequence.
    """

    def __init__(
        self,
        physics: SkinPhysics | None = None,
        layout: SkinLayout | None = None,
        seed: int = 0,
        sample_rate_hz: float = DEFAULT_SAMPLE_RATE_HZ,
        supersample: int = 8,
    ) -> None:
        if sample_rate_hz <= 0:
            raise ConfigError(f"sample rate must be positive, got {sample_rate_hz}")
        if supersample < 1:
            raise ConfigError(f"supersample must be >= 1, got {supersample}")
        self.physics = physics if physics is not None else SkinPhysics()
        self.layout = layout if layout is not None else SkinLayout()
        self.sample_rate_hz = float(sample_rate_hz)
        self.supersample = int(supersample)
        phys, lay = self.physics, self.layout
        shape = lay.shape
        static = np.random.default_rng([int(seed) & 0xFFFFFFFF, 0x51C])
        self._rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, 0xD15])

        self.baseline_pf = phys.c0_pf * static.lognormal(0.0, phys.baseline_spread, shape)
        gain = phys.gain_pf * static.lognormal(0.0, phys.channel_gain_spread, shape)
        direction = static.uniform(0, 2 * np.pi)
        xx, yy = lay.channel_centers_mm()
        across = (xx - lay.width_mm / 2) * np.cos(direction)
        across += (yy - lay.height_mm / 2) * np.sin(direction)
        gain *= 1.0 + phys.gain_gradient * across / max(np.abs(across).max(), 1e-9)
        dead = static.random(shape) < phys.dead_channel_fraction
        self.channel_gain_pf = np.where(dead, 0.05 * gain, gain)
        self._noise_sd = phys.noise_pf * static.lognormal(0.0, 0.2, shape)
        self._mains_amp = phys.mains_pf * static.lognormal(0.0, phys.mains_spread, shape)
        scan_order = static.permutation(lay.channels).reshape(shape)
        self._scan_offset_s = scan_order / lay.channels * phys.scan_time_s
        self._mains_phase = static.uniform(0, 2 * np.pi)
        self._third_phase = static.uniform(0, 2 * np.pi)

        s = self.supersample
        self._dx = lay.col_pitch_mm / s
        self._dy = lay.row_pitch_mm / s
        self._px, self._py = lay.cols * s, lay.rows * s
        frac = (np.arange(s) + 0.5) / s - 0.5
        edge = phys.channel_edge_sensitivity
        profile = edge + (1.0 - edge) * np.cos(np.pi * frac) ** 2
        weight = np.outer(profile, profile)
        self._sub_weight = weight / weight.mean()  # (s, s): full coverage -> mean 1
        self._spread_rows = self._spread_cols = None
        if phys.field_spread_mm > 0:
            norm = profile / profile.mean()
            self._spread_rows = _spread_matrix(lay.rows, s, self._dy, phys.field_spread_mm, norm)
            self._spread_cols = _spread_matrix(lay.cols, s, self._dx, phys.field_spread_mm, norm)
        self._centers_x, self._centers_y = lay.channel_centers_mm()

        self.frames_rendered = 0
        channels = lay.channels
        self._lag_state = np.zeros((1, channels))
        self._creep_state = np.zeros((1, channels))
        self._drift_common_sigma = _ou_sigma(phys.drift_common_per_min, phys.drift_tau_s)
        self._drift_channel_sigma = _ou_sigma(phys.drift_channel_per_min, phys.drift_tau_s)
        self._drift_common = np.array([static.normal(0.0, self._drift_common_sigma)])
        self._drift_channel = static.normal(0.0, self._drift_channel_sigma, channels)
        self._smooth_common = self._drift_common.copy()  # the low-passed drift processes
        self._smooth_channel = self._drift_channel.copy()
        self._average_history: np.ndarray | None = None

    # -- public -----------------------------------------------------------------------
    @property
    def time_s(self) -> float:
        """Stream time of the next frame to render."""
        return self.frames_rendered / self.sample_rate_hz

    def render(
        self,
        contacts: Sequence[ContactTrack] = (),
        n_frames: int | None = None,
        bursts: Sequence[NoiseBurst] = (),
        offset: int = 0,
    ) -> np.ndarray:
        """Render frames ``offset .. offset + n_frames`` of ``contacts`` (and ``bursts``).

        Frame 0 of the tracks and of the bursts' ``start_s`` is the track start; rendering
        a long track in pieces (increasing ``offset``) gives the same result as rendering it
        at once.  Tracks shorter than the requested range hover with no force.  Returns
        ``(n_frames, rows, cols)`` float32 pF and advances the model's state.
        """
        contacts = list(contacts)
        for c in contacts:
            if not isinstance(c, ContactTrack):
                raise TypeError(f"contacts must be ContactTrack objects, got {type(c).__name__}")
        if n_frames is None:
            n_frames = max((c.n_frames for c in contacts), default=0) - offset
        if n_frames < 0 or offset < 0:
            raise ValueError(f"cannot render {n_frames} frames at offset {offset}")
        n = int(n_frames)
        rows, cols = self.layout.shape
        if n == 0:
            return np.zeros((0, rows, cols), dtype=np.float32)

        pressure = self.pressure_response(contacts, n, offset).reshape(n, -1)
        lagged = self._mechanics(pressure).reshape(n, rows, cols)
        proximity, body = self._proximity(contacts, n, offset)
        change = (lagged + proximity) * self.channel_gain_pf
        change = self._crosstalk(change)

        t = (self.frames_rendered + np.arange(n)) / self.sample_rate_hz
        resting = self._baseline_with_drift(n)
        frames = resting + change
        frames += self._mains(t, body)
        frames += self._noise_sd * self._rng.standard_normal((n, rows, cols))
        for burst in bursts:
            self._add_burst(frames, burst, offset)
        self._add_glitches(frames)
        frames = self._firmware_average(frames, resting[0])
        if self.physics.adc_lsb_pf > 0:
            frames = np.round(frames / self.physics.adc_lsb_pf) * self.physics.adc_lsb_pf
        self.frames_rendered += n
        return frames.astype(np.float32)

    def render_idle(self, n_frames: int) -> np.ndarray:
        """``n_frames`` without contact (baseline, drift and noise only)."""
        return self.render((), n_frames)

    def pressure_response(
        self, contacts: Sequence[ContactTrack], n_frames: int, offset: int = 0
    ) -> np.ndarray:
        """Stateless local response ``(n_frames, rows, cols)`` in [0, 1] before the lag.

        The channel-averaged, sensitivity-weighted ``1 - exp(-p / pressure_scale)``: 1 means
        the channel is fully covered at saturating pressure.
        """
        rows, cols = self.layout.shape
        out = np.zeros((n_frames, rows, cols))
        active = [c for c in contacts if c.touching[offset : offset + n_frames].any()]
        if not active:
            return out
        touching_any = np.zeros(n_frames, dtype=bool)
        for c in active:
            seg = c.touching[offset : offset + n_frames]
            touching_any[: seg.shape[0]] |= seg
        frame_idx = np.flatnonzero(touching_any)
        slot = np.full(n_frames, -1)
        slot[frame_idx] = np.arange(frame_idx.size)
        py, px = self._py, self._px
        image = np.zeros(frame_idx.size * py * px + 1)  # last element: sink for off-skin points
        for c in active:
            self._splat(c, offset, n_frames, slot, image)
        pressure = image[:-1].reshape(frame_idx.size, py, px)
        s = self.supersample
        local = -np.expm1(-pressure / self.physics.pressure_scale_kpa)
        if self._spread_rows is not None and self._spread_cols is not None:
            # Spread, in-channel weighting and channel averaging in one separable product.
            out[frame_idx] = self._spread_rows @ local @ self._spread_cols.T
            return out
        local = local.reshape(frame_idx.size, rows, s, cols, s) * self._sub_weight[:, None, :]
        out[frame_idx] = local.mean(axis=(2, 4))
        return out

    # -- internals --------------------------------------------------------------------
    def _splat(
        self, c: ContactTrack, offset: int, n: int, slot: np.ndarray, image: np.ndarray
    ) -> None:
        """Add one contact's pressure at the supersample points near it into ``image``."""
        local_frames = np.flatnonzero(c.touching[offset : offset + n])
        k = local_frames + offset
        cx, cy = c.x_mm[k], c.y_mm[k]
        a, b = c.semi_major_mm[k], c.semi_minor_mm[k]
        reach = float(a.max())
        hx = int(math.ceil(reach / self._dx)) + 1
        hy = int(math.ceil(reach / self._dy)) + 1
        px, py = self._px, self._py
        ix0 = np.clip(np.round(cx / self._dx - 0.5), -hx - 1, px + hx).astype(np.int64)
        iy0 = np.clip(np.round(cy / self._dy - 0.5), -hy - 1, py + hy).astype(np.int64)
        jx = ix0[:, None] + np.arange(-hx, hx + 1)  # (m, wx)
        jy = iy0[:, None] + np.arange(-hy, hy + 1)  # (m, wy)
        ddx = ((jx + 0.5) * self._dx - cx[:, None])[:, None, :]
        ddy = ((jy + 0.5) * self._dy - cy[:, None])[:, :, None]
        col = (slice(None), None, None)
        p = hertz_pressure_kpa(ddx, ddy, a[col], b[col], c.angle_rad[k][col], c.force_n[k][col])
        on_skin = ((jy >= 0) & (jy < py))[:, :, None] & ((jx >= 0) & (jx < px))[:, None, :]
        flat = (slot[local_frames][:, None, None] * py + jy[:, :, None]) * px + jx[:, None, :]
        flat = np.where(on_skin, flat, image.size - 1)
        # Within one contact every on-skin (frame, point) index is unique, so += is exact.
        image[flat] += p

    def _mechanics(self, response: np.ndarray) -> np.ndarray:
        """Fast lag plus slow creep of the fabric, continuing the previous chunk's state."""
        phys, dt = self.physics, 1.0 / self.sample_rate_hz
        alpha = math.exp(-dt / phys.mechanical_tau_s)
        fast, self._lag_state = lfilter(
            [1.0 - alpha], [1.0, -alpha], response, axis=0, zi=self._lag_state
        )
        if phys.creep_fraction <= 0:
            return fast
        beta = math.exp(-dt / phys.creep_tau_s)
        slow, self._creep_state = lfilter(
            [1.0 - beta], [1.0, -beta], fast, axis=0, zi=self._creep_state
        )
        return (1.0 - phys.creep_fraction) * fast + phys.creep_fraction * slow

    def _proximity(self, contacts: Sequence[ContactTrack], n: int, offset: int):
        """Fringe-field response (share of gain) and body coupling (0..1), both (n, R, C)."""
        rows, cols = self.layout.shape
        proximity = np.zeros((n, rows, cols))
        phys = self.physics
        hover_frames = phys.hover_tau_s * self.sample_rate_hz
        lift_frames = min(phys.hover_tau_s, LIFT_HOVER_TAU_S) * self.sample_rate_hz
        for c in contacts:
            if c.presence is not None:
                presence = c.presence[offset : offset + n]
            else:
                touching = c.touching
                if not touching.any():
                    continue
                presence = _presence(touching, hover_frames, lift_frames)[offset : offset + n]
            idx = np.flatnonzero(presence > 1e-3)
            if idx.size == 0:
                continue
            k = idx + offset
            a, b = c.semi_major_mm[k][:, None, None], c.semi_minor_mm[k][:, None, None]
            angle = c.angle_rad[k][:, None, None]
            dx = self._centers_x[None] - c.x_mm[k][:, None, None]
            dy = self._centers_y[None] - c.y_mm[k][:, None, None]
            u = dx * np.cos(angle) + dy * np.sin(angle)
            v = dy * np.cos(angle) - dx * np.sin(angle)
            sig2 = phys.proximity_sigma_mm**2
            blob = np.exp(-0.5 * (u * u / (a * a + sig2) + v * v / (b * b + sig2)))
            size = np.minimum(np.sqrt(a * b) / 5.0, 3.0)
            proximity[idx] += presence[idx][:, None, None] * blob * size
        body = np.minimum(proximity, 1.0)
        return phys.proximity_fraction * proximity, body

    def _crosstalk(self, change: np.ndarray) -> np.ndarray:
        kr, kc = self.physics.row_crosstalk, self.physics.col_crosstalk
        if kr == 0 and kc == 0:
            return change
        row_sum = change.sum(axis=2, keepdims=True)
        col_sum = change.sum(axis=1, keepdims=True)
        return change + kr * (row_sum - change) + kc * (col_sum - change)

    def _ou(self, state: np.ndarray, sigma: float, n: int) -> tuple[np.ndarray, np.ndarray]:
        """``n`` steps of an Ornstein-Uhlenbeck process per element of ``state``."""
        if sigma == 0:
            return np.broadcast_to(state, (n, state.size)), state
        rho = math.exp(-1.0 / (self.sample_rate_hz * self.physics.drift_tau_s))
        shocks = self._rng.standard_normal((n, state.size)) * sigma * math.sqrt(1 - rho * rho)
        path, zf = lfilter([1.0], [1.0, -rho], shocks, axis=0, zi=rho * state[None, :])
        return path, zf[0] / rho

    def _thermal_lowpass(self, path: np.ndarray, state: np.ndarray) -> np.ndarray:
        """``path`` ``(n, k)`` through the thermal low-pass, from its last output ``state``."""
        a = math.exp(-1.0 / (self.sample_rate_hz * DRIFT_SMOOTHING_S))
        return lfilter([1.0 - a], [1.0, -a], path, axis=0, zi=a * state[None, :])[0]

    def _baseline_with_drift(self, n: int) -> np.ndarray:
        rows, cols = self.layout.shape
        common, self._drift_common = self._ou(self._drift_common, self._drift_common_sigma, n)
        channel, self._drift_channel = self._ou(self._drift_channel, self._drift_channel_sigma, n)
        common = self._thermal_lowpass(common, self._smooth_common)
        channel = self._thermal_lowpass(channel, self._smooth_channel)
        self._smooth_common, self._smooth_channel = common[-1].copy(), channel[-1].copy()
        drift = common.reshape(n, 1, 1) + channel.reshape(n, rows, cols)
        return self.baseline_pf * (1.0 + drift)

    def _mains(self, t: np.ndarray, body: np.ndarray) -> np.ndarray:
        phys = self.physics
        amplitude = self._mains_amp + phys.body_mains_pf * body
        if not amplitude.any():
            return np.zeros_like(body)
        phase = 2 * np.pi * phys.mains_hz * (t[:, None, None] + self._scan_offset_s)
        phase = phase + self._mains_phase
        wave = np.sin(phase) + phys.mains_third_harmonic * np.sin(3 * phase + self._third_phase)
        return amplitude * wave

    def _add_burst(self, frames: np.ndarray, burst: NoiseBurst, offset: int) -> None:
        """Add an interference burst over a random share of rows and columns."""
        n, rows, cols = frames.shape
        fs = self.sample_rate_hz
        start = int(round(burst.start_s * fs)) - offset
        length = max(1, int(round(burst.duration_s * fs)))
        lo, hi = max(start, 0), min(start + length, n)
        rng = self._rng
        row_lines = rng.random(rows) < burst.line_fraction
        col_lines = rng.random(cols) < burst.line_fraction
        if not row_lines.any() and not col_lines.any():
            row_lines[rng.integers(rows)] = True
        if hi <= lo:
            return
        k = np.arange(lo, hi) - start
        taper = max(2, int(round(0.015 * fs)))
        envelope = np.minimum(1.0, np.minimum(k + 1, length - k) / taper)
        envelope = 0.5 - 0.5 * np.cos(np.pi * envelope)
        tt = k[:, None] / fs

        def line_waves(count: int) -> np.ndarray:
            freq = burst.frequency_hz * rng.uniform(0.95, 1.05, count)
            phase = rng.uniform(0, 2 * np.pi, count)
            coupling = rng.lognormal(0.0, 0.4, count)
            tone = np.sin(2 * np.pi * freq * tt + phase)
            return coupling * (tone + 0.6 * rng.standard_normal((k.size, count)))

        amp = self.physics.burst_pf * burst.strength * envelope[:, None, None]
        row_part = (line_waves(rows) * row_lines)[:, :, None]
        col_part = (line_waves(cols) * col_lines)[:, None, :]
        frames[lo:hi] += amp * (row_part + col_part)

    def _add_glitches(self, frames: np.ndarray) -> None:
        n, rows, cols = frames.shape
        count = self._rng.poisson(self.physics.glitch_rate_hz * n / self.sample_rate_hz)
        for _ in range(count):
            t, r, c = self._rng.integers(n), self._rng.integers(rows), self._rng.integers(cols)
            sign = 1.0 if self._rng.random() < 0.5 else -1.0
            frames[t, r, c] += sign * self.physics.glitch_pf * self._rng.lognormal(0.0, 0.5)

    def _firmware_average(self, frames: np.ndarray, resting: np.ndarray) -> np.ndarray:
        """The firmware's moving average.  Before the first frame it has been averaging the
        skin at rest, as a device that was running before the host connected has:
        ``resting`` (the first frame's level) with its mains pickup, without noise."""
        window = int(round(self.physics.firmware_average_s * self.sample_rate_hz))
        if window < 2:
            return frames
        if self._average_history is None:
            before = (
                self.frames_rendered - window + 1 + np.arange(window - 1)
            ) / self.sample_rate_hz
            rows, cols = self.layout.shape
            mains = self._mains(before, np.zeros((window - 1, rows, cols)))
            self._average_history = resting[None] + mains
        joined = np.concatenate([self._average_history, frames], axis=0)
        csum = np.cumsum(joined, axis=0)
        csum = np.concatenate([np.zeros((1, *frames.shape[1:])), csum], axis=0)
        averaged = (csum[window:] - csum[:-window]) / window
        self._average_history = joined[-(window - 1) :]
        return averaged
