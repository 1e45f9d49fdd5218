"""The report's figures: PNG files, and no path figure without a full participant."""

from __future__ import annotations

from paths import is_png

from wovenskin.study.plots import box_plots, trajectory_participant, trajectory_plot
from wovenskin.study.reader import read_trials
from wovenskin.study.recorder import TrialRecorder


def _trial(folder, participant, interface, n=1):
    rec = TrialRecorder(folder, participant, "novice", "pour", interface, n)
    rec.start(0.0)
    rec.command(0.5, interface, "x", "key")
    for i in range(5):
        rec.pose(0.5 + i, (0.1 * i, 0.05 * i, 0.3, 1, 0, 0, 0), 0.0)
    rec.finish(5.0, "success")


def test_box_plots_and_paths_are_pngs(tmp_path):
    for interface in ("skin", "keyboard"):
        _trial(tmp_path, "P2", interface)
    _trial(tmp_path, "P1", "skin")
    trials, _ = read_trials(tmp_path)
    assert trajectory_participant(trials, "pour", ["skin", "keyboard"]) == "P2"
    assert trajectory_participant(trials, "pour", ["skin", "pendant"]) is None
    assert trajectory_plot(trials, "pour", ["skin", "pendant"], tmp_path / "x.png") is None
    path, who = trajectory_plot(trials, "pour", ["skin", "keyboard"], tmp_path / "p.png")
    assert who == "P2" and is_png(path)
    box = box_plots(trials, "pour", ["skin", "keyboard"], tmp_path / "b.png", synthetic=True)
    assert is_png(box)
