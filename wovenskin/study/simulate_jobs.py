"""A simulated study's trials run one at a time or in worker processes, stopped by Ctrl-C.

:func:`run_jobs` runs every job of a work list through a top-level function
``run(job, stopped)`` and returns the results in the order they finished.  Ctrl-C does
not raise in the middle of a trial (where it could cut a file in two): while the jobs
run, SIGINT only raises a flag (:class:`StopFlag`).  ``run`` passes ``stopped`` to the
trial's session, which ends at its next step; a trial stopped so returns ``None`` and
leaves nothing behind.  With ``jobs > 1`` the workers ignore SIGINT (a terminal sends it
to every process of the group: the parent decides), the parent polls the flag every
:data:`POLL_S` and then sets an event the workers share: the running trials end at their
next step, the queued ones return at once without starting, and the pool is closed.
Workers that have not answered within :data:`DRAIN_S` are killed.  A whole stop takes
well under a second on a 2-core machine.
"""

from __future__ import annotations

import functools
import multiprocessing
import signal
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from typing import Any

Runner = Callable[[Any, Callable[[], bool] | None], Any]

POLL_S = 0.1
"""How often the parent looks at the flag while workers run."""
DRAIN_S = 1.5
"""How long workers may take to end their trials after a stop before they are killed."""


class StopFlag:
    """Raised by SIGINT (:func:`ctrl_c_stops`); read without locks (a signal handler sets it)."""

    def __init__(self) -> None:
        self.raised = False

    def __call__(self) -> bool:
        return self.raised


@contextmanager
def ctrl_c_stops(flag: StopFlag) -> Iterator[StopFlag]:
    """While inside, Ctrl-C (SIGINT) raises ``flag`` instead of :class:`KeyboardInterrupt`.

    Off the main thread (where no signal arrives) it changes nothing."""
    if threading.current_thread() is not threading.main_thread():
        yield flag
        return
    previous = signal.getsignal(signal.SIGINT)
    if previous is None:  # set outside Python: the default is what to come back to
        previous = signal.SIG_DFL

    def on_sigint(signum: int, frame: Any) -> None:
        flag.raised = True

    signal.signal(signal.SIGINT, on_sigint)
    try:
        yield flag
    finally:
        signal.signal(signal.SIGINT, previous)


_worker_stop: Any = None  # the pool's shared event, in a worker process


def _init_worker(event: Any) -> None:
    global _worker_stop
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _worker_stop = event


def _in_worker(run: Runner, job: Any) -> Any:
    if _worker_stop.is_set():
        return None  # queued when the stop came: never started
    return run(job, _worker_stop.is_set)


def run_jobs(
    work: Sequence[Any],
    run: Runner,
    jobs: int,
    flag: StopFlag,
    progress: Callable[[Any], None] | None = None,
) -> list[Any]:
    """Each job's ``run(job, stopped)`` result (not ``None``), in the order they finished;
    ``jobs`` at once in worker processes.  The caller holds :func:`ctrl_c_stops`; when
    ``flag`` is raised no further job starts (see ``flag`` afterwards)."""
    results: list[Any] = []

    def keep(result: Any) -> None:
        if result is not None:
            results.append(result)
            if progress is not None:
                progress(result)

    if jobs <= 1:
        for job in work:
            if flag():
                break
            keep(run(job, flag))
        return results
    _run_pool(work, run, int(jobs), flag, keep)
    return results


def _run_pool(
    work: Sequence[Any], run: Runner, jobs: int, flag: StopFlag, keep: Callable[[Any], None]
) -> None:
    if flag():  # stopped while the study was being set up: no worker is started
        return
    context = multiprocessing.get_context("spawn")
    shared = context.Event()
    main = threading.current_thread() is threading.main_thread()
    handler = signal.getsignal(signal.SIGINT) or signal.SIG_DFL
    if main:  # the workers start with Ctrl-C ignored (an ignored signal stays so across exec)
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        pool = context.Pool(jobs, initializer=_init_worker, initargs=(shared,))
    finally:
        if main:
            signal.signal(signal.SIGINT, handler)
    try:
        answers = pool.imap_unordered(functools.partial(_in_worker, run), work)
        if _collect(answers, keep, flag, None):
            return
        shared.set()  # stopped: running trials end at their next step, queued ones at once
        _collect(answers, keep, None, time.monotonic() + DRAIN_S)
    finally:
        pool.terminate()
        pool.join()


def _collect(
    answers: Any, keep: Callable[[Any], None], flag: StopFlag | None, until: float | None
) -> bool:
    """Keep answers until all are in (True), ``flag`` is raised or ``until`` passes (False)."""
    while True:
        if flag is not None and flag():
            return False
        wait = POLL_S if until is None else until - time.monotonic()
        if wait <= 0:
            return False
        try:
            keep(answers.next(timeout=wait))
        except StopIteration:
            return True
        except multiprocessing.TimeoutError:
            continue
