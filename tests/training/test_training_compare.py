"""Tests of wovenskin.training.compare: default data set, training on a split, comparison."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from rich.console import Console
from tiny_models import HPARAMS as TINY_TCN
from tiny_models import TINY_SIM_SET

from wovenskin.recognition.checkpoint_meta import read_meta
from wovenskin.training import runs
from wovenskin.training.compare import compare_models, train_on_dataset
from wovenskin.training.config import TrainConfig
from wovenskin.training.datasets import DatasetError, generate_sim_dataset, grouped_split
from wovenskin.training.history import EpochRecord, TrainEvent
from wovenskin.training.progress import TrainProgressDisplay
from wovenskin.training.report import dataset_fingerprint, evaluate_on_dataset
from wovenskin.training.runs import COMPARE_FILE, ensure_dataset

pytestmark = pytest.mark.slow  # trains models or builds data sets: `make test-fast` leaves it out

TINY_HPARAMS = {
    "transformer": {"n_layers": 1, "ff_dim": 32, "d_model": 16, "n_heads": 2, "stem_channels": 8},
    "bilstm": {"hidden": 16, "n_layers": 1},
    "tcn": TINY_TCN,
}
OPTIONS = TrainConfig(epochs=1, batch_size=32, threads=1, val_fraction=0.34)


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    return generate_sim_dataset(tmp_path_factory.mktemp("compare") / "ds", seed=5, **TINY_SIM_SET)


def test_ensure_dataset_builds_the_default_set_once(tmp_path, monkeypatch):
    default = tmp_path / "runs" / "datasets" / "sim-default"
    monkeypatch.setattr(runs, "DEFAULT_DATASET_DIR", default)
    builds = []

    def tiny_generate(path, workers, progress):
        builds.append(path)
        return generate_sim_dataset(path, seed=1, progress=progress, **TINY_SIM_SET)

    monkeypatch.setattr(runs, "generate_sim_dataset", tiny_generate)
    reports = []
    ds, built = ensure_dataset(None, progress=lambda done, total: reports.append((done, total)))
    assert built and builds == [default] and ds.path == default
    assert reports[-1] == (3, 3)
    again, built = ensure_dataset(None)
    assert not built and builds == [default] and len(again) == len(ds)
    with pytest.raises(DatasetError, match="no such data set directory"):
        ensure_dataset(tmp_path / "typo")


def test_train_on_dataset_records_data_and_split(data, tmp_path):
    result = train_on_dataset(
        data, tmp_path / "m", "grouped", replace(OPTIONS, model="tcn", hparams=TINY_HPARAMS["tcn"])
    )
    assert result.epochs_run == 1
    training = read_meta(tmp_path / "m").training_data
    assert training["dataset"]["fingerprint"] == dataset_fingerprint(data)
    split = training["split"]
    expected = grouped_split(data, val_fraction=0.34)
    assert split["name"] == "grouped" and split["n_val"] == expected.val.size
    assert training["training"]["n_train"] == expected.train.size
    assert result.validation.n == expected.val.size
    with pytest.raises(DatasetError, match="cannot train on split 'all'"):
        train_on_dataset(data, tmp_path / "x", "all", replace(OPTIONS, model="tcn"))


def test_compare_models_side_by_side(data, tmp_path):
    labels: set[str] = set()
    reported: list[tuple[str, str]] = []
    comparison = compare_models(
        data,
        tmp_path / "cmp",
        ["transformer", "bilstm", "tcn"],
        ["grouped", "random"],
        OPTIONS,
        TINY_HPARAMS,
        latency_repeats=5,
        progress=lambda label, event: labels.add(label),
        on_report=lambda model, split, report: reported.append((model, split)),
    )
    assert [row.model for row in comparison.rows] == ["transformer", "bilstm", "tcn"]
    assert labels == {f"{m} / {s}" for m in TINY_HPARAMS for s in ("grouped", "random")}
    assert len(reported) == 6
    for row in comparison.rows:
        assert row.params > 0 and 0 < row.latency_median_ms <= row.latency_p99_ms
        for split in ("grouped", "random"):
            score = row.scores[split]
            # the score is an ONNX Runtime evaluation of the saved checkpoint on its split
            again = evaluate_on_dataset(score.checkpoint_dir, data, split)
            assert again.accuracy == score.accuracy and again.seen_in_training == 0
            assert (
                tmp_path / "cmp" / split / row.model / f"eval-{split}" / "confusion.png"
            ).is_file()
    document = json.loads((tmp_path / "cmp" / COMPARE_FILE).read_text())
    assert document == json.loads(json.dumps(comparison.to_dict()))
    assert set(document["models"]["bilstm"]) >= {"params", "latency_median_ms", "grouped", "random"}
    console = Console(record=True, width=160)
    console.print(comparison.table())
    text = console.export_text()
    assert "grouped" in text and "random" in text and "bilstm" in text


def test_compare_scores_each_model_on_whole_streams(data, tmp_path):
    from wovenskin.recognition.event_scoring import score_stream
    from wovenskin.recognition.onnx_runtime import OnnxRecognizer
    from wovenskin.recognition.pipeline import (
        PipelineSettings,
        arbiter_settings_for_model,
        run_pipeline,
    )
    from wovenskin.sim.stream import simulate_stream

    stream = simulate_stream(8.0, seed=41)
    comparison = compare_models(
        data, tmp_path / "cmp", ["tcn"], ["grouped"], OPTIONS, {"tcn": TINY_HPARAMS["tcn"]},
        latency_repeats=3, streams=[stream],
    )  # fmt: skip
    assert comparison.recipe == "stream"  # the data set's own recipe, reported beside it
    row = comparison.rows[0]
    assert row.stream is not None and row.stream.n_streams == 1
    assert row.stream.n_events == int((stream.event_labels != "invalid").sum())
    # the figures are the live pipeline's on that stream, scored as eval-stream scores it
    recognizer = OnnxRecognizer(tmp_path / "cmp" / "grouped" / "tcn")
    settings = PipelineSettings(arbiter=arbiter_settings_for_model(recognizer))
    expected = score_stream(run_pipeline(stream, recognizer, settings).commands, stream)
    assert (row.stream.f1, row.stream.false_per_min) == (expected.f1, expected.false_per_min)
    document = json.loads((tmp_path / "cmp" / COMPARE_FILE).read_text())
    assert document["recipe"] == "stream" and document["models"]["tcn"]["streams"]["n_streams"] == 1
    console = Console(record=True, width=200)
    console.print(comparison.table())
    text = console.export_text()
    assert "event F1" in text and "stream recipe" in text


def test_compare_models_refuses_bad_requests(data, tmp_path):
    with pytest.raises(ValueError, match="unknown model"):
        compare_models(data, tmp_path, ["transformer", "gru"], config=OPTIONS)
    with pytest.raises(ValueError, match="not compared: tcn"):
        compare_models(data, tmp_path, ["bilstm"], config=OPTIONS, hparams=TINY_HPARAMS)
    with pytest.raises(DatasetError, match="unknown split"):
        compare_models(data, tmp_path, ["bilstm"], ["all"], config=OPTIONS)


def _record(epoch: int, val_accuracy: float, val_loss: float) -> EpochRecord:
    return EpochRecord(epoch, 1.0, 0.5, val_loss, val_accuracy, val_accuracy, 1e-3, 2.0)


def test_progress_display_marks_the_best_epochs():
    console = Console(record=True, width=200, force_terminal=False)
    with TrainProgressDisplay(console) as show:
        for epoch, acc, loss in [(1, 0.5, 1.0), (2, 0.7, 0.9), (3, 0.7, 0.95), (4, 0.7, 0.8)]:
            for batch in (1, 2):
                show("tcn / grouped", TrainEvent("batch", epoch, 4, batch, 2, 0.3))
            record = _record(epoch, acc, loss)
            show("tcn / grouped", TrainEvent("epoch", epoch, 4, 2, 2, 0.3, record))
        show(TrainEvent("epoch", 1, 1, 2, 2, 0.3, _record(1, 0.1, 2.0)))  # unlabelled run
    lines = [line for line in console.export_text().splitlines() if "epoch" in line]
    assert len(lines) == 5
    best = ["best" in line for line in lines]
    assert best == [True, True, False, True, True]  # a tie in accuracy needs a lower loss
    assert lines[1].startswith("tcn / grouped  epoch   2/4") and "val  70.00%" in lines[1]
    assert np.isclose(float(lines[0].split("loss ")[1].split()[0]), 1.0)
