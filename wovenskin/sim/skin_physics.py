"""Every physical parameter of a simulated skin, with its meaning and its plausible range.

:class:`SkinPhysics` is one skin (the default a typical one); :meth:`SkinPhysics.sample`
draws a random skin within the documented ranges, which :mod:`wovenskin.sim.physics`
renders into raw frames.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields, replace

import numpy as np

from wovenskin.errors import ConfigError
from wovenskin.settings import from_dict


def _param(default: float, low: float, high: float, unit: str, doc: str, log: bool = False):
    """A physics parameter with its range (used by :meth:`SkinPhysics.sample`) and meaning."""
    return field(
        default=default, metadata={"range": (low, high), "unit": unit, "doc": doc, "log": log}
    )


@dataclass(frozen=True)
class SkinPhysics:
    """All physical parameters of one simulated skin, with the default being a typical skin.

    Each field's metadata holds ``range`` (what :meth:`sample` draws from), ``unit`` and
    ``doc``; :meth:`describe` prints them as a table.
    """

    # -- baseline and gain ---------------------------------------------------------------
    c0_pf: float = _param(
        20.0, 10.0, 30.0, "pF", "nominal no-contact channel capacitance (a 10 x 14 mm channel)"
    )
    baseline_spread: float = _param(
        0.15, 0.05, 0.30, "1", "relative sd of per-channel baselines around c0 (lognormal)"
    )
    gain_pf: float = _param(
        4.0,
        0.4,
        60.0,
        "pF",
        "change of a fully covered channel at saturating pressure, 1 % to several times c0: "
        "skins differ 10x and more (weave, cover, insulation, mounting): a firm (1.5 N) "
        "fingertip press changes a channel by 6 % on the default skin, by under 1 % on the "
        "dullest and by 100 % and more on the most sensitive",
        log=True,
    )
    channel_gain_spread: float = _param(
        0.15, 0.05, 0.30, "1", "relative sd of per-channel gain (lognormal)"
    )
    gain_gradient: float = _param(
        0.0, 0.0, 0.3, "1", "linear gain change across the skin (uneven tension of the wrap)"
    )
    dead_channel_fraction: float = _param(
        0.0, 0.0, 0.03, "1", "share of channels that barely respond (a broken thread)"
    )
    channel_edge_sensitivity: float = _param(
        0.75, 0.5, 1.0, "1", "sensitivity at a channel's border relative to its centre"
    )
    field_spread_mm: float = _param(
        0.0,
        0.0,
        7.0,
        "mm",
        "sd of the lateral spread of a contact's effect (fringe field, a thick cover "
        "spreading the pressure): 0 keeps a fingertip on 1-2 channels, 7 spreads it over 3-4",
    )
    pressure_scale_kpa: float = _param(
        30.0, 18.0, 45.0, "kPa", "local response is 1 - exp(-p / scale); ~100 kPa saturates"
    )
    # -- fabric mechanics ----------------------------------------------------------------
    mechanical_tau_s: float = _param(
        0.02, 0.01, 0.03, "s", "first-order lag of the fabric's compression"
    )
    creep_fraction: float = _param(
        0.05, 0.0, 0.12, "1", "share of the response that follows slow viscoelastic creep"
    )
    creep_tau_s: float = _param(0.5, 0.2, 1.0, "s", "time constant of the creep")
    # -- fringe field --------------------------------------------------------------------
    proximity_fraction: float = _param(
        0.03,
        -0.015,
        0.06,
        "1",
        "fringe-field response at a contact's centre, share of gain (< 0: the grounded hand "
        "shunts the field of a mutual-capacitance readout)",
    )
    proximity_sigma_mm: float = _param(
        6.0, 3.0, 10.0, "mm", "reach of the fringe field beyond a contact's edge"
    )
    hover_tau_s: float = _param(
        0.03, 0.01, 0.06, "s", "how early before landing / late after lift the hand is sensed"
    )
    # -- crosstalk -----------------------------------------------------------------------
    row_crosstalk: float = _param(
        0.02, 0.0, 0.05, "1", "share of a channel's change leaking into every channel of its row"
    )
    col_crosstalk: float = _param(
        0.02, 0.0, 0.05, "1", "share of a channel's change leaking into every channel of its col"
    )
    # -- noise ---------------------------------------------------------------------------
    noise_pf: float = _param(0.01, 0.003, 0.03, "pF", "white noise sd per channel", log=True)
    mains_hz: float = _param(50.0, 49.8, 60.2, "Hz", "mains frequency (50 or 60, +-0.2)")
    mains_pf: float = _param(0.01, 0.0, 0.04, "pF", "mains pickup amplitude of a channel")
    mains_spread: float = _param(
        0.5, 0.2, 0.8, "1", "relative sd of the per-channel mains pickup amplitude"
    )
    mains_third_harmonic: float = _param(
        0.2, 0.0, 0.5, "1", "third-harmonic amplitude relative to the fundamental"
    )
    body_mains_pf: float = _param(
        0.03, 0.0, 0.1, "pF", "extra mains pickup on channels under/near a touching hand"
    )
    scan_time_s: float = _param(
        0.001, 0.0005, 0.001, "s", "one scan of all channels; offsets the sampling time"
    )
    drift_common_per_min: float = _param(
        0.004, 0.001, 0.01, "1", "rms change of the common thermal drift in 1 min, share of C"
    )
    drift_channel_per_min: float = _param(
        0.001, 0.0003, 0.004, "1", "rms change of per-channel drift in 1 min, share of C"
    )
    drift_tau_s: float = _param(300.0, 120.0, 900.0, "s", "correlation time of the drift")
    glitch_rate_hz: float = _param(
        0.05, 0.0, 0.3, "1/s", "one-frame single-channel spikes per second (whole skin)"
    )
    glitch_pf: float = _param(2.0, 0.5, 5.0, "pF", "typical magnitude of a glitch")
    burst_pf: float = _param(
        0.5, 0.15, 2.0, "pF", "typical amplitude of an electrical noise burst", log=True
    )
    # -- readout -------------------------------------------------------------------------
    firmware_average_s: float = _param(
        0.0, 0.0, 0.1, "s", "firmware moving-average window (0 = raw; often 0)"
    )
    adc_lsb_pf: float = _param(0.0, 0.0, 0.005, "pF", "ADC quantisation step (0 = none)")

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if not math.isfinite(value) or (value < 0 and f.metadata["range"][0] >= 0):
                raise ConfigError(f"skin physics {f.name} must be finite and >= 0, got {value}")
        for name in ("c0_pf", "gain_pf", "pressure_scale_kpa", "mechanical_tau_s", "mains_hz"):
            if getattr(self, name) <= 0:
                raise ConfigError(f"skin physics {name} must be > 0")

    @classmethod
    def sample(cls, rng: np.random.Generator) -> SkinPhysics:
        """A random skin: every parameter drawn within its documented range."""
        values: dict[str, float] = {}
        for f in fields(cls):
            low, high = f.metadata["range"]
            if f.metadata["log"]:
                values[f.name] = float(np.exp(rng.uniform(np.log(low), np.log(high))))
            else:
                values[f.name] = float(rng.uniform(low, high))
        values["mains_hz"] = float(rng.choice([50.0, 60.0]) + rng.uniform(-0.2, 0.2))
        # Most readouts stream raw values, some average in firmware, some quantise coarsely.
        if rng.random() < 0.6:
            values["firmware_average_s"] = 0.0
        if rng.random() < 0.5:
            values["adc_lsb_pf"] = 0.0
        if rng.random() < 0.6:
            values["dead_channel_fraction"] = 0.0
        return cls(**values)

    @classmethod
    def sample_typical(cls, rng: np.random.Generator) -> SkinPhysics:
        """A random skin of typical response: :meth:`sample` with the gain kept within
        :data:`TYPICAL_GAIN_PF` (a firm press changes a channel by about 2-12 %).

        The full range trains and tests recognisers; a demonstration skin (the
        dashboard's, ``wovenskin run``'s) and the contact-detection benchmark use this one.
        """
        physics = cls.sample(rng)
        return replace(physics, gain_pf=float(np.clip(physics.gain_pf, *TYPICAL_GAIN_PF)))

    def without_noise(self) -> SkinPhysics:
        """The same skin with every random disturbance off (noise, mains, drift, glitches)."""
        return replace(
            self,
            noise_pf=0.0,
            mains_pf=0.0,
            body_mains_pf=0.0,
            drift_common_per_min=0.0,
            drift_channel_per_min=0.0,
            glitch_rate_hz=0.0,
            adc_lsb_pf=0.0,
        )

    def to_dict(self) -> dict[str, float]:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> SkinPhysics:
        """The skin :meth:`to_dict` wrote; one :class:`ConfigError` line naming a bad key."""
        return from_dict(cls, d, "skin physics")

    @classmethod
    def describe(cls) -> str:
        """A plain-text table of every parameter: name, default, range, unit and meaning."""
        lines = []
        for f in fields(cls):
            low, high = f.metadata["range"]
            lines.append(
                f"{f.name:24s} {f.default:<8g} [{low:g}, {high:g}] {f.metadata['unit']:4s} "
                f"{f.metadata['doc']}"
            )
        return "\n".join(lines)


TYPICAL_GAIN_PF = (1.5, 8.0)
"""Gain range (pF) of a skin of typical response (:meth:`SkinPhysics.sample_typical`)."""
