"""A mouse for browser tests that samples its path on its own clock, as a real one does."""

from __future__ import annotations

import time


class HardwareMouse:
    """A mouse that samples its path on its own clock, as a real one does (Chrome DevTools
    mouse events carrying their sample times).

    Playwright's ``page.mouse.move`` makes one event per round trip, stamped when the page
    takes it: when a busy page stalls for 300 ms the path it sees rests, then jumps.  A
    USB mouse keeps sampling through the stall and the browser hands the page the missed
    samples, each with its own time, as coalesced events.  This driver does the same: each
    step sends the samples of the time since its last one (at least ``SPACING_S`` apart, at
    most ``MAX_CATCH_UP`` of them), stamped with their times on the path."""

    SPACING_S = 0.008  # a 125 Hz USB mouse
    MAX_CATCH_UP = 3

    def __init__(self, page) -> None:
        self.cdp = page.context.new_cdp_session(page)
        self.last_t: float | None = None

    def _event(self, kind: str, xy: tuple[float, float], t: float, buttons: int) -> None:
        event = {"type": kind, "x": xy[0], "y": xy[1], "timestamp": t, "buttons": buttons}
        if kind != "mouseMoved" or buttons:
            event.update(button="left", clickCount=1 if kind != "mouseMoved" else 0)
        self.cdp.send("Input.dispatchMouseEvent", event)

    def down(self, path) -> None:
        """Press the button where ``path(0)`` (page pixels) is; ``path(s)`` is where the
        hand is ``s`` seconds after the press."""
        self.path, self.t0 = path, time.time()
        self.xy = path(0.0)
        self._event("mouseMoved", path(0.0), self.t0, 0)
        self._event("mousePressed", path(0.0), self.t0, 1)
        self.last_t = self.t0

    def step(self) -> None:
        """Send the samples of the path since the last step (the newest at the present;
        none where the path rests)."""
        assert self.last_t is not None, "press first"
        now = time.time()
        count = min(self.MAX_CATCH_UP, int((now - self.last_t) / self.SPACING_S))
        for k in range(1, count + 1):
            t = self.last_t + (now - self.last_t) * k / count
            xy = self.path(t - self.t0)
            if xy != self.xy:  # a mouse at rest sends nothing
                self._event("mouseMoved", xy, t, 1)
                self.xy = xy
        if count:
            self.last_t = now

    @property
    def pressed(self) -> bool:
        return self.last_t is not None

    def up(self) -> None:
        assert self.last_t is not None, "press first"
        now = time.time()
        self._event("mouseReleased", self.path(now - self.t0), now, 0)
        self.last_t = None
