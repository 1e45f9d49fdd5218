"""Tests of wovenskin.training.report: splits, ONNX evaluation, leakage, report files."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from paths import is_png
from rich.console import Console
from tiny_models import HPARAMS as TINY_TCN
from tiny_models import TINY_SIM_SET

from wovenskin.recognition.checkpoint_meta import read_meta, write_meta
from wovenskin.recognition.onnx_runtime import OnnxRecognizer
from wovenskin.training.compare import train_on_dataset
from wovenskin.training.config import TrainConfig
from wovenskin.training.datasets import (
    DatasetError,
    generate_sim_dataset,
    grouped_split,
    open_dataset,
    random_split,
)
from wovenskin.training.metrics import classification_metrics
from wovenskin.training.report import (
    CONFUSION_JSON,
    CONFUSION_PNG,
    METRICS_FILE,
    DatasetSummary,
    confusion_document,
    dataset_fingerprint,
    dataset_split,
    evaluate_on_dataset,
    per_class_table,
    split_record,
    write_report,
)


@pytest.fixture(scope="module")
def data(tmp_path_factory):
    root = tmp_path_factory.mktemp("report")
    return generate_sim_dataset(root / "ds", seed=5, **TINY_SIM_SET)


@pytest.fixture(scope="module")
def checkpoint(data, tmp_path_factory) -> Path:
    """A tiny TCN trained one epoch on the grouped split (a third of the recordings)."""
    out = tmp_path_factory.mktemp("model") / "tcn"
    config = TrainConfig(
        model="tcn", hparams=TINY_TCN, epochs=1, batch_size=32, threads=1, val_fraction=0.34
    )
    train_on_dataset(data, out, "grouped", config)
    return out


def _copy_with_meta(ds, target: Path, **changes) -> Path:
    shutil.copytree(ds.path, target)
    meta = json.loads((target / "meta.json").read_text())
    meta.update(changes)
    (target / "meta.json").write_text(json.dumps(meta))
    return target


# -------------------------------------------------------------------------------- splits


def test_dataset_split_names(data):
    grouped = dataset_split(data, "grouped", seed=3)
    expected = grouped_split(data, seed=3)
    np.testing.assert_array_equal(grouped.val, expected.val)
    random = dataset_split(data, "random", seed=3)
    np.testing.assert_array_equal(random.val, random_split(data, seed=3).val)
    everything = dataset_split(data, "all")
    assert everything.train.size == 0
    np.testing.assert_array_equal(everything.val, np.arange(len(data)))
    with pytest.raises(DatasetError, match="unknown split 'leaky'"):
        dataset_split(data, "leaky")


def test_split_record_and_fingerprint(data, tmp_path):
    split = dataset_split(data, "grouped", val_fraction=0.34)
    record = split_record(data, "grouped", split, seed=0, val_fraction=0.34)
    assert record["dataset"]["n_windows"] == len(data)
    assert record["dataset"]["fingerprint"] == dataset_fingerprint(open_dataset(data.path))
    assert record["split"]["n_train"] + record["split"]["n_val"] == len(data)
    assert record["split"]["held_out"]["recording"] == 1
    other = generate_sim_dataset(tmp_path / "other", seed=6, **TINY_SIM_SET)
    assert dataset_fingerprint(other) != dataset_fingerprint(data)


# ---------------------------------------------------------------------------- evaluation


def test_evaluation_defaults_to_the_training_split_and_matches_onnx(data, checkpoint):
    report = evaluate_on_dataset(checkpoint, data)
    assert report.split == "grouped" and report.model_name == "tcn"
    val = grouped_split(data, val_fraction=0.34).val
    assert report.metrics.n == val.size
    predictions = OnnxRecognizer(checkpoint).predict(np.asarray(data.windows[val], np.float32))
    expected = classification_metrics(data.labels[val], predictions, data.class_names)
    assert report.metrics == expected
    assert report.seen_in_training == 0 and report.warnings == []
    d = report.to_dict()
    assert d["accuracy"] == expected.accuracy and d["n_windows"] == val.size
    json.dumps(d)


def test_evaluation_counts_windows_seen_in_training(data, checkpoint):
    trained = grouped_split(data, val_fraction=0.34)
    report = evaluate_on_dataset(checkpoint, data, "random", seed=1)
    scored = random_split(data, val_fraction=0.34, seed=1).val
    seen = np.intersect1d(trained.train, scored).size
    assert seen > 0 and report.seen_in_training == seen
    assert any("not a held-out score" in w for w in report.warnings)
    everything = evaluate_on_dataset(checkpoint, data, "all")
    assert everything.metrics.n == len(data)
    assert everything.seen_in_training == trained.train.size


def test_another_data_set_is_not_leakage(checkpoint, tmp_path):
    other = generate_sim_dataset(tmp_path / "other", seed=7, **TINY_SIM_SET)
    report = evaluate_on_dataset(checkpoint, other, "all")
    assert report.seen_in_training == 0 and report.warnings == []
    assert report.metrics.n == len(other)


def test_a_checkpoint_without_training_record_gets_a_warning(data, checkpoint, tmp_path):
    bare = tmp_path / "bare"
    shutil.copytree(checkpoint, bare)
    meta = read_meta(bare)
    write_meta(bare, meta.with_updates(training_data={}))
    report = evaluate_on_dataset(bare, data, "grouped")
    assert any("does not record its training data" in w for w in report.warnings)


def test_a_data_set_that_does_not_fit_the_model_is_refused(data, checkpoint, tmp_path):
    conditioning = {**data.meta["conditioning"], "smoothing_s": 0.05}
    other = _copy_with_meta(data, tmp_path / "cond", conditioning=conditioning)
    with pytest.raises(ValueError, match="other conditioning settings"):
        evaluate_on_dataset(checkpoint, other)
    renamed = ["tap", *data.class_names[1:]]
    other = _copy_with_meta(data, tmp_path / "classes", class_names=renamed)
    with pytest.raises(ValueError, match="has classes tap"):
        evaluate_on_dataset(checkpoint, other)
    with pytest.raises(ValueError, match="no checkpoint directory"):
        evaluate_on_dataset(tmp_path / "missing", data)


def test_evaluation_reports_progress(data, checkpoint):
    calls: list[tuple[int, int]] = []
    report = evaluate_on_dataset(
        checkpoint, data, "all", progress=lambda d, t: calls.append((d, t))
    )
    assert calls[0] == (0, report.metrics.n) and calls[-1] == (report.metrics.n,) * 2


# ------------------------------------------------------------------------------- writing


def test_write_report_files(data, checkpoint, tmp_path):
    report = evaluate_on_dataset(checkpoint, data, "all")
    files = write_report(report, tmp_path / "eval")
    assert files.metrics_json.name == METRICS_FILE and files.confusion_json.name == CONFUSION_JSON
    assert files.confusion_png.name == CONFUSION_PNG
    assert is_png(files.confusion_png)
    metrics = json.loads(files.metrics_json.read_text())
    assert metrics["accuracy"] == report.accuracy and metrics["split"] == "all"
    confusion = json.loads(files.confusion_json.read_text())
    counts = np.array(confusion["counts"])
    assert counts.shape == (15, 15) and counts.sum() == len(data)
    np.testing.assert_array_equal(counts.sum(axis=1), np.bincount(data.labels, minlength=15))
    rates = np.array(confusion["rates"])
    present = counts.sum(axis=1) > 0
    np.testing.assert_allclose(rates[present].sum(axis=1), 1.0, atol=1e-5)
    assert (rates[~present] == 0).all()


def test_confusion_document_and_table_by_hand():
    metrics = classification_metrics(
        np.array([0, 0, 0, 1, 1, 2]), np.array([0, 1, 1, 1, 1, 2]), ["up", "down", "idle"]
    )
    document = confusion_document(metrics)
    assert document["counts"] == [[1, 2, 0], [0, 2, 0], [0, 0, 1]]
    assert document["rates"][0] == pytest.approx([1 / 3, 2 / 3, 0.0], abs=1e-6)
    console = Console(record=True, width=120)
    console.print(per_class_table(metrics))
    text = console.export_text()
    assert "down (2)" in text  # "up" is most often mistaken for "down", twice
    assert "accuracy 66.67 %" in text


def test_dataset_summary(data):
    summary = DatasetSummary.of(data)
    assert summary.n_windows == len(data) == sum(summary.class_counts.values())
    assert (summary.recordings, summary.people, summary.skins) == (3, 3, 3)
    assert summary.bytes_on_disk > data.windows.nbytes
    assert "3 people, 3 skins" in summary.describe()
    console = Console(record=True, width=100)
    console.print(summary.table(data.class_names))
    assert "invalid" in console.export_text()
    json.dumps(summary.to_dict())
