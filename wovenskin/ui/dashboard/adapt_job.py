"""The dashboard's adapt run: ``adapt_model`` in a child process, its progress read back.

Adapting takes minutes of CPU.  Run inside the dashboard's process it would contend for
the interpreter with the 200 Hz control loop, so :class:`AdaptJob` starts
``python -m wovenskin.ui.dashboard.adapt_worker`` (:mod:`.adapt_worker`: one torch
thread, a lower scheduling priority) and reads the JSON lines it prints on a thread of its
own: progress events, then one outcome.  :meth:`AdaptJob.status` is a consistent copy at
any moment: ``running``, ``done`` (the model is installed in ``out``), ``refused`` (worse
than the base: the report, no model), ``failed`` (one line; the child's stderr is kept in
``log``) or ``cancelled``.  The dashboard itself never imports PyTorch:
:func:`torch_missing` only asks whether it is installed.
"""

from __future__ import annotations

import contextlib
import importlib.util
import json
import os
import subprocess
import sys
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from wovenskin.wording import train_extra_hint

WORKER_COMMAND: tuple[str, ...] = (sys.executable, "-m", "wovenskin.ui.dashboard.adapt_worker")
FINISHED = ("done", "refused", "failed", "cancelled")


def torch_missing() -> str:
    """One line saying that adapting needs PyTorch, or ``""`` when it is installed."""
    if importlib.util.find_spec("torch") is not None:
        return ""
    return f"adapting needs PyTorch, which is not installed here: {train_extra_hint()}"


@dataclass
class AdaptStatus:
    """Where an adapt run stands (see the module docstring for ``state``)."""

    state: str = "running"
    stage: str = "starting"
    done: int = 0
    total: int = 0
    note: str = ""
    seconds: float = 0.0
    report: dict[str, Any] | None = None
    message: str = ""
    stages: list[str] = field(default_factory=list)  # every stage seen, in order

    @property
    def finished(self) -> bool:
        return self.state in FINISHED


class AdaptJob:
    """One adapt run of ``paths`` into ``out`` from ``base`` (None: the shipped model).

    ``settings`` are :class:`~wovenskin.training.adapt.AdaptSettings` fields; ``command``
    the worker's command line (tests give a stand-in speaking the same protocol); the
    child's stderr goes to ``log``."""

    def __init__(
        self,
        paths: Sequence[str | Path],
        out: str | Path,
        base: str | Path | None = None,
        *,
        settings: dict[str, Any] | None = None,
        command: Sequence[str] = WORKER_COMMAND,
        log: str | Path | None = None,
    ) -> None:
        self.request = {
            "paths": [str(p) for p in paths],
            "out": str(out),
            "base": None if base is None else str(base),
            "settings": dict(settings or {}),
        }
        self.command = list(command)
        self.log = Path(log) if log is not None else Path(out).parent / "adapt.log"
        self._status = AdaptStatus()
        self._lock = threading.Lock()
        self._process: subprocess.Popen | None = None
        self._reader: threading.Thread | None = None
        self._started = 0.0

    def start(self) -> None:
        """Start the child and the thread that reads it (OSError if it cannot start)."""
        self.log.parent.mkdir(parents=True, exist_ok=True)
        env = {**os.environ, "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
        self._started = time.monotonic()
        with open(self.log, "ab") as log:
            self._process = subprocess.Popen(
                [*self.command, json.dumps(self.request)],
                stdin=subprocess.DEVNULL,
                stdout=subprocess.PIPE,
                stderr=log,
                env=env,
                text=True,
                encoding="utf-8",
                errors="replace",
            )
        self._reader = threading.Thread(target=self._read, name="dashboard-adapt", daemon=True)
        self._reader.start()

    def status(self) -> AdaptStatus:
        """A copy of where the run stands now."""
        with self._lock:
            status = replace(self._status, stages=list(self._status.stages))
        if not status.finished and self._started:
            status.seconds = time.monotonic() - self._started
        return status

    def cancel(self) -> None:
        """Stop the child (its partial output stays in ``out``); nothing if it ended."""
        with self._lock:
            if self._status.finished:
                return
            self._status.state, self._status.message = "cancelled", "adapting was cancelled"
        self._stop_child()

    def close(self) -> None:
        """Cancel a running child and wait for the reader (the dashboard closes)."""
        self.cancel()
        if self._reader is not None:
            self._reader.join(timeout=5.0)

    def _stop_child(self) -> None:
        process = self._process
        if process is None or process.poll() is not None:
            return
        process.terminate()
        try:
            process.wait(timeout=5.0)
        except subprocess.TimeoutExpired:
            process.kill()

    def _read(self) -> None:
        process = self._process
        assert process is not None and process.stdout is not None
        for line in process.stdout:
            self._take(line)
        code = process.wait()
        with self._lock:
            status = self._status
            if not status.finished:
                status.state = "failed"
                status.message = (
                    f"the adapt process ended without a result (exit code {code}): see {self.log}"
                )
            status.seconds = time.monotonic() - self._started

    def _take(self, line: str) -> None:
        """One line from the child: progress or the outcome (anything else is ignored)."""
        try:
            message = json.loads(line)
        except ValueError:
            return
        if not isinstance(message, dict):
            return
        event = message.get("event")
        with self._lock:
            status = self._status
            if status.finished:
                return
            if event == "progress":
                status.stage = str(message.get("stage", ""))[:80]
                status.done = _count(message.get("done"))
                status.total = _count(message.get("total"))
                status.note = str(message.get("note", ""))[:120]
                if not status.stages or status.stages[-1] != status.stage:
                    status.stages.append(status.stage)
            elif event in ("done", "refused", "failed"):
                status.state = event
                report = message.get("report")
                status.report = report if isinstance(report, dict) else None
                text = message.get("verdict") or message.get("message") or ""
                status.message = " ".join(str(text).split())[:400]


def _count(value: object) -> int:
    """A progress count from the child's JSON (0 for anything that is not a whole number)."""
    with contextlib.suppress(TypeError, ValueError, OverflowError):
        return max(0, int(value))  # type: ignore[call-overload]
    return 0
