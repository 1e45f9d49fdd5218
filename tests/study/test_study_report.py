"""The report end to end on a synthetic study: tables, statistics, PNGs, HTML, warnings."""

from __future__ import annotations

import shutil

import pytest
from paths import is_png

from wovenskin.outputs import OutputExistsError
from wovenskin.study.report import SYNTHETIC_BANNER, write_report
from wovenskin.study.synthetic import synthetic_study


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    folder = tmp_path_factory.mktemp("study")
    synthetic_study(folder, participants=6, seed=1, trials=1)
    shutil.rmtree(folder / "trials" / "S02" / "pour-pendant-1")  # a participant without it
    (folder / "trials" / "S03" / "pour-skin-1" / "trial.json").unlink()  # a killed trial
    return folder


@pytest.mark.slow
def test_the_report_has_the_papers_tables_statistics_and_plots(study, tmp_path):
    report = write_report(study, tmp_path / "out")
    md = report.markdown.read_text()
    assert md.startswith("# Study report: synthetic demo (seed 1)\n\n" + SYNTHETIC_BANNER)
    assert report.synthetic
    for heading in ("## Task: pick_place", "## Task: pour", "## Questionnaires"):
        assert heading in md
    header = "| interface | expertise | participants | trials | time (s) | commands | success |"
    assert md.count(header) == 2
    assert "| skin | novice | 3 | 3 |" in md  # pick_place: every novice once
    assert "| skin | novice | 2 | 2 |" in md  # pour: S03's trial is incomplete
    assert "| skin vs keyboard | all |" in md and "| skin vs pendant | expert |" in md
    assert "Friedman test of time over n = 6 participants" in md  # pick_place
    assert "Friedman test of time over n = 4 participants" in md  # pour: S02, S03 lack one
    assert "too few for a test" in md  # pour: 4-5 pairs
    assert "NASA-TLX raw" in md and "SUS" in md
    assert len(report.warnings) == 1 and "S03/pour-skin-1: incomplete" in report.warnings[0]
    assert "S03/pour-skin-1: incomplete" in md
    names = sorted(p.name for p in report.images)
    assert names == ["pick_place-box.png", "pick_place-paths.png", "pour-box.png", "pour-paths.png"]
    for path in report.images:
        assert is_png(path)
        assert f"]({path.name})" in md
    page = report.html.read_text()
    assert page.count("data:image/png;base64,") == 4 and "<table>" in page
    assert "<strong>SYNTHETIC DATA" in page
    with pytest.raises(OutputExistsError):
        write_report(study, tmp_path / "out")
    write_report(study, tmp_path / "out", overwrite=True)
