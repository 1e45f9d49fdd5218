"""The gesture vocabulary of ``docs/gestures.md``: names are the stable identifiers.

Files, checkpoints and command logs carry these names, never bare class indices.
"""

from __future__ import annotations

from dataclasses import dataclass

INVALID = "invalid"


@dataclass(frozen=True)
class GestureSpec:
    name: str
    fingers: int
    action: str


GESTURES: tuple[GestureSpec, ...] = (
    GestureSpec("swipe_up", 1, "translate +z"),
    GestureSpec("swipe_down", 1, "translate -z"),
    GestureSpec("swipe_right", 1, "translate +y"),
    GestureSpec("swipe_left", 1, "translate -y"),
    GestureSpec("pinch_in_2f", 2, "translate +x"),
    GestureSpec("push", 1, "translate -x"),
    GestureSpec("swipe_up_2f", 2, "rotate +y"),
    GestureSpec("swipe_down_2f", 2, "rotate -y"),
    GestureSpec("swipe_right_2f", 2, "rotate +z"),
    GestureSpec("swipe_left_2f", 2, "rotate -z"),
    GestureSpec("circle_cw_2f", 2, "rotate +x"),
    GestureSpec("circle_ccw_2f", 2, "rotate -x"),
    GestureSpec("pinch_in_5f", 5, "go to initial pose"),
    GestureSpec("pinch_out_5f", 5, "go to home posture"),
)

GESTURE_NAMES: tuple[str, ...] = tuple(g.name for g in GESTURES)
"""The 14 valid gestures, in the order of docs/gestures.md."""

CLASS_NAMES: tuple[str, ...] = (*GESTURE_NAMES, INVALID)
"""All 15 classes: the 14 gestures and ``invalid`` last."""


def check_name(name: str) -> str:
    """Return ``name`` if it is one of :data:`CLASS_NAMES`, else raise ``ValueError``."""
    if name not in CLASS_NAMES:
        raise ValueError(f"unknown gesture {name!r}; known: {', '.join(CLASS_NAMES)}")
    return name
