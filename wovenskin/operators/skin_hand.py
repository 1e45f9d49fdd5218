"""The skin a simulated operator's hand touches: the simulator's skin and person.

:class:`OperatorSkin` is a :class:`~.touch_skin.TouchSkin` (rendered when the session
polls it, ``block`` frames a poll; a touch held until lifted) whose skin is drawn from the
simulator's skins of typical response by default (a lab's working skin; the full range,
responses 150x apart, on request), touched by a simulated person's hand
(:class:`~wovenskin.sim.person.Person`).  These are the very simulator the shipped model
was trained on: ``wovenskin study simulate --hands sim``.  The hands of
:mod:`wovenskin.independent` (:class:`~.independent_skin.IndependentSkin`) are strangers
to it.

:meth:`~.touch_skin.TouchSkin.touch` performs a gesture as the person of
:mod:`wovenskin.sim` does (landing, the pause after landing, the motion, the fingers
resting), keeps the fingers resting until :meth:`~.touch_skin.TouchSkin.lift` and then
plays the person's own lift-off.  Everything it renders goes through the session's
conditioning and recogniser: a gesture the recogniser misreads costs the operator as it
would cost a person.
"""

from __future__ import annotations

import numpy as np

from wovenskin.operators.touch_skin import BLOCK_FRAMES, TouchSkin
from wovenskin.sim.contact import ContactTrack
from wovenskin.sim.motion import Performance
from wovenskin.sim.performances import perform
from wovenskin.sim.person import Person
from wovenskin.sim.physics import SkinModel
from wovenskin.sim.skin_physics import SkinPhysics
from wovenskin.skin.frames import SkinInfo
from wovenskin.skin.layout import DEFAULT_SAMPLE_RATE_HZ, SkinLayout

__all__ = ["BLOCK_FRAMES", "OperatorSkin"]


class OperatorSkin(TouchSkin):
    """A simulated skin touched by a simulated operator (module docstring)."""

    def __init__(
        self,
        seed: int,
        physics: SkinPhysics | None = None,
        person: Person | None = None,
        block: int = BLOCK_FRAMES,
        sample_rate_hz: float = DEFAULT_SAMPLE_RATE_HZ,
        full_range: bool = False,
        gesture_seed: int | None = None,
    ) -> None:
        """``physics`` default: a skin of typical response drawn from ``seed``
        (:meth:`~wovenskin.sim.skin_physics.SkinPhysics.sample_typical`), or from the
        simulator's full range with ``full_range`` (responses 150x apart: the dullest
        skins lose a light touch in the noise).  ``gesture_seed``: the draws of each
        performance and of the sensor noise (default: from ``seed``), so one person on one
        skin performs differently from trial to trial."""
        rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, 0x5C1])
        self.layout = SkinLayout()
        if physics is None:
            draw = SkinPhysics.sample if full_range else SkinPhysics.sample_typical
            physics = draw(rng)
        self.physics = physics
        self.person = person if person is not None else Person.sample(rng)
        if gesture_seed is not None:
            rng = np.random.default_rng([int(gesture_seed) & 0xFFFFFFFF, 0x6E5])
        self._rng = rng
        self._fs = float(sample_rate_hz)
        self._model = SkinModel(self.physics, self.layout, int(rng.integers(2**31)), self._fs)
        info = SkinInfo(
            rows=self.layout.rows, cols=self.layout.cols, sample_rate_hz=self._fs,
            firmware="wovenskin-operator-sim", device_id=f"operator-sim-{int(seed)}",
            source="sim", row_pitch_mm=self.layout.row_pitch_mm,
            col_pitch_mm=self.layout.col_pitch_mm,
        )  # fmt: skip
        self._ready(info, block, self._fs)

    # -- TouchSkin

    def _perform(self, gesture: str) -> Performance:
        return perform(gesture, self.person, self._rng, self.layout, sample_rate_hz=self._fs)

    def _render_idle(self, n: int) -> np.ndarray:
        return self._model.render_idle(n)

    def _render_played(self, start: int, n: int) -> np.ndarray:
        p = self._performance
        return self._model.render(p.contacts, n, p.bursts, start)

    def _render_held(self, frame: int, n: int) -> np.ndarray:
        return self._model.render(_held(self._performance.contacts, frame, n), n)


def _held(contacts: list[ContactTrack], frame: int, n: int) -> list[ContactTrack]:
    """``n`` frames of every contact as it is at ``frame`` (the fingers resting, held)."""
    held = []
    for c in contacts:
        i = min(max(frame, 0), c.n_frames - 1)

        def at(value: np.ndarray | float, i: int = i) -> np.ndarray:
            array = np.asarray(value, dtype=np.float64)
            return np.full(n, array if array.ndim == 0 else array[i])

        held.append(ContactTrack(
            at(c.x_mm), at(c.y_mm), at(c.force_n), at(c.semi_major_mm), at(c.semi_minor_mm),
            at(c.angle_rad), c.kind, c.finger,
            None if c.presence is None else at(c.presence),
        ))  # fmt: skip
    return held
