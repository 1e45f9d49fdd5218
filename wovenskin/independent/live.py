"""One drawn skin rendered frame block by frame block, as a live source renders it.

:func:`~.streams.render_stream` renders a whole stream at once; a skin under a simulated
operator's hand renders only the frames a session polls for, while the operator decides
when a held gesture lifts.  :class:`LiveRenderer` runs the same signal chain
(:class:`~.skins.SkinRenderer`: pressure, saturation, the fabric's lag, crosstalk, dead
channels, baseline, drift and noise) with the fabric's state and the clock carried from
one call to the next.  :func:`touch_frames` cuts a touch's fingers to a span of its frames
and :func:`held_fingers` holds them still as they are at one frame (a held gesture).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from wovenskin.independent.skins import Skin, SkinRenderer, pressure_signal
from wovenskin.independent.tracks import Finger, Touch
from wovenskin.skin.layout import SkinLayout


class LiveRenderer:
    """A drawn :class:`~.skins.Skin` rendered ``n`` frames a call, on its own frame clock.

    ``noise_seed`` is :class:`~.skins.SkinRenderer`'s: the same skin with its own noise."""

    def __init__(
        self, skin: Skin, layout: SkinLayout, fs: float, noise_seed: int | None = None
    ) -> None:
        self.renderer = SkinRenderer(skin, layout, fs, noise_seed=noise_seed)
        self.frame = 0  # the next frame's number (its time: frame / fs)
        self._state = np.zeros(layout.shape)

    @property
    def dead(self) -> list[int]:
        """The skin's dead channels (flat indices)."""
        return self.renderer.dead

    def render(self, fingers: list[Finger] | None, n: int) -> np.ndarray:
        """``(n, rows, cols)`` integer counts under ``fingers`` (tracks ``n`` frames long;
        ``None`` or none: nothing touches the skin)."""
        r = self.renderer
        if fingers:
            s = pressure_signal(fingers, r.layout, r.skin.gamma)
        else:
            s = np.zeros((n, *r.layout.shape))
        lagged, self._state = r.lag(r.saturated(s), self._state)
        t = (self.frame + np.arange(n, dtype=np.float64)) / r.fs
        self.frame += n
        return r.raw(r.couple(lagged), t)


def touch_frames(touch: Touch, start: int, stop: int) -> list[Finger]:
    """The fingers of ``touch`` over its frames ``start`` to ``stop`` (not included)."""
    return [
        replace(f, x=f.x[start:stop], y=f.y[start:stop], force=f.force[start:stop])
        for f in touch.fingers
    ]


def held_fingers(touch: Touch, frame: int, n: int) -> list[Finger]:
    """``n`` frames of the fingers of ``touch`` resting as they are at ``frame``."""
    i = min(max(int(frame), 0), touch.n_frames - 1)
    return [
        replace(f, x=np.full(n, f.x[i]), y=np.full(n, f.y[i]), force=np.full(n, f.force[i]))
        for f in touch.fingers
    ]
