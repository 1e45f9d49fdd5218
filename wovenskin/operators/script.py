"""An operator's plan stepped in session time: generators that wait for time or for a sight.

A plan is a generator that yields what it waits for: :class:`Sleep` (session seconds:
thinking, a key press, a gesture) or :class:`Until` (a predicate of the scene, checked
every control tick, with a timeout).  :class:`ScriptRunner` resumes it from the session's
tick callback when the wait is over, so the operator acts on the session's clock however
fast the simulation runs, and a run is the same for the same seeds.  A timed-out
``Until`` raises :class:`Timeout` inside the plan (which may catch it and correct).

:func:`run_blocking` steps a plan from a thread of its own instead, polling the session's
clock: for a session that runs elsewhere (a dashboard's, driven through its page), where a
plan's acts block while they happen.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Generator
from dataclasses import dataclass
from typing import Any


class Timeout(Exception):
    """An :class:`Until` did not come true in time."""


@dataclass(frozen=True)
class Sleep:
    """Wait ``seconds`` of session time."""

    seconds: float


@dataclass(frozen=True)
class Until:
    """Wait until ``predicate()`` is true, at most ``timeout_s`` (then :class:`Timeout`)."""

    predicate: Callable[[], bool]
    timeout_s: float
    what: str = ""


Plan = Generator[Sleep | Until, None, Any]


class ScriptRunner:
    """Steps one plan at a time from the session's ticks (module docstring)."""

    def __init__(self) -> None:
        self.plan: Plan | None = None
        self.result: Any = None
        self.error: BaseException | None = None
        self._wait: Sleep | Until | None = None
        self._since = 0.0

    @property
    def running(self) -> bool:
        return self.plan is not None

    def start(self, plan: Plan, t: float) -> None:
        """Run ``plan`` from session time ``t`` (a running plan is closed first)."""
        self.stop()
        self.plan, self.result, self.error = plan, None, None
        self._wait, self._since = None, t

    def stop(self) -> None:
        if self.plan is not None:
            self.plan.close()
        self.plan, self._wait = None, None

    def tick(self, t: float) -> None:
        """Resume the plan if what it waits for is over at session time ``t``."""
        if self.plan is None:
            return
        send: BaseException | None = None
        wait = self._wait
        if isinstance(wait, Sleep):
            if t - self._since < wait.seconds:
                return
        elif isinstance(wait, Until) and not wait.predicate():
            if t - self._since < wait.timeout_s:
                return
            send = Timeout(f"{wait.what or 'a condition'} not seen in {wait.timeout_s:g} s")
        try:
            nxt = self.plan.throw(send) if send is not None else self.plan.send(None)
        except StopIteration as done:
            self.plan, self._wait, self.result = None, None, done.value
            return
        except Exception as exc:  # the plan gave up: keep why, stop stepping it
            self.plan, self._wait, self.error = None, None, exc
            return
        self._wait, self._since = nxt, t
        if isinstance(nxt, Until) and nxt.predicate():  # already true: go on next tick
            self._wait = Sleep(0.0)


def run_blocking(plan: Plan, clock: Callable[[], float], poll_s: float = 0.01) -> Any:
    """Step ``plan`` to its end in this thread, its waits on ``clock`` (the session's
    ``now``, so a wait lasts session time however the session keeps up with the wall),
    looking every ``poll_s`` wall seconds.  Returns the plan's result, or raises the
    error it ended on."""
    runner = ScriptRunner()
    runner.start(plan, clock())
    while runner.running:
        runner.tick(clock())
        time.sleep(poll_s)
    runner.stop()
    if runner.error is not None:
        raise runner.error
    return runner.result
