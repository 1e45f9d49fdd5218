"""What the simulated skin controller (:mod:`wovenskin.sim.pty_skin`) sends: its frames'
signal, the record of each frame sent, the sample scales it declares and its boot banner."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from wovenskin.skin.layout import SkinLayout
from wovenskin.skin.messages import SampleDtype

FrameFn = Callable[[int, float], np.ndarray]
"""``fn(frame_index, device_time_s) -> (rows, cols)`` values in ``[row, col]`` order."""

DEFAULT_SCALES = {SampleDtype.F32: 1.0, SampleDtype.U16: 1e-3, SampleDtype.U32: 1e-6}
"""Units per count the fake device declares for each sample type (pF)."""

BOOT_BANNER = (
    b"ESP-ROM:esp32s3-20210327\r\nBuild:Mar 27 2021\r\n"
    b"rst:0x1 (POWERON),boot:0x8 (SPI_FAST_FLASH_BOOT)\r\nentry 0x403c98d0\r\n"
)
"""What an ESP32-S3's ROM prints at boot, before the firmware's first delimiter."""


@dataclass(frozen=True)
class SentFrame:
    """A frame the device sent, as the host should decode it (``[row, col]``, float32)."""

    boot: int
    seq: int
    device_t_us: int
    values: np.ndarray


class BaselineFrames:
    """The default signal: a per-channel baseline near 20 pF (+-15 %) plus small noise."""

    def __init__(self, layout: SkinLayout, seed: int = 0, noise_pf: float = 0.02) -> None:
        rng = np.random.default_rng(seed)
        self.baseline = 20.0 * (1.0 + 0.15 * rng.standard_normal(layout.shape)).clip(0.5, 1.5)
        self.noise_pf = noise_pf
        self._rng = np.random.default_rng(seed + 1)

    def __call__(self, index: int, t_s: float) -> np.ndarray:
        noise = self.noise_pf * self._rng.standard_normal(self.baseline.shape)
        return (self.baseline + noise).astype(np.float32)
