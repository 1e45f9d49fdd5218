"""The recognition part of ``wovenskin reproduce``: run at the TINY preset, and its pieces."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from paths import PNG_SIGNATURE, is_png

from wovenskin.recording.formats import LabelledCaptures, write_labelled_captures
from wovenskin.reproduce import recognition_runs as runs
from wovenskin.reproduce.recognition import (
    ACCURACY_COLUMNS,
    PAPER,
    TINY,
    _bilstm_verdict,
    _transformer_verdict,
    haart_blocks,
    recognition_section,
)
from wovenskin.study.document import Image, Table, Text, to_html, to_markdown


@pytest.fixture(scope="module")
def section(tmp_path_factory):
    out = tmp_path_factory.mktemp("reproduce-recognition")
    messages: list[str] = []
    blocks, figures = recognition_section(out, TINY, log=messages.append)
    return out, blocks, figures, messages


def _texts(blocks) -> list[str]:
    return [b.text for b in blocks if isinstance(b, Text)]


@pytest.mark.slow
def test_pngs_exist_and_every_image_is_one(section):
    out, blocks, figures, _ = section
    images = [b for b in blocks if isinstance(b, Image)]
    assert len(images) == 4  # both models x both splits; no HAART at TINY
    assert sorted(b.path for b in images) == sorted(figures["png"].values())
    for image in images:
        data = (out / image.path).read_bytes()
        assert data.startswith(PNG_SIGNATURE) and len(data) > 1000
    html = to_html(blocks, "recognition", out)  # embeds every PNG: fails on a missing one
    assert html.count("data:image/png;base64,") == 4
    assert to_markdown(blocks).startswith("## Recognition")


@pytest.mark.slow
def test_accuracies_are_measured_fractions_on_the_tiny_data(section):
    _, _, figures, _ = section
    c = TINY
    assert figures["dataset"]["windows"] == c.people * (
        c.windows_per_person + c.invalid_windows_per_person
    )
    assert figures["dataset"]["people"] == c.people
    for model in ("transformer", "bilstm"):
        for split in ("random", "grouped"):
            score = figures[model][split]
            assert 0.0 <= score["accuracy"] <= 1.0 and 0.0 <= score["macro_f1"] <= 1.0
            assert score["n_val"] == figures["dataset"]["splits"][split]["n_val"] > 0
            assert score["epochs_run"] == c.epochs
        assert figures[model]["latency_ms"] > 0 and figures[model]["params"] > 1000
    ratio = figures["transformer"]["latency_ms"] / figures["bilstm"]["latency_ms"]
    assert figures["latency_ratio"] == pytest.approx(ratio)


@pytest.mark.slow
def test_tables_name_both_models_beside_the_paper(section):
    _, blocks, figures, _ = section
    table = next(b for b in blocks if isinstance(b, Table) and b.header == ACCURACY_COLUMNS)
    names = [row[0] for row in table.rows]
    assert any("transformer" in n for n in names) and any("BiLSTM" in n for n in names)
    assert [row[4] for row in table.rows] == ["near 100 %", "96.7 %"]
    measured = f"{100 * figures['bilstm']['random']['accuracy']:.1f} %"
    assert any("96.7 %" in t and measured in t for t in _texts(blocks))
    stream_table = next(b for b in blocks if isinstance(b, Table) and "event F1" in b.header)
    assert [row[0] for row in stream_table.rows][-1] == "shipped default model"
    assert len(stream_table.rows) == 3


def _text_beside(blocks, i: int, step: int) -> str:
    """The nearest Text before (step -1) or after (step 1) block i, past tables and images."""
    j = i + step
    while 0 <= j < len(blocks) and isinstance(blocks[j], Table | Image):
        j += step
    return blocks[j].text if 0 <= j < len(blocks) and isinstance(blocks[j], Text) else ""


@pytest.mark.slow
def test_every_table_and_image_has_its_command_beside_it(section):
    _, blocks, _, _ = section
    for i, block in enumerate(blocks):
        if isinstance(block, Table | Image):
            beside = _text_beside(blocks, i, -1) + _text_beside(blocks, i, 1)
            assert "`" in beside, f"no command or API call beside block {i}: {block}"
    texts = " ".join(_texts(blocks))
    for needle in ("compare_models(", "generate_sim_dataset(", "run_recognition_benchmark("):
        assert needle in texts
    assert f"seed={TINY.seed}" in texts and f"n_recordings={TINY.people}" in texts


@pytest.mark.slow
def test_streams_and_robustness_are_scored(section):
    _, _, figures, messages = section
    for model in ("transformer", "bilstm"):
        assert figures[model]["streams"]["streams"] == TINY.streams
        assert figures[model]["streams"]["events"] > 0
    shipped = figures["shipped"]
    assert shipped["streams"]["events"] == figures["transformer"]["streams"]["events"]
    assert 0.0 <= shipped["streams"]["f1"] <= 1.0
    robustness = shipped["robustness"]
    assert list(robustness["conditions"]) == list(TINY.conditions)
    assert robustness["streams_per_condition"] == TINY.robustness_streams
    assert robustness["pooled"]["events"] > 0
    assert any("robustness" in m for m in messages)


@pytest.mark.slow
def test_haartless_run_says_how_to_run_it_and_figures_are_json(section):
    _, blocks, figures, _ = section
    assert figures["haart"] is None
    assert any("Not run" in t and "--lopo" in t and "haart" in t for t in _texts(blocks))
    assert json.loads(json.dumps(figures, allow_nan=False)) == figures
    assert figures["paper"] == PAPER
    assert figures["config"]["people"] == TINY.people and figures["config"]["haart"] is None


def test_verdicts_say_plainly_when_the_paper_is_not_reproduced():
    assert "Differs" in _transformer_verdict(0.95) and "95.0 %" in _transformer_verdict(0.95)
    assert "reproduced" in _transformer_verdict(0.995)
    assert "Differs" in _bilstm_verdict(0.90) and "-6.7 points" in _bilstm_verdict(0.90)
    assert "reproduced" in _bilstm_verdict(0.97) and "96.7 %" in _bilstm_verdict(0.97)


def test_jsonable_drops_non_finite_and_numpy():
    value = {"a": np.float32(0.5), "b": float("nan"), "c": (np.int64(3), Path("x")), 1: None}
    assert runs.jsonable(value) == {"a": 0.5, "b": None, "c": [3, "x"], "1": None}


def test_stream_seeds_are_reproducible_and_distinct():
    assert runs.stream_seeds(4, 0) == runs.stream_seeds(4, 0)
    assert len(set(runs.stream_seeds(4, 0))) == 4
    assert runs.stream_seeds(4, 0) != runs.stream_seeds(4, 1)
    assert runs.stream_seeds(0, 0) == []


def _fake_haart(path: Path) -> None:
    """Two participants, two classes on a 10 x 10 grid at 54 Hz: a still press, a tap."""
    rng = np.random.default_rng(0)
    frames, labels, groups = [], [], []
    t = np.arange(120) / 54.0
    for person in ("p1", "p2"):
        for label in (0, 1):
            for _ in range(3):
                x = rng.integers(0, 5, size=(120, 10, 10)).astype(np.float64)
                r, c = rng.integers(0, 8, size=2)
                on = 1.0 if label == 0 else (np.sin(2 * np.pi * 3 * t) > 0).astype(float)
                x[:, r : r + 3, c : c + 3] += 300.0 * np.reshape(on, (-1, 1, 1))
                frames.append(x)
                labels.append(label)
                groups.append(person)
    captures = LabelledCaptures(
        frames=np.round(np.stack(frames)).astype(np.uint16),
        lengths=np.full(len(labels), 120, dtype=np.int64),
        labels=np.array(labels, dtype=np.int64),
        class_names=["constant", "pat"],
        groups=np.array(groups),
        sample_rate_hz=54.0,
    )
    write_labelled_captures(path, captures)


@pytest.mark.slow
def test_haart_part_on_synthetic_captures(tmp_path):
    path = tmp_path / "fake-haart.npz"
    _fake_haart(path)
    config = replace(TINY, haart=path, haart_epochs=1)
    result = runs.haart_lopo(config, tmp_path / "lopo", lambda _m: None)
    figures = {
        "haart": runs.jsonable(runs.haart_figures(result)),
        "png": runs.confusion_pngs(tmp_path, {}, result),
    }
    h = figures["haart"]
    assert sorted(h["participants"]) == ["p1", "p2"] and h["n_captures"] == 12
    assert 0.0 <= h["capture_accuracy"] <= 1.0 and h["epochs"] == 1
    assert is_png(tmp_path / figures["png"]["haart"])
    blocks = haart_blocks(config, figures)
    table = next(b for b in blocks if isinstance(b, Table))
    assert table.rows[0][1] == f"{100 * h['capture_accuracy']:.1f} %"
    assert any("79.1 %" in row[1] for row in table.rows)
    assert any("leave_one_participant_out(" in t for t in _texts(blocks))
    assert not any("Not run" in t for t in _texts(blocks))
