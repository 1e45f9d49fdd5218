"""How a simulated person performs each gesture: :func:`perform`, for any class name.

Owns :func:`perform` (any class name, ``invalid`` included).  The performers of the 14
valid gestures of ``docs/gestures.md`` live in :mod:`wovenskin.sim.valid`, the invalid
touches in :mod:`wovenskin.sim.invalid` (which builds on :mod:`wovenskin.sim.valid`), so
the imports run one way: this module -> invalid -> valid.  A user's custom gestures (given
as ``custom``) are performed from their stroke scripts by :mod:`wovenskin.sim.strokes`.
:data:`DIRECTIONS`,
:func:`perform_valid` and :func:`five_finger_layout` stay importable from here.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from wovenskin.custom_gestures import CustomGesture
from wovenskin.gestures import INVALID, check_name, known_classes
from wovenskin.sim.invalid import perform_invalid
from wovenskin.sim.motion import Performance
from wovenskin.sim.person import Person, Trial
from wovenskin.sim.strokes import perform_strokes
from wovenskin.sim.valid import DIRECTIONS, five_finger_layout, perform_valid
from wovenskin.skin.layout import DEFAULT_SAMPLE_RATE_HZ, SkinLayout

__all__ = ["DIRECTIONS", "Performance", "five_finger_layout", "perform", "perform_valid"]


def perform(
    name: str,
    person: Person,
    rng: np.random.Generator,
    layout: SkinLayout | None = None,
    *,
    invalid_kind: str | None = None,
    sample_rate_hz: float = DEFAULT_SAMPLE_RATE_HZ,
    custom: Mapping[str, CustomGesture] | None = None,
) -> Performance:
    """One performance of ``name`` (a gesture, one of ``custom`` or ``invalid``) by ``person``.

    For ``invalid``, ``invalid_kind`` picks the sub-kind (see
    :data:`wovenskin.sim.invalid.INVALID_KINDS`); ``None`` draws one at random.  A custom
    gesture is performed from its stroke script (one ConfigError line if it has none).
    """
    custom = custom or {}
    check_name(name, known_classes(custom))
    layout = layout if layout is not None else SkinLayout()
    if name == INVALID:
        return perform_invalid(person, rng, layout, invalid_kind, sample_rate_hz)
    if invalid_kind is not None:
        raise ValueError(f"invalid_kind is only for 'invalid', not {name!r}")
    if name in custom:
        return perform_strokes(custom[name], Trial(person, rng), layout, sample_rate_hz)
    return perform_valid(name, Trial(person, rng), layout, sample_rate_hz)
