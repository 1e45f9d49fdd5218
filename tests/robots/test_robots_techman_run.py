"""End to end: ``wovenskin run --skin replay:FILE --robot tm:127.0.0.1?...`` against the fake
Techman controller (TM5-900 joints, binary state table, lower-case checksums, the real
velocity-mode timeouts), as a user would run it: a separate process, the shipped model,
the full safety layer, a short replay played in real time.

It checks the issue's targets: zero protocol violations, velocity mode entered once (or
again only after a documented timeout), every streamed velocity within the caps
(250 mm/s, 60 deg/s), ``StopContinueVmode`` on exit, a clean exit with no error lines.
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from wovenskin.recording.formats import write_labelled_stream
from wovenskin.robots.techman import FakeListenNode
from wovenskin.sim.stream import simulate_stream

MAX_LINEAR_MM_S = 250.0
MAX_ANGULAR_DEG_S = 60.0
GESTURES = ["swipe_up", "swipe_right", "circle_cw_2f", "swipe_up_2f"]


@pytest.fixture(scope="module")
def replay(tmp_path_factory) -> Path:
    """Six seconds with a translation (swipe up) and a rotation (circle) for the shipped
    model to recognise."""
    path = tmp_path_factory.mktemp("tm_run") / "replay.npz"
    write_labelled_stream(path, simulate_stream(6.0, 7, gestures=GESTURES, invalid_fraction=0.0))
    return path


def run_cli(*args: str, timeout: float = 240.0) -> subprocess.CompletedProcess[str]:
    command = [sys.executable, "-c", "from wovenskin.cli import main; main()", *args]
    return subprocess.run(command, capture_output=True, text=True, timeout=timeout)


@pytest.mark.slow
def test_a_replayed_session_drives_the_fake_controller_cleanly(replay: Path) -> None:
    with FakeListenNode.tm5_900() as fake:
        result = run_cli(
            "run", "--skin", f"replay:{replay}?speed=1", "--robot", fake.spec, "--view", "none"
        )
        summary = fake.summary()
        exits = [reason for _, reason in fake.velocity_mode_exits]
        commands = [v for _, v in fake.velocity_commands]
        scripts = list(fake.scripts)
    output = result.stdout + result.stderr
    assert result.returncode == 0, output
    lines = output.splitlines()
    bad = [line for line in lines if re.search(r"error:|traceback|warning|exception", line, re.I)]
    assert bad == [], output
    assert " 0 errors;" in output  # the session's closing line
    # the protocol, as the controller saw it
    assert summary["protocol_violations"] == 0, summary
    assert summary["script_errors"] == [], summary
    timeouts = [reason for reason in exits if reason.startswith("timeout_stop")]
    assert fake.velocity_mode_entries == 1 + len(timeouts), (exits, summary)
    # motion happened, within the caps
    moving = [v for v in commands if np.any(v != 0.0)]
    assert len(moving) > 10, summary
    linear = max(float(np.linalg.norm(v[:3])) for v in commands)
    angular = max(float(np.linalg.norm(v[3:])) for v in commands)
    assert 0.0 < linear <= MAX_LINEAR_MM_S * (1 + 1e-6)
    assert angular <= MAX_ANGULAR_DEG_S * (1 + 1e-6)
    # velocity mode was left on exit
    assert exits[-1] == "StopContinueVmode" and "StopContinueVmode()" in scripts[-3:]
    assert not fake.velocity_mode
