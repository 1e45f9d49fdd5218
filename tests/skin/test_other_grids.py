"""Skins of other grids end to end (issue 23, docs/skins.md): simulated 8x8 and 16x12
skins, each through a guided recording, a data set and a model of that grid; then
``replay``/``eval-stream``, ``run`` (from the recording and from a live simulated skin that
takes the model's grid), the dashboard and a serial device declaring the grid in its INFO,
with that model moving the simulated arm; and a model of another grid refused in one line.

The data sets and models are tiny (one short simulated recording, a one-layer transformer,
one epoch): the test is about every stage taking the grid from the skin, not about accuracy.
Their data sets hold no ``invalid`` windows, so the models name a gesture for every touch
(an undertrained model that had seen them would answer ``invalid`` to every window, its
most frequent class) and the arm has something to do.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from stand_ins import wait_until
from typer.testing import CliRunner

from wovenskin.cli import app
from wovenskin.recognition.checkpoint_meta import read_meta
from wovenskin.recording.native import read_recording
from wovenskin.recording.writer import RecordingWriter
from wovenskin.runtime.session import open_session
from wovenskin.sim.pty_skin import FakeSkinDevice
from wovenskin.sim.stream import simulate_stream
from wovenskin.skin.frames import SkinInfo
from wovenskin.skin.layout import SkinLayout
from wovenskin.training.datasets import open_dataset
from wovenskin.ui.dashboard.runner import DashboardRunner

pytestmark = pytest.mark.slow  # end to end on two grids: left out of `make test-fast`

runner = CliRunner()

GRIDS = [(8, 8), (16, 12)]
TINY_TRANSFORMER = '{"d_model": 16, "n_layers": 1, "n_heads": 2, "ff_dim": 32, "stem_channels": 4}'
GESTURES = "swipe_up,swipe_down,push"


def _ok(args: list[str]) -> str:
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    return result.output


def _refused(args: list[str]) -> str:
    """The one line a command that cannot go on prints (exit code 2, no traceback)."""
    result = runner.invoke(app, args)
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    lines = [line for line in result.output.splitlines() if line.strip()]
    errors = [line for line in lines if line.startswith("error:")]
    assert len(errors) == 1, result.output
    return errors[0]


@dataclass
class Grid:
    rows: int
    cols: int
    recording: Path
    model: Path

    @property
    def sim(self) -> str:
        return f"sim:rows={self.rows},cols={self.cols},speed=0,seed=7"


@pytest.fixture(scope="module", params=GRIDS, ids=lambda g: f"{g[0]}x{g[1]}")
def grid(request, tmp_path_factory) -> Grid:
    """A guided recording on a simulated skin of the grid, and a model trained for it."""
    rows, cols = request.param
    root = tmp_path_factory.mktemp(f"grid{rows}x{cols}")
    recording, data, model = root / "guided.wsrec", root / "data", root / "model"
    skin = f"sim:rows={rows},cols={cols},speed=0,seed=3"
    _ok(["record", "--out", str(recording), "--skin", skin, "--gestures", GESTURES,
         "--trials", "1", "--invalid-trials", "1", "--countdown", "0.5",
         "--trial-seconds", "2"])  # fmt: skip
    _ok(["dataset", "--out", str(data), "--rows", str(rows), "--cols", str(cols),
         "--recordings", "1", "--windows", "60", "--invalid-windows", "0",
         "--seconds", "30", "--workers", "1"])  # fmt: skip
    _ok(["train", "--data", str(data), "--out", str(model), "--epochs", "1",
         "--split", "random", "--hparams", TINY_TRANSFORMER, "--threads", "1"])  # fmt: skip
    return Grid(rows, cols, recording, model)


def test_the_guided_recording_data_set_and_model_take_the_skins_grid(grid: Grid) -> None:
    recording = read_recording(grid.recording)
    assert (recording.info.rows, recording.info.cols) == (grid.rows, grid.cols)
    assert recording.frames.shape[1:] == (grid.rows, grid.cols)
    labels = {label.label for label in recording.labels}
    assert labels == {*GESTURES.split(","), "invalid"}
    dataset = open_dataset(grid.model.parent / "data")
    assert dataset.windows.shape[2:] == (grid.rows, grid.cols)
    meta = read_meta(grid.model)
    assert (meta.rows, meta.cols, meta.sample_rate_hz) == (grid.rows, grid.cols, 200.0)


def test_replay_and_eval_stream_run_the_grids_model(grid: Grid) -> None:
    log = _ok(["replay", str(grid.recording), "--model", str(grid.model), "--json"])
    commands = [json.loads(line) for line in log.splitlines() if line.startswith("{")]
    assert commands, "the model of this grid issued no command on the guided recording"
    _ok(["eval-stream", str(grid.recording), "--model", str(grid.model)])


def _joint_travel_deg(trace: Path) -> float:
    """How far the arm's joints went from where they started (a rotation moves no TCP)."""
    ticks = [json.loads(line) for line in trace.read_text().splitlines()]
    q = np.array([tick["q"] for tick in ticks])
    return float(np.degrees(np.abs(q - q[0]).max()))


def test_run_moves_the_simulated_arm_from_the_recording_and_the_live_skin(grid, tmp_path):
    replayed, live = tmp_path / "replayed.jsonl", tmp_path / "live.jsonl"
    _ok(["run", "--skin", f"replay:{grid.recording}", "--model", str(grid.model),
         "--robot", "sim", "--headless", "--trace", str(replayed)])  # fmt: skip
    assert _joint_travel_deg(replayed) > 0.1
    # a simulated skin that leaves its grid unset takes the model's
    _ok(["run", "--skin", "sim:speed=0,seed=7", "--model", str(grid.model), "--robot", "sim",
         "--headless", "--seconds", "5", "--trace", str(live)])  # fmt: skip
    assert _joint_travel_deg(live) > 0.1


def test_a_model_of_another_grid_is_one_line(grid: Grid) -> None:
    line = _refused(["replay", str(grid.recording)])  # the shipped 10x10 model
    assert f"model expects 10x10 frames at 200 Hz, got {grid.rows}x{grid.cols}" in line
    line = _refused(["run", "--skin", grid.sim, "--robot", "sim", "--headless",
                     "--seconds", "1"])  # fmt: skip
    assert f"got {grid.rows}x{grid.cols}" in line and "trained for this skin" in line


def test_the_dashboard_draws_the_grid_and_its_perform_buttons_move_the_arm(grid, tmp_path):
    def opener(skin: str, robot: str):
        return open_session(skin, robot, model=grid.model, poses=tmp_path / "poses.toml")

    skin = f"sim:rows={grid.rows},cols={grid.cols},auto=0,seed=2"
    runner = DashboardRunner(opener, skin, "sim", record_dir=tmp_path / "rec")
    try:
        runner.start()
        assert wait_until(lambda: (runner.latest() or {"skin": {"calibrating": True}})["skin"][
            "calibrating"] is False)  # fmt: skip
        state = runner.latest()
        page_skin = state["skin"]
        assert (page_skin["rows"], page_skin["cols"]) == (grid.rows, grid.cols)
        assert len(page_skin["signal"]) == grid.rows * grid.cols
        corners = np.asarray(state["robot"]["skin_corners"])
        height_mm = 1000 * np.linalg.norm(corners[2] - corners[0])
        assert height_mm == pytest.approx(grid.rows * 14.0, abs=0.1)  # the layout's extent
        start = np.asarray(state["robot"]["q"])
        for _ in range(3):  # the simulated person performs on the skin of this grid
            runner.submit({"cmd": "perform", "gesture": "swipe_up"})
            moved = wait_until(
                lambda: np.abs(np.asarray(runner.latest()["robot"]["q"]) - start).max() > 0.005,
                timeout=8.0,
            )
            if moved:
                break
        assert moved, runner.latest()["messages"]
    finally:
        runner.close()


def test_a_serial_device_of_the_grid_drives_the_arm_from_its_info(grid, tmp_path) -> None:
    """A binary device declares its grid in INFO; ``serial:PORT`` sets none, so the session
    assumes the model's grid until INFO confirms it, and the arm follows the device."""
    layout = SkinLayout(grid.rows, grid.cols)
    stream = simulate_stream(12.0, seed=5, layout=layout, gestures=["swipe_up", "push"])
    device = FakeSkinDevice(stream.frames, layout=layout, device_id="grid-skin").start()
    session = open_session(f"serial:{device.port}", "sim", model=grid.model,
                           poses=tmp_path / "poses.toml")  # fmt: skip
    try:
        session.start()
        start: np.ndarray | None = None

        def moved() -> bool:
            session.step(timeout=0.02)
            robot = session.state.robot
            nonlocal start
            if robot is None:
                return False
            start = robot.q.copy() if start is None else start
            return float(np.abs(robot.q - start).max()) > 0.005

        assert wait_until(moved, timeout=30.0), session.state.last_error
        info = session.live_skin.info
        assert (info.rows, info.cols, info.device_id) == (grid.rows, grid.cols, "grid-skin")
        assert session.state.errors == 0, session.state.last_error
    finally:
        session.close()
        device.stop()


def test_a_device_of_another_grid_than_the_models_is_one_error_line(grid, tmp_path) -> None:
    device = FakeSkinDevice().start()  # a 10x10 device
    session = open_session(f"serial:{device.port}", "sim", model=grid.model,
                           poses=tmp_path / "poses.toml")  # fmt: skip
    try:
        session.start()
        assert wait_until(lambda: session.step(timeout=0.02) >= 0 and session.state.errors > 0)
        line = session.state.last_error
        assert line.startswith("skin frames dropped: the skin now streams 10x10 frames, the "
                               f"model expects {grid.rows}x{grid.cols}")  # fmt: skip
        assert "\n" not in line and session.state.robot is not None
        assert not session.state.robot.moving
    finally:
        session.close()
        device.stop()


@pytest.mark.parametrize("shape", GRIDS, ids=lambda g: f"{g[0]}x{g[1]}")
def test_a_guided_recording_on_a_serial_device_takes_its_grid_from_info(shape, tmp_path):
    """The serial source assumes 10x10 until INFO: the recording, opened before, is
    re-described from INFO (no frame was written yet) and holds the device's frames."""
    layout = SkinLayout(*shape)
    stream = simulate_stream(6.0, seed=5, layout=layout, gestures=["push"])
    device = FakeSkinDevice(stream.frames, layout=layout, device_id="grid-skin").start()
    out = tmp_path / "guided.wsrec"
    try:
        _ok(["record", "--out", str(out), "--skin", f"serial:{device.port}", "--gestures",
             "push", "--trials", "1", "--invalid-trials", "0", "--countdown", "0.3",
             "--trial-seconds", "0.5"])  # fmt: skip
    finally:
        device.stop()
    recording = read_recording(out)
    assert (recording.info.rows, recording.info.cols) == shape
    assert recording.info.device_id == "grid-skin" and len(recording.frames) > 0
    assert recording.frames.shape[1:] == shape and [lab.label for lab in recording.labels] == [
        "push"
    ]
    assert any(a.stream == "source" for a in recording.annotations)  # kept across the change


def test_the_recording_is_re_described_only_before_its_first_frame(tmp_path) -> None:
    path = tmp_path / "r.wsrec"
    with RecordingWriter(path, SkinInfo()) as writer:
        writer.add_annotation("source", 0.0, {"kind": "connected"})
        writer.change_info(SkinInfo(rows=8, cols=8, device_id="d"))
        writer.append_frames(np.arange(3), np.arange(3) / 200, np.ones((3, 8, 8)))
        with pytest.raises(ValueError, match="already holds frames of a 8x8 skin"):
            writer.change_info(SkinInfo(rows=16, cols=12))
    recording = read_recording(path)
    assert (recording.info.rows, recording.info.cols, recording.info.device_id) == (8, 8, "d")
    assert len(recording.frames) == 3 and len(recording.annotations) == 1
    assert not recording.warnings
