"""A simulated operator's skin whose hand and skin are strangers to the model.

:class:`IndependentSkin` is a :class:`~.touch_skin.TouchSkin` (rendered when the session
polls it, ``block`` frames a poll; a touch held until lifted) whose person and skin come
from :mod:`wovenskin.independent`, the labelled-stream generator written apart from the
simulator the shipped model was trained on (docs/independent-streams.md).  Operator
``seed`` touches with the person and on the skin of that generator's stream of that seed
(:func:`~wovenskin.independent.person_of`, :func:`~wovenskin.independent.skin_of`: drawn
over its whole range); each gesture is one of its people's performances
(:func:`~wovenskin.independent.perform_touch`, a swipe's rest drawn as they draw it),
rendered block by block by :class:`~wovenskin.independent.LiveRenderer`.  Held, the
fingers rest as they were before the performance's lift-off; lifted, they play its own
lift-off.  ``wovenskin study simulate`` uses it by default (``--hands independent``).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from wovenskin.custom_gestures import CustomGesture
from wovenskin.independent import (
    LiveRenderer,
    held_fingers,
    perform_touch,
    person_of,
    skin_of,
    touch_frames,
)
from wovenskin.independent.people import Person
from wovenskin.independent.skins import Skin
from wovenskin.independent.tracks import Touch
from wovenskin.operators.touch_skin import BLOCK_FRAMES, TouchSkin
from wovenskin.skin.frames import SkinInfo
from wovenskin.skin.layout import DEFAULT_SAMPLE_RATE_HZ, SkinLayout

SEED_MASK = 0x7FFFFFFF  # a seed as the generator's streams take it (non-negative)


class IndependentSkin(TouchSkin):
    """An independent generator's skin touched by its person's hand (module docstring)."""

    opened = "independent skin under a simulated operator's hand"

    def __init__(
        self,
        seed: int,
        skin: Skin | None = None,
        person: Person | None = None,
        block: int = BLOCK_FRAMES,
        sample_rate_hz: float = DEFAULT_SAMPLE_RATE_HZ,
        gesture_seed: int | None = None,
        custom: Mapping[str, CustomGesture] | None = None,
    ) -> None:
        """``skin`` / ``person`` default: those of the generator's stream of ``seed``.
        ``gesture_seed``: the draws of each performance and of the sensor noise (default:
        from ``seed``), so one person on one skin performs differently from trial to trial.
        ``custom``: custom gestures the operator may perform (by name)."""
        stream = int(seed) & SEED_MASK
        self.layout = SkinLayout()
        self.skin = skin if skin is not None else skin_of(stream)
        self.person = person if person is not None else person_of(stream)
        draws = stream if gesture_seed is None else int(gesture_seed) & SEED_MASK
        self._rng = np.random.default_rng([draws, 0x1D5])
        self.custom = dict(custom or {})
        self._renderer = LiveRenderer(self.skin, self.layout, sample_rate_hz, noise_seed=draws)
        info = SkinInfo(
            rows=self.layout.rows, cols=self.layout.cols, sample_rate_hz=sample_rate_hz,
            firmware="wovenskin-operator-independent", device_id=f"operator-independent-{seed}",
            units="counts", source="independent", row_pitch_mm=self.layout.row_pitch_mm,
            col_pitch_mm=self.layout.col_pitch_mm,
        )  # fmt: skip
        self._ready(info, block, sample_rate_hz)

    # -- TouchSkin

    def _perform(self, gesture: str) -> Touch:
        return perform_touch(gesture, self.person, self._rng, layout=self.layout,
                             sample_rate_hz=self._fs, custom=self.custom)  # fmt: skip

    def _render_idle(self, n: int) -> np.ndarray:
        return self._renderer.render(None, n).astype(np.float32)

    def _render_played(self, start: int, n: int) -> np.ndarray:
        fingers = touch_frames(self._performance, start, start + n)
        return self._renderer.render(fingers, n).astype(np.float32)

    def _render_held(self, frame: int, n: int) -> np.ndarray:
        fingers = held_fingers(self._performance, frame, n)
        return self._renderer.render(fingers, n).astype(np.float32)
