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

DIRECTIONS: dict[str, tuple[str, ...]] = {
    "swipe": ("up", "down", "right", "left"),
    "press": ("",),
    "circle": ("cw", "ccw"),
    "pinch": ("in", "out"),
}
"""The directions each motion may have (``""``: none)."""


@dataclass(frozen=True)
class GestureSpec:
    """A gesture: its stable name, how many fingers perform it, how they move (``swipe``,
    ``press``, ``circle`` or ``pinch``: the fingers close or spread) and which way
    (:data:`DIRECTIONS` of its motion: a swipe's ``up``/``down``/``right``/``left`` on the
    skin, a circle's ``cw``/``ccw`` as the user sees it, a pinch's ``in``/``out``; none for
    a press)."""

    name: str
    fingers: int
    motion: str
    direction: str = ""

    def __post_init__(self) -> None:
        if self.motion not in MOTIONS:
            raise ValueError(f"gesture motion must be one of {MOTIONS}, got {self.motion!r}")
        if self.direction not in DIRECTIONS[self.motion]:
            raise ValueError(
                f"a {self.motion}'s direction must be one of {DIRECTIONS[self.motion]}, "
                f"got {self.direction!r}"
            )


GESTURES: tuple[GestureSpec, ...] = (
    GestureSpec("swipe_up", 1, "swipe", "up"),
    GestureSpec("swipe_down", 1, "swipe", "down"),
    GestureSpec("swipe_right", 1, "swipe", "right"),
    GestureSpec("swipe_left", 1, "swipe", "left"),
    GestureSpec("pinch_in_2f", 2, "pinch", "in"),
    GestureSpec("push", 1, "press"),
    GestureSpec("swipe_up_2f", 2, "swipe", "up"),
    GestureSpec("swipe_down_2f", 2, "swipe", "down"),
    GestureSpec("swipe_right_2f", 2, "swipe", "right"),
    GestureSpec("swipe_left_2f", 2, "swipe", "left"),
    GestureSpec("circle_cw_2f", 2, "circle", "cw"),
    GestureSpec("circle_ccw_2f", 2, "circle", "ccw"),
    GestureSpec("pinch_in_5f", 5, "pinch", "in"),
    GestureSpec("pinch_out_5f", 5, "pinch", "out"),
)

GESTURE_NAMES: tuple[str, ...] = tuple(g.name for g in GESTURES)
"""The 14 valid gestures, in the order of docs/gestures.md."""

SPECS: dict[str, GestureSpec] = {g.name: g for g in GESTURES}
"""Each valid gesture's :class:`GestureSpec` by name."""

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
