"""Calibration: per-channel baseline, noise, dead channels and disturbed channels.

:func:`calibrate` looks at a contact-free period of raw frames (default 0.5 s) and
returns a :class:`Calibration`:

- ``baseline``: the mean reading of each channel (``C0``);
- ``step_noise``: the relative sd of each channel's frame-to-frame changes, which sets
  the glitch filter's threshold;
- ``noise``: the standard deviation of each channel's *conditioned* signal -- the
  relative change ``(C - C0) / C0`` after the glitch filters and the causal moving
  average: the larger of its direct (detrended) estimate and the one predicted from the
  frame-to-frame noise, floored so that a suspiciously quiet channel cannot get a
  near-zero contact threshold;
- ``dead``: channels that are flat, mostly NaN/inf, non-positive or at full scale;
- ``touched``: channels disturbed during calibration, found from the range of their
  smoothed relative signal compared with the other channels.  Their baseline is their
  level at the end of the period (whatever disturbed them may be over, or may stay: a
  finger still resting there is then part of the baseline until it lifts, and the
  tracker's fast recovery repairs that; a baseline taken too low would instead leave a
  phantom contact) and their noise is replaced by the typical noise.  A finger resting
  perfectly still through the whole period cannot be seen at all; recovery fixes that
  after lift-off too.

The frames pass through the same glitch filters as in conditioning first, so a
converter glitch (smeared into a pulse by a firmware average or not) neither counts as
a touch nor biases the baseline.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from wovenskin.errors import DataError
from wovenskin.io import to_jsonable
from wovenskin.signal.config import ConditioningConfig
from wovenskin.signal.filters import StepGlitchFilter, median_of_three

_MAX_LISTED_DEAD = 5


@dataclass
class Calibration:
    """Result of :func:`calibrate`; JSON-serialisable through :meth:`to_dict`."""

    baseline: np.ndarray  # (R, C) float64 C0 per channel; 0 where unknown (dead)
    noise: np.ndarray  # (R, C) float64 noise of the conditioned signal; 0 for dead channels
    dead: np.ndarray  # (R, C) bool
    touched: np.ndarray  # (R, C) bool: disturbed during calibration
    n_frames: int
    message: str  # one line
    step_noise: np.ndarray | None = None  # (R, C) relative sd of frame-to-frame changes

    def __post_init__(self) -> None:
        if self.step_noise is not None:
            self.step_noise = np.asarray(self.step_noise, dtype=np.float64)

    @property
    def shape(self) -> tuple[int, int]:
        return (int(self.baseline.shape[0]), int(self.baseline.shape[1]))

    @property
    def ok(self) -> bool:
        """True when nothing disturbed the calibration and some channel works."""
        return not bool(self.touched.any()) and bool((~self.dead).any())

    def to_dict(self) -> dict:
        d = {
            "baseline": self.baseline,
            "noise": self.noise,
            "dead": self.dead,
            "touched": self.touched,
            "n_frames": int(self.n_frames),
            "message": self.message,
        }
        if self.step_noise is not None:
            d["step_noise"] = self.step_noise
        return to_jsonable(d)

    @classmethod
    def from_dict(cls, d: dict) -> Calibration:
        """Inverse of :meth:`to_dict`; ``ValueError`` naming the problem on a bad dict."""
        try:
            baseline = np.asarray(d["baseline"], dtype=np.float64)
            noise = np.asarray(d["noise"], dtype=np.float64)
            dead = np.asarray(d["dead"], dtype=bool)
            touched = np.asarray(d["touched"], dtype=bool)
            n_frames = int(d["n_frames"])
            message = str(d.get("message", ""))
            step_noise = d.get("step_noise")
            if step_noise is not None:
                step_noise = np.asarray(step_noise, dtype=np.float64)
        except KeyError as exc:
            raise DataError(f"calibration record lacks key {exc.args[0]!r}") from None
        except (TypeError, ValueError) as exc:
            raise DataError(f"calibration record has a malformed field: {exc}") from None
        if baseline.ndim != 2 or baseline.size == 0:
            raise DataError(f"calibration baseline must be a 2-D grid, got {baseline.shape}")
        for name, arr in (
            ("noise", noise),
            ("dead", dead),
            ("touched", touched),
            ("step_noise", baseline if step_noise is None else step_noise),
        ):
            if arr.shape != baseline.shape:
                raise DataError(
                    f"calibration {name} has shape {arr.shape}, baseline has {baseline.shape}"
                )
        if not (np.isfinite(baseline).all() and np.isfinite(noise).all()):
            raise DataError("calibration baseline and noise must be finite")
        if step_noise is not None and not np.isfinite(step_noise).all():
            raise DataError("calibration step_noise must be finite")
        return cls(baseline, noise, dead, touched, n_frames, message, step_noise)


def calibrate(raw: np.ndarray, config: ConditioningConfig) -> Calibration:
    """Calibrate on contact-free raw frames ``(N, R, C)``; all ``N`` frames are used.

    Raises ``ValueError`` for a wrong shape or dtype, fewer than
    ``config.calibration_frames`` frames, or frames that are all NaN/inf.
    """
    raw = np.asarray(raw)
    if raw.ndim != 3 or raw.shape[1] < 1 or raw.shape[2] < 1:
        raise DataError(f"calibration needs frames shaped (N, rows, cols), got {raw.shape}")
    if not (np.issubdtype(raw.dtype, np.number) and not np.iscomplexobj(raw)):
        raise DataError(f"calibration needs real numeric frames, got dtype {raw.dtype}")
    n_frames = raw.shape[0]
    need = config.calibration_frames
    if n_frames < need:
        raise DataError(
            f"calibration needs at least {need} frames ({config.calibration_s:g} s at "
            f"{config.sample_rate_hz:g} Hz), got {n_frames}"
        )
    x = raw.astype(np.float64)
    finite = np.isfinite(x)
    if not finite.any():
        raise DataError("calibration frames are all NaN/inf: is the skin connected?")

    with warnings.catch_warnings(), np.errstate(invalid="ignore", divide="ignore"):
        warnings.simplefilter("ignore", RuntimeWarning)
        level = np.nanmedian(np.where(finite, x, np.nan), axis=0)
    nan_fraction = 1.0 - finite.mean(axis=0)
    usable_level = np.isfinite(level) & (level > 0)
    safe_level = np.where(usable_level, level, 1.0)
    filled = np.where(finite, x, safe_level)  # NaN samples read as the channel's median
    peak_to_peak = filled.max(axis=0) - filled.min(axis=0)
    dead = (
        ~usable_level
        | (nan_fraction > config.dead_nan_fraction)
        | (peak_to_peak < config.dead_flat_rel * safe_level)
    )
    if config.full_scale is not None:
        dead |= level >= config.full_scale
    live = ~dead

    step_noise = _step_noise(filled, safe_level, live)
    if config.glitch_filter:  # the same glitch removal as the conditioner
        glitches = StepGlitchFilter(
            glitch_threshold(step_noise, safe_level, live, config),
            safe_level,
            config.glitch_max_frames,
        )
        filled = glitches.apply(filled)
    if config.spike_filter:
        filled = np.concatenate(
            (filled[:2], median_of_three(filled[:-2], filled[1:-1], filled[2:]))
        )
    rel = np.where(live, (filled - safe_level) / safe_level, 0.0)
    smoothed = _moving_average_valid(rel, config.window_frames)
    spread = smoothed.max(axis=0) - smoothed.min(axis=0)
    noise = np.maximum(
        _detrended_std(smoothed),
        _white_noise_after_smoothing(rel, config.window_frames, config.spike_filter),
    )

    touched = np.zeros_like(dead)
    if live.any():
        typical_spread = float(np.quantile(spread[live], 0.25))
        limit = max(config.calib_disturb_ratio * typical_spread, config.calib_disturb_min_rel)
        touched = live & ((spread > limit) | (spread > config.calib_disturb_abs_rel))

    quiet = live & ~touched
    reference = quiet if quiet.any() else live
    typical_noise = float(np.median(noise[reference])) if reference.any() else 0.0
    floor = max(config.noise_floor_rel, config.noise_floor_fraction * typical_noise)
    noise = np.maximum(noise, floor)
    noise = np.where(touched, max(typical_noise, floor), noise)
    noise = np.where(dead, 0.0, noise)

    mean_level = filled.mean(axis=0)
    latest_level = safe_level * (1.0 + smoothed[-1])
    baseline = np.where(touched, latest_level, mean_level)
    baseline = np.where(dead, np.where(usable_level, level, 0.0), baseline)

    message = _describe(n_frames, baseline, noise, dead, touched, spread)
    return Calibration(
        baseline=baseline.astype(np.float64),
        noise=noise.astype(np.float64),
        dead=dead,
        touched=touched,
        n_frames=int(n_frames),
        message=message,
        step_noise=step_noise,
    )


def _step_noise(x: np.ndarray, level: np.ndarray, live: np.ndarray) -> np.ndarray:
    """Relative sd of frame-to-frame changes per channel (0 for dead channels).

    The rms of the changes without the largest 5 % (glitch edges): unlike a median-based
    spread it stays above zero on a quantised reading whose changes are mostly 0.
    """
    steps = np.abs(np.diff(x, axis=0))
    keep = max(1, int(0.95 * steps.shape[0]))
    kept = np.partition(steps, keep - 1, axis=0)[:keep]
    return np.where(live, np.sqrt(np.mean(kept * kept, axis=0)) / level, 0.0)


def glitch_threshold(
    step_noise: np.ndarray, level: np.ndarray, live: np.ndarray, config: ConditioningConfig
) -> np.ndarray:
    """Raw jump (same units as ``level``) above which a one-channel step may be a glitch.

    ``glitch_sigma`` frame-to-frame noise, and never below ``min_contact_rel`` of the
    level (a step too small to make a contact is not worth removing); dead channels
    never qualify.
    """
    relative = np.maximum(config.glitch_sigma * step_noise, config.min_contact_rel)
    return np.where(live, relative * level, np.inf)


def _moving_average_valid(x: np.ndarray, window: int) -> np.ndarray:
    """Trailing mean over ``window`` frames, only where the window is full."""
    cumulative = np.cumsum(x, axis=0)
    out = cumulative[window - 1 :].copy()
    out[1:] -= cumulative[:-window]
    return out / window


# Lag-1 and lag-2 autocorrelation of the median of three consecutive samples of white
# Gaussian noise (the spike filter's output); beyond lag 2 it is uncorrelated.
_MEDIAN3_RHO1 = 0.553
_MEDIAN3_RHO2 = 0.263


def _white_noise_after_smoothing(rel: np.ndarray, window: int, spike_filter: bool) -> np.ndarray:
    """Smoothed-signal noise predicted from the frame-to-frame (white) noise of ``rel``.

    Differences ``x[t] - x[t - window]`` cancel 50/60 Hz mains (the window holds whole
    periods) and slow drift, and a median-based spread ignores glitches, so this uses
    every calibration frame; the direct standard deviation of the smoothed signal rests
    on only a few independent windows and tends to come out low.
    """
    n = rel.shape[0]
    if n <= window + 2:
        return np.zeros(rel.shape[1:])
    lagged = rel[window:] - rel[:-window]
    spread = np.median(np.abs(lagged - np.median(lagged, axis=0)), axis=0)
    frame_sd = 1.4826 * spread / np.sqrt(2.0)
    rho1, rho2 = (_MEDIAN3_RHO1, _MEDIAN3_RHO2) if spike_filter else (0.0, 0.0)
    pairs = window + 2 * (window - 1) * rho1 + 2 * max(window - 2, 0) * rho2
    return frame_sd * np.sqrt(pairs) / window


def _detrended_std(x: np.ndarray) -> np.ndarray:
    """Per-channel standard deviation over axis 0 after removing a least-squares line."""
    n = x.shape[0]
    if n < 3:
        return x.std(axis=0)
    t = np.arange(n, dtype=np.float64) - (n - 1) / 2.0
    centred = x - x.mean(axis=0)
    slope = np.tensordot(t, centred, axes=(0, 0)) / float(t @ t)
    residual = centred - t[:, None, None] * slope
    return np.sqrt((residual**2).sum(axis=0) / (n - 2))


def _describe(
    n_frames: int,
    baseline: np.ndarray,
    noise: np.ndarray,
    dead: np.ndarray,
    touched: np.ndarray,
    spread: np.ndarray,
) -> str:
    parts: list[str] = []
    if touched.any():
        rows, cols = np.nonzero(touched)
        weights = spread[rows, cols]
        row = int(round(float(np.average(rows, weights=weights))))
        col = int(round(float(np.average(cols, weights=weights))))
        count = int(touched.sum())
        noun = "channel" if count == 1 else "channels"
        parts.append(
            f"touch detected on {count} {noun} near row {row}, col {col} during calibration"
        )
    if dead.all():
        parts.append("no working channel: every channel is dead (flat, NaN or non-positive)")
    elif dead.any():
        rows, cols = np.nonzero(dead)
        listed = ", ".join(
            f"({r},{c})" for r, c in list(zip(rows, cols, strict=True))[:_MAX_LISTED_DEAD]
        )
        more = f" and {len(rows) - _MAX_LISTED_DEAD} more" if len(rows) > _MAX_LISTED_DEAD else ""
        noun = "channel" if len(rows) == 1 else "channels"
        parts.append(f"{len(rows)} dead {noun} (row,col): {listed}{more}")
    if not parts:
        live = ~dead
        parts.append(
            f"calibration ok: {n_frames} frames, baseline {baseline[live].min():.4g}"
            f"..{baseline[live].max():.4g}, median noise {np.median(noise[live]):.3%}"
        )
    return "; ".join(parts)
