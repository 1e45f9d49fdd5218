"""An independent labelled-stream generator: people and skins made apart from ``wovenskin.sim``.

The project's simulator (:mod:`wovenskin.sim`) trained the shipped model, so scoring the
model on its streams grades the project on its own homework (issue 22).  This package
renders labelled streams from the gesture table of ``docs/gestures.md`` alone, with its
own people (:mod:`.people`), its own fingertip and skin physics (:mod:`.skins`), its own
strokes (:mod:`.tracks`, :mod:`.performers`, :mod:`.invalid`, and :mod:`.strokes` for a
user's custom gestures) and its own stream assembly (:mod:`.streams`); :mod:`.live`
renders one skin block by block for a live source (a simulated operator's).  It never imports
:mod:`wovenskin.sim` (a test parses the imports); what it models and how it differs is in
``docs/independent-streams.md``.
"""

from __future__ import annotations

from wovenskin.independent.live import LiveRenderer, held_fingers, touch_frames
from wovenskin.independent.skins import TYPICAL_GAIN, WEAK_GAIN
from wovenskin.independent.streams import (
    GENERATOR,
    gesture_stream,
    mixed_stream,
    perform_touch,
    person_of,
    render_stream,
    skin_of,
)

__all__ = [
    "GENERATOR",
    "TYPICAL_GAIN",
    "WEAK_GAIN",
    "LiveRenderer",
    "gesture_stream",
    "held_fingers",
    "mixed_stream",
    "perform_touch",
    "person_of",
    "render_stream",
    "skin_of",
    "touch_frames",
]
