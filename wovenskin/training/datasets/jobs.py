"""Running one job per recording, in worker processes, into a data set's collector."""

from __future__ import annotations

import multiprocessing
import sys
from collections.abc import Callable, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait

from wovenskin.training.datasets.store import DatasetError, ProgressCallback
from wovenskin.training.datasets.writer import RecordingCollector, RecordingWindows


def run_jobs(
    jobs: Sequence,
    worker: Callable,
    workers: int,
    collector: RecordingCollector,
    progress: ProgressCallback | None,
    describe: Callable[[object], str],
) -> None:
    """Run ``worker(job)`` for every job on ``workers`` processes into ``collector``."""
    total = len(jobs)
    if progress is not None:
        progress(0, total)
    done = 0

    def accept(index: int, result: RecordingWindows) -> None:
        nonlocal done
        collector.put(index, result)
        done += 1
        if progress is not None:
            progress(done, total)

    if workers <= 1 or total <= 1:
        for index, job in enumerate(jobs):
            accept(index, _call(worker, job, describe))
        return
    pool = ProcessPoolExecutor(max_workers=min(workers, total), mp_context=_pool_context())
    try:
        pending: dict[Future, int] = {
            pool.submit(worker, job): index for index, job in enumerate(jobs)
        }
        while pending:
            finished, _ = wait(pending, return_when=FIRST_COMPLETED)
            for future in sorted(finished, key=pending.__getitem__):
                index = pending.pop(future)
                try:
                    result = future.result()
                except Exception as exc:
                    raise DatasetError(f"{describe(jobs[index])}: {one_line(exc)}") from exc
                accept(index, result)
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


def _pool_context() -> multiprocessing.context.BaseContext:
    """``fork`` on Linux, ``spawn`` elsewhere.

    Forked workers start at once and work from any caller, including a script without an
    ``if __name__ == "__main__"`` guard, which spawned (and forkserver) workers re-run
    and fail on.  The workers use numpy and scipy only and never touch the parent's
    threads (a progress display) or locks.  macOS and Windows cannot fork safely.
    """
    method = "fork" if sys.platform.startswith("linux") else "spawn"
    return multiprocessing.get_context(method)


def _call(worker: Callable, job, describe: Callable[[object], str]) -> RecordingWindows:
    try:
        return worker(job)
    except Exception as exc:
        raise DatasetError(f"{describe(job)}: {one_line(exc)}") from exc


def one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split()) or type(exc).__name__
