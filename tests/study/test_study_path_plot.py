"""The report's top-view path plot stays readable for a path that is narrow in x (pouring
moves the cup mostly in y): its tick labels never overlap, and every path is in view."""

from __future__ import annotations

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg

from wovenskin.study.plots import trajectory_figure, trajectory_plot
from wovenskin.study.reader import TrialResult
from wovenskin.study.recorder import TrialRecorder

INTERFACES = ("skin", "keyboard", "pendant")


def pour_like_trials(study) -> list[TrialResult]:
    """One trial per interface whose TCP goes 7 cm in x and 42 cm in y (as a pour does)."""
    trials = []
    for k, interface in enumerate(INTERFACES):
        recorder = TrialRecorder(study, "P01", "novice", "pour", interface, 1)
        recorder.start(0.0)
        for i, (x, y) in enumerate([(0.52, -0.12), (0.52, 0.22), (0.45, 0.22), (0.45, -0.19)]):
            recorder.pose(0.1 * (i + 1), (x + 0.001 * k, y, 0.3, 1, 0, 0, 0), 0.0)
        recorder.finish(1.0, "success")
        trials.append(
            TrialResult("P01", "pour", interface, 1, recorder.folder, True, "novice", "success")
        )
    return trials


def overlapping(labels) -> list[tuple[str, str]]:
    boxes = [(t.get_text(), t.get_window_extent()) for t in labels if t.get_text()]
    pairs = zip(boxes, boxes[1:], strict=False)
    return [(a, b) for (a, box_a), (b, box_b) in pairs if box_a.overlaps(box_b)]


def test_the_tick_labels_of_a_narrow_path_do_not_overlap(tmp_path):
    trials = pour_like_trials(tmp_path)
    fig, who = trajectory_figure(trials, "pour", INTERFACES)
    assert who == "P01"
    FigureCanvasAgg(fig).draw()
    for ax in fig.axes:
        assert not overlapping(ax.get_xticklabels()), overlapping(ax.get_xticklabels())
        assert not overlapping(ax.get_yticklabels())
        (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
        assert x0 <= 0.45 and x1 >= 0.522 and y0 <= -0.19 and y1 >= 0.22
        assert np.isclose(x1 - x0, y1 - y0)  # the same scale both ways
    written = trajectory_plot(trials, "pour", INTERFACES, tmp_path / "pour-paths.png")
    assert written == (tmp_path / "pour-paths.png", "P01")
    assert (tmp_path / "pour-paths.png").stat().st_size > 0
