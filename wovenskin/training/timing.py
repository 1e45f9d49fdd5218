"""Timing of inference calls: per-call latency in interleaved rounds, on one pinned CPU.

Owns :func:`measure_latency` and :func:`one_core`.  :func:`~.compare.compare_models` times
the models it compares with them, and the benchmarks (``wovenskin.bench.model``,
``wovenskin.bench.io``, ``wovenskin.bench.sim``) build on them, so recognition never
imports the benchmarks.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager, suppress

import numpy as np

WARMUP_CALLS = 20
"""Calls each callable gets before :func:`measure_latency` starts timing."""


def measure_latency(
    calls: Mapping[str, Callable[[np.ndarray], object]],
    inputs: np.ndarray,
    repeats: int,
    warmup: int = WARMUP_CALLS,
) -> dict[str, np.ndarray]:
    """Seconds per call of every callable over ``repeats`` interleaved rounds.

    ``inputs`` is a pool of ready-made arguments (e.g. ``(P, 1, W, R, C)`` single-window
    batches) cycled through; each callable is warmed up ``warmup`` times first.
    """
    if repeats < 1:
        raise ValueError(f"repeats must be at least 1, got {repeats}")
    for call in calls.values():
        for i in range(warmup):
            call(inputs[i % len(inputs)])
    times = {name: np.empty(repeats) for name in calls}
    clock = time.perf_counter
    for r in range(repeats):
        x = inputs[r % len(inputs)]
        for name, call in calls.items():
            t0 = clock()
            call(x)
            times[name][r] = clock() - t0
    return times


@contextmanager
def one_core() -> Iterator[None]:
    """Pin this process to one CPU for the duration (where the OS allows it)."""
    if not hasattr(os, "sched_getaffinity"):
        yield
        return
    before = os.sched_getaffinity(0)
    with suppress(OSError):
        os.sched_setaffinity(0, {min(before)})
    try:
        yield
    finally:
        with suppress(OSError):
            os.sched_setaffinity(0, before)
