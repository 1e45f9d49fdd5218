"""The gesture vocabulary of ``docs/gestures.md``: names are the stable identifiers.

Files, checkpoints and command logs carry these names, never bare class indices.  What
each gesture makes the robot do is the mapping file's business
(``wovenskin/control/default_mapping.toml``), not the vocabulary's.  A user's own gestures
(:mod:`wovenskin.custom_gestures`) join these names through :func:`known_classes`.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass

from wovenskin.errors import ConfigError

INVALID = "invalid"


MOTIONS = ("swipe", "press", "circle", "pinch")


@dataclass(frozen=True)
class GestureSpec:
    """A gesture: its stable name, how many fingers perform it and how they move
    (``swipe``, ``press``, ``circle`` or ``pinch``: the fingers close or spread)."""

    name: str
    fingers: int
    motion: str

    def __post_init__(self) -> None:
        if self.motion not in MOTIONS:
            raise ValueError(f"gesture motion must be one of {MOTIONS}, got {self.motion!r}")


GESTURES: tuple[GestureSpec, ...] = (
    GestureSpec("swipe_up", 1, "swipe"),
    GestureSpec("swipe_down", 1, "swipe"),
    GestureSpec("swipe_right", 1, "swipe"),
    GestureSpec("swipe_left", 1, "swipe"),
    GestureSpec("pinch_in_2f", 2, "pinch"),
    GestureSpec("push", 1, "press"),
    GestureSpec("swipe_up_2f", 2, "swipe"),
    GestureSpec("swipe_down_2f", 2, "swipe"),
    GestureSpec("swipe_right_2f", 2, "swipe"),
    GestureSpec("swipe_left_2f", 2, "swipe"),
    GestureSpec("circle_cw_2f", 2, "circle"),
    GestureSpec("circle_ccw_2f", 2, "circle"),
    GestureSpec("pinch_in_5f", 5, "pinch"),
    GestureSpec("pinch_out_5f", 5, "pinch"),
)

GESTURE_NAMES: tuple[str, ...] = tuple(g.name for g in GESTURES)
"""The 14 valid gestures, in the order of docs/gestures.md."""

CLASS_NAMES: tuple[str, ...] = (*GESTURE_NAMES, INVALID)
"""All 15 classes: the 14 gestures and ``invalid`` last."""


def known_classes(extra: Iterable[str] = ()) -> tuple[str, ...]:
    """The class names a mapping or model knows: :data:`CLASS_NAMES`, then ``extra`` (a
    mapping's custom gestures, a model's ``meta.json`` class names) not already there."""
    out = list(CLASS_NAMES)
    for name in extra:
        if str(name) not in out:
            out.append(str(name))
    return tuple(out)


def check_name(name: str, known: Iterable[str] | None = None) -> str:
    """Return ``name`` if it is one of ``known`` (default :data:`CLASS_NAMES`; see
    :func:`known_classes`), else raise :class:`ConfigError` (a ``ValueError``)."""
    names = CLASS_NAMES if known is None else tuple(known)
    if name not in names:
        raise ConfigError(f"unknown gesture {name!r}; known: {', '.join(names)}")
    return name
