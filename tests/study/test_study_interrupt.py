"""Ctrl-C in ``wovenskin study simulate`` stops the study whatever ``--jobs`` is: it says
what was kept, exits 130, leaves no trial cut short and writes no trial afterwards.

Each test runs a tiny study in a subprocess, waits until its first trial has been written
(the progress line), sends SIGINT to the command alone (as a signal to the parent only:
the workers must be stopped by it, not by the terminal) and reads what is left.  The
deadlines are generous, for a busy machine: they catch a study that goes on, not a slow one.
"""

from __future__ import annotations

import csv
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from wovenskin.study.recorder import SUMMARY_FILE, TRIALS_DIR, TRIALS_FILE
from wovenskin.study.simulate_jobs import StopFlag, run_jobs

STARTUP_S = 240.0  # to the first written trial (spawned workers import the package)
STOP_S = 30.0  # from SIGINT to the exit: the fix stops in well under 2 s


def interrupt_study(folder: Path, jobs: int) -> tuple[int, str, float]:
    """Run a 12-trial study, Ctrl-C it after its first trial; (exit code, stderr, the
    wall time of the exit, as ``time.time()``)."""
    args = [
        sys.executable, "-m", "wovenskin.cli", "study", "simulate", str(folder),
        "--participants", "2", "--trials", "3", "--task", "pick_place",
        "--interface", "keyboard", "--interface", "pendant", "--time-limit", "20",
        "--jobs", str(jobs),
    ]  # fmt: skip
    env = {**os.environ, "PYTHONUNBUFFERED": "1", "COLUMNS": "200"}
    process = subprocess.Popen(
        args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env
    )
    try:
        first = process.stdout.readline()
        assert "simulated trials" in first and "Ctrl-C" in first, first
        line = process.stdout.readline()  # the first trial's line, once it is written
        assert " trial " in line and "done" in line, line + process.stderr.read()
        process.send_signal(signal.SIGINT)
        _, err = process.communicate(timeout=STOP_S)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    return process.returncode, err, time.time()


def check_what_was_kept(folder: Path, err: str, ended: float) -> int:
    """The message matches the folder; every trial folder is finished; nothing newer than
    the exit.  Returns how many trials were kept."""
    assert "interrupted:" in err and "Traceback" not in err, err
    assert len(err.strip().splitlines()) == 1, err
    summaries = sorted((folder / TRIALS_DIR).glob(f"*/*/{SUMMARY_FILE}"))
    kept = len(summaries)
    assert kept >= 1
    assert f"{kept} of 12 trials" in err and str(folder / TRIALS_DIR) in err, err
    rows = list(csv.DictReader((folder / TRIALS_FILE).open()))
    assert len(rows) == kept
    for trial in (folder / TRIALS_DIR).glob("*/*"):
        assert (trial / SUMMARY_FILE).exists(), f"{trial} was cut short and left behind"
    time.sleep(1.0)  # a worker that went on would write here
    newest = max(p.stat().st_mtime for p in folder.rglob("*"))
    assert newest <= ended, "a file was written after the command exited"
    assert len(sorted((folder / TRIALS_DIR).glob(f"*/*/{SUMMARY_FILE}"))) == kept
    return kept


@pytest.mark.slow  # a whole simulated study in a subprocess, interrupted
@pytest.mark.parametrize("jobs", [1, 2])
def test_ctrl_c_stops_the_study_and_says_what_was_kept(tmp_path, jobs):
    folder = tmp_path / "study"
    code, err, ended = interrupt_study(folder, jobs)
    assert code == 130, err
    kept = check_what_was_kept(folder, err, ended)
    assert kept < 12  # the queued trials never ran


def double(n: int, stopped) -> int | None:
    return None if stopped() else 2 * n


def test_run_jobs_starts_nothing_once_the_flag_is_raised():
    flag = StopFlag()
    seen: list[int] = []

    def run(n: int, stopped) -> int:
        if n == 3:
            flag.raised = True  # as SIGINT would, during the third job
        return double(n, stopped)

    assert run_jobs(range(1, 10), run, 1, flag, seen.append) == [2, 4]
    assert seen == [2, 4] and flag()
    assert run_jobs(range(1, 4), double, 1, StopFlag()) == [2, 4, 6]
