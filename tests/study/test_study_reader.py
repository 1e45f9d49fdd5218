"""Reading trials back: complete ones, and a killed trial marked incomplete."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap

from wovenskin.study.reader import read_commands, read_trajectory, read_trials
from wovenskin.study.recorder import TrialRecorder


def test_a_killed_writer_leaves_an_incomplete_trial_that_reads_back(tmp_path):
    """A real process writes a trial and is killed with SIGKILL before finish(): the
    lines it flushed are there, the torn last one is dropped, the trial is incomplete."""
    code = textwrap.dedent(f"""
        import os, sys
        from wovenskin.study.recorder import TrialRecorder
        rec = TrialRecorder({str(tmp_path)!r}, "P01", "novice", "pick_place", "keyboard", 1)
        rec.start(0.0)
        for i in range(50):
            rec.command(i * 0.1, "keyboard", "w", "key")
            rec.pose(i * 0.1, (0.1 * i, 0, 0.3, 1, 0, 0, 0), 0.0)
        rec._trajectory._file.write("5.0,0.5,0,0.3")  # a line half written...
        rec._trajectory._file.flush()
        print("ready", flush=True)
        sys.stdin.read()
    """)
    proc = subprocess.Popen(
        [sys.executable, "-c", code], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True
    )
    assert proc.stdout.readline().strip() == "ready"
    os.kill(proc.pid, signal.SIGKILL)  # ...when the process is killed
    proc.wait()
    trials, warnings = read_trials(tmp_path)
    assert trials == []
    assert len(warnings) == 1 and "pick_place-keyboard-1: incomplete" in warnings[0]
    folder = tmp_path / "trials" / "P01" / "pick_place-keyboard-1"
    assert len(read_commands(folder)) == 50
    trajectory = read_trajectory(folder)
    assert trajectory.shape == (50, 9) and trajectory[-1, 1] == 4.9


def test_complete_trials_read_back_and_a_corrupt_summary_is_incomplete(tmp_path):
    for n in (1, 2):
        rec = TrialRecorder(tmp_path, "P02", "expert", "pour", "pendant", n)
        rec.start(0.0)
        rec.command(1.0, "pendant", "jog +x", "panel")
        rec.finish(3.0, "success", {"particles_spilled": 0})
    (tmp_path / "trials" / "P02" / "pour-pendant-2" / "trial.json").write_text("{")
    trials, warnings = read_trials(tmp_path)
    assert [(t.participant, t.interface, t.trial, t.duration_s) for t in trials] == [
        ("P02", "pendant", 1, 2.0)
    ]
    assert trials[0].measures == {"particles_spilled": 0.0} and trials[0].commands == 1
    assert "unreadable trial.json" in warnings[0]
