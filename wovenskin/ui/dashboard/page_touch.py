"""A page's virtual fingertips: touch messages checked and parsed, one page drawing at a time.

The dashboard's page sends ``{"type": "touch", "t": seconds, "touches": [{"id", "x_mm",
"y_mm", "force_n"}, ...]}`` (or several such ``samples`` at once: a pointer's coalesced
events).  :func:`parse_touch_message` turns one into ``(client time, {id: Fingertip})``
samples and refuses, with a ``ValueError`` the server answers in one line, anything else:
a touch id that is not a whole number in 0..2^31-1 (a browser's ``pointerId``), a position,
force or time that is not a finite number, more than 64 samples.  :class:`PageTouch` is one
page's hold on the virtual skin (:mod:`.server` keeps one per socket).
"""

from __future__ import annotations

import math

from wovenskin.sim.live_touches import Fingertip


def parse_touches(items: object) -> dict[int, Fingertip]:
    """``[{"id", "x_mm", "y_mm", "force_n"}, ...]`` -> ``{id: Fingertip}``; ValueError if bad."""
    if not isinstance(items, list):
        raise ValueError("touches must be a list")
    touches: dict[int, Fingertip] = {}
    for item in items:
        if not isinstance(item, dict):
            raise ValueError("each touch must be an object")
        try:
            key = _touch_id(item["id"])
            values = [_finite(item[k]) for k in ("x_mm", "y_mm", "force_n")]
        except (KeyError, TypeError, ValueError, OverflowError):
            raise ValueError("a touch needs numeric id, x_mm, y_mm and force_n") from None
        touches[key] = Fingertip(*values)
    return touches


MAX_TOUCH_ID = 2**31 - 1  # a browser's pointerId is a 32-bit integer


def _finite(value: object) -> float:
    """A finite float from a JSON number (or numeric text); ValueError otherwise."""
    if isinstance(value, bool) or not isinstance(value, int | float | str):
        raise TypeError("not a number")
    number = float(value)
    if not math.isfinite(number):
        raise ValueError("not a finite number")
    return number


def _touch_id(value: object) -> int:
    """A touch id: a whole number in 0..2^31-1 (``Infinity``, ``1e400``, 2.5 are refused)."""
    number = _finite(value)
    if number != int(number) or not 0 <= number <= MAX_TOUCH_ID:
        raise ValueError("a touch id must be a whole number in 0..2^31-1")
    return int(number)


def parse_touch_message(message: dict) -> list[tuple[float | None, dict[int, Fingertip]]]:
    """The ``(client time or None, touches)`` samples of one touch message; ValueError if bad.

    ``t`` is the sample's time in seconds on the page's clock (``event.timeStamp / 1000``);
    ``samples`` carries several (a pointer's coalesced events) in time order."""
    samples = message.get("samples")
    if samples is None:
        samples = [{"t": message.get("t"), "touches": message.get("touches")}]
    if not isinstance(samples, list) or not 0 < len(samples) <= 64:
        raise ValueError("samples must be a list of 1-64 samples")
    out = []
    for sample in samples:
        if not isinstance(sample, dict):
            raise ValueError("each sample must be an object")
        t = sample.get("t")
        if t is not None:
            try:
                t = _finite(t)
            except (TypeError, ValueError):
                raise ValueError("a sample's t must be a finite number of seconds") from None
        out.append((t, parse_touches(sample.get("touches"))))
    return out


class PageTouch:
    """One page's fingertips on the virtual skin.  One page draws at a time: while a page
    has fingers down (it *holds* the skin), touch messages of the others are refused, so
    two tablets never overwrite each other's fingers."""

    def __init__(self, shared: dict) -> None:
        self._shared = shared  # {"holder": PageTouch | None}, one per app
        self.down = False

    def may_touch(self) -> bool:
        return self._shared.get("holder") in (None, self)

    def set_down(self, down: bool) -> None:
        self.down = down
        if down:
            self._shared["holder"] = self
        elif self._shared.get("holder") is self:
            self._shared["holder"] = None
