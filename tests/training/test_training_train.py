"""Tests of wovenskin.training.train: metrics, training, early stopping, resume, budget."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st
from paths import is_png

from wovenskin.recognition.checkpoint_meta import META_FILE, ONNX_FILE, WEIGHTS_FILE, read_meta
from wovenskin.recognition.onnx_runtime import OnnxRecognizer
from wovenskin.training import train as train_module
from wovenskin.training.checkpoint import load_checkpoint
from wovenskin.training.config import TrainConfig
from wovenskin.training.history import CURVE_FILE, HISTORY_FILE, TrainEvent, write_history
from wovenskin.training.metrics import ClassificationMetrics, ClassScore, classification_metrics
from wovenskin.training.models import build_model
from wovenskin.training.run_meta import checkpoint_meta_for
from wovenskin.training.scoring import evaluate
from wovenskin.training.train import STATE_FILE, fit_input_scale

pytestmark = pytest.mark.slow  # trains models or builds data sets: `make test-fast` leaves it out

CLASSES = ("slide_right", "slide_down", "press")
ROWS, COLS, WINDOW = 6, 8, 16
DATA_META = {
    "sample_rate_hz": 200.0,
    "conditioning": {"smoothing_s": 0.1, "spike_filter": True},
    "grid": {"rows": ROWS, "cols": COLS, "row_pitch_mm": 14.0, "col_pitch_mm": 10.0},
    "window": WINDOW,
    "source": "synthetic moving blobs",
}
SMALL_TRANSFORMER = {"n_layers": 2, "ff_dim": 64}


def train_model(
    model_name, windows, labels, class_names, train_idx, val_idx, out_dir, meta,
    progress=None, **settings,
):  # fmt: skip
    """:func:`~wovenskin.training.train.train_model` with its settings as keywords."""
    config = TrainConfig(model=model_name, **settings)
    return train_module.train_model(
        windows, labels, class_names, train_idx, val_idx, out_dir, meta, config, progress
    )


def moving_blobs(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Windows of a Gaussian blob that slides right, slides down or presses in place."""
    rng = np.random.default_rng(seed)
    labels = rng.integers(0, len(CLASSES), n)
    t = np.linspace(0.0, 1.0, WINDOW)[None, :]
    r0 = rng.uniform(1.5, ROWS - 2.5, (n, 1))
    c0 = rng.uniform(1.5, COLS - 2.5, (n, 1))
    travel = rng.uniform(2.0, 3.5, (n, 1))
    amplitude = rng.uniform(0.05, 0.3, (n, 1))
    right, down, press = (labels == k for k in range(3))
    row = r0 + down[:, None] * travel * (t - 0.5)
    col = c0 + right[:, None] * travel * (t - 0.5)
    strength = amplitude * np.where(press[:, None], 0.2 + 0.8 * t, 1.0)
    width = rng.uniform(0.6, 1.0, (n, 1, 1, 1))
    rr = np.arange(ROWS)[None, None, :, None]
    cc = np.arange(COLS)[None, None, None, :]
    distance2 = (rr - row[:, :, None, None]) ** 2 + (cc - col[:, :, None, None]) ** 2
    windows = strength[:, :, None, None] * np.exp(-distance2 / (2 * width**2))
    windows += rng.normal(0.0, 0.003, windows.shape)
    return windows.astype(np.float32), labels.astype(np.int64)


def _arguments(data, **settings) -> dict:
    """The keywords of a training run on ``data`` (the fixture below), with ``settings``."""
    run = dict(zip(("windows", "labels", "train_idx", "val_idx"), data, strict=True))
    return run | {"class_names": CLASSES, "meta": DATA_META} | settings


@pytest.fixture(scope="module")
def data() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    windows, labels = moving_blobs(360, seed=0)
    return windows, labels, np.arange(0, 270), np.arange(270, 360)


# --------------------------------------------------------------------------- metrics


def test_classification_metrics_by_hand() -> None:
    y_true = np.array([0, 0, 0, 1, 1, 2])
    y_pred = np.array([0, 0, 1, 1, 2, 2])
    m = classification_metrics(y_true, y_pred, ["a", "b", "c"])
    assert m.n == 6
    assert m.accuracy == pytest.approx(4 / 6)
    assert m.confusion == [[2, 1, 0], [0, 1, 1], [0, 0, 1]]
    a, b, c = m.per_class
    assert (a.precision, a.recall, a.support) == (1.0, pytest.approx(2 / 3), 3)
    assert a.f1 == pytest.approx(0.8)
    assert (b.precision, b.recall, b.f1) == (0.5, 0.5, 0.5)
    assert (c.precision, c.recall) == (0.5, 1.0)
    assert c.f1 == pytest.approx(2 / 3)
    assert m.macro_f1 == pytest.approx((0.8 + 0.5 + 2 / 3) / 3)
    d = json.loads(json.dumps(m.to_dict()))
    assert d["class_names"] == ["a", "b", "c"]
    assert d["per_class"][0]["name"] == "a"


def test_absent_classes_do_not_enter_macro_f1() -> None:
    m = classification_metrics(np.array([0, 0, 1]), np.array([0, 0, 1]), ["a", "b", "c"])
    assert m.macro_f1 == 1.0
    assert m.per_class[2] == ClassScore("c", 0.0, 0.0, 0.0, 0)


def test_classification_metrics_refuses_bad_input() -> None:
    with pytest.raises(ValueError, match="3 labels but 2 predictions"):
        classification_metrics(np.zeros(3, int), np.zeros(2, int), ["a", "b"])
    with pytest.raises(ValueError, match=r"predictions must lie in \[0, 2\)"):
        classification_metrics(np.zeros(3, int), np.array([0, 1, 2]), ["a", "b"])


@settings(max_examples=60, deadline=None)
@given(pairs=st.lists(st.tuples(st.integers(0, 4), st.integers(0, 4)), min_size=1, max_size=60))
def test_classification_metrics_match_their_definitions(pairs: list[tuple[int, int]]) -> None:
    y_true = np.array([p[0] for p in pairs])
    y_pred = np.array([p[1] for p in pairs])
    m = classification_metrics(y_true, y_pred, list("abcde"))
    assert m.accuracy == pytest.approx(np.mean(y_true == y_pred))
    assert sum(map(sum, m.confusion)) == len(pairs)
    f1s = []
    for k, score in enumerate(m.per_class):
        tp = int(np.sum((y_true == k) & (y_pred == k)))
        fp = int(np.sum((y_true != k) & (y_pred == k)))
        fn = int(np.sum((y_true == k) & (y_pred != k)))
        precision = tp / (tp + fp) if tp + fp else 0.0
        recall = tp / (tp + fn) if tp + fn else 0.0
        f1 = 2 * tp / (2 * tp + fp + fn) if tp + fp + fn else 0.0
        assert score.precision == pytest.approx(precision)
        assert score.recall == pytest.approx(recall)
        assert score.f1 == pytest.approx(f1)
        assert score.support == tp + fn
        if tp + fp + fn:
            f1s.append(f1)
    assert m.macro_f1 == pytest.approx(np.mean(f1s))


# --------------------------------------------------------------------------- training


def test_transformer_learns_moving_blobs_and_exports(tmp_path: Path, data) -> None:
    windows, labels, _, val_idx = data
    events: list[TrainEvent] = []
    result = train_model(
        "transformer",
        out_dir=tmp_path,
        progress=events.append,
        **_arguments(
            data,
            windows=windows.astype(np.float16),
            epochs=10,
            batch_size=16,
            lr=2e-3,
            seed=0,
            patience=4,
        ),
    )
    assert result.best_val_accuracy >= 0.95, [r.val_accuracy for r in result.history]
    assert result.stop_reason in ("completed", "early_stopping")
    assert result.validation.accuracy == result.best_val_accuracy
    assert {p.name for p in tmp_path.iterdir()} == {
        META_FILE, WEIGHTS_FILE, ONNX_FILE, STATE_FILE, HISTORY_FILE, CURVE_FILE
    }  # fmt: skip
    # every run keeps its history and learning curve beside the weights
    history = json.loads((tmp_path / HISTORY_FILE).read_text())
    assert [e["epoch"] for e in history["epochs"]] == [r.epoch for r in result.history]
    assert history["epochs"][-1]["val_accuracy"] == result.history[-1].val_accuracy
    assert is_png(tmp_path / CURVE_FILE)
    write_history(tmp_path, result.history, "transformer", extra={"stream_f1": 0.5})
    assert json.loads((tmp_path / HISTORY_FILE).read_text())["extra"] == {"stream_f1": 0.5}

    epoch_events = [e for e in events if e.kind == "epoch"]
    assert [e.epoch for e in epoch_events] == [r.epoch for r in result.history]
    batch_events = [e for e in events if e.kind == "batch" and e.epoch == 1]
    assert [e.batch for e in batch_events] == list(range(1, 18))  # ceil(270 / 16)
    assert all(e.batches == 17 for e in batch_events)

    meta = read_meta(tmp_path)
    assert meta.class_names == CLASSES
    assert (meta.rows, meta.cols, meta.window, meta.sample_rate_hz) == (ROWS, COLS, WINDOW, 200.0)
    assert (meta.row_pitch_mm, meta.col_pitch_mm) == (14.0, 10.0)
    assert meta.conditioning == DATA_META["conditioning"]
    assert meta.hparams["d_model"] == 64 and meta.hparams["n_layers"] == 4
    assert meta.training_data["source"] == "synthetic moving blobs"
    assert meta.training_data["training"]["n_train"] == 270
    assert meta.metrics["best_epoch"] == result.best_epoch
    assert meta.metrics["val_accuracy"] == pytest.approx(result.best_val_accuracy)
    assert meta.metrics["validation"]["confusion"] == result.validation.confusion

    # the exported graph scores the validation windows as the torch model does
    recognizer = OnnxRecognizer(tmp_path)
    onnx_metrics = evaluate(recognizer, windows, labels, indices=val_idx)
    model, _ = load_checkpoint(tmp_path)
    torch_metrics = evaluate(model, windows, labels, CLASSES, indices=val_idx)
    assert isinstance(onnx_metrics, ClassificationMetrics)
    assert onnx_metrics.confusion == torch_metrics.confusion
    assert onnx_metrics.accuracy == pytest.approx(result.best_val_accuracy)


@pytest.mark.parametrize("name", ["bilstm", "tcn"])
def test_baselines_train_end_to_end(tmp_path: Path, data, name: str) -> None:
    windows = data[0]
    result = train_model(
        name,
        out_dir=tmp_path,
        **_arguments(
            data,
            epochs=6,
            batch_size=32,
            lr=3e-3,
            seed=1,
            patience=6,
            hparams={"hidden": 32, "n_layers": 1} if name == "bilstm" else {"dim": 32},
        ),
    )
    assert result.epochs_run == 6 and result.stop_reason == "completed"
    assert result.history[-1].train_loss < result.history[0].train_loss
    assert result.best_val_accuracy > 0.5  # chance is 1/3
    assert OnnxRecognizer(tmp_path).predict_proba(windows[:4]).shape == (4, 3)


class Interrupted(Exception):
    pass


def _stop_after(epoch: int):
    def progress(event: TrainEvent) -> None:
        if event.kind == "epoch" and event.epoch == epoch:
            raise Interrupted

    return progress


def test_resume_gives_the_same_weights_as_an_uninterrupted_run(tmp_path: Path, data) -> None:
    arguments = _arguments(
        data, epochs=4, batch_size=32, lr=2e-3, seed=3, patience=10, hparams=SMALL_TRANSFORMER
    )
    whole = train_model("transformer", out_dir=tmp_path / "whole", **arguments)
    with pytest.raises(Interrupted):
        train_model("transformer", out_dir=tmp_path / "split", progress=_stop_after(2), **arguments)
    state = torch.load(tmp_path / "split" / STATE_FILE, weights_only=True)["progress"]
    assert state["epoch"] == 2 and state["stop_reason"] is None
    resumed = train_model("transformer", out_dir=tmp_path / "split", resume=True, **arguments)
    assert resumed.resumed_from_epoch == 3
    assert [r.epoch for r in resumed.history] == [1, 2, 3, 4]
    assert [r.val_loss for r in resumed.history] == [r.val_loss for r in whole.history]
    whole_state = torch.load(tmp_path / "whole" / STATE_FILE, weights_only=True)["model"]
    resumed_state = torch.load(tmp_path / "split" / STATE_FILE, weights_only=True)["model"]
    for key, value in whole_state.items():
        assert torch.equal(value, resumed_state[key]), key
    best_whole = torch.load(tmp_path / "whole" / WEIGHTS_FILE, weights_only=True)
    best_resumed = torch.load(tmp_path / "split" / WEIGHTS_FILE, weights_only=True)
    assert all(torch.equal(v, best_resumed[k]) for k, v in best_whole.items())

    # resuming a finished run only re-exports it
    again = train_model("transformer", out_dir=tmp_path / "split", resume=True, **arguments)
    assert again.epochs_run == 4 and again.resumed_from_epoch == 5
    # resuming with other settings is refused
    with pytest.raises(ValueError, match="trained with batch_size=32, this run asks for 16"):
        train_model(
            "transformer",
            out_dir=tmp_path / "split",
            resume=True,
            **(arguments | {"batch_size": 16}),
        )


def test_time_budget_stops_after_one_epoch_and_can_be_resumed(tmp_path: Path, data) -> None:
    arguments = _arguments(
        data,
        out_dir=tmp_path,
        epochs=3,
        batch_size=64,
        lr=2e-3,
        seed=0,
        patience=5,
        hparams={"dim": 16},
    )
    result = train_model("tcn", time_budget_s=0.0, **arguments)
    assert result.epochs_run == 1 and result.stop_reason == "time_budget"
    assert (tmp_path / ONNX_FILE).is_file()
    assert read_meta(tmp_path).metrics["stop_reason"] == "time_budget"
    resumed = train_model("tcn", resume=True, **arguments)
    assert resumed.epochs_run == 3 and resumed.stop_reason == "completed"


def test_early_stopping_keeps_the_best_epoch(
    tmp_path: Path, data, monkeypatch: pytest.MonkeyPatch
) -> None:
    accuracies = iter([0.5, 0.7, 0.6, 0.7, 0.65, 0.9])
    real_validate = train_module._validate
    best_weights = {}

    def scripted_validate(model, *args):
        loss, metrics = real_validate(model, *args)
        accuracy = next(accuracies)
        if accuracy == 0.7 and not best_weights:
            best_weights.update({k: v.clone() for k, v in model.state_dict().items()})
        return 1.0, metrics.__class__(**{**metrics.__dict__, "accuracy": accuracy})

    monkeypatch.setattr(train_module, "_validate", scripted_validate)
    result = train_model(
        "tcn",
        out_dir=tmp_path,
        **_arguments(
            data, epochs=6, batch_size=64, lr=1e-3, seed=0, patience=2, hparams={"dim": 16}
        ),
    )
    # epoch 4 ties epoch 2 without a lower loss: no improvement, so patience ends at epoch 4
    assert result.stop_reason == "early_stopping"
    assert result.epochs_run == 4 and result.best_epoch == 2
    assert result.best_val_accuracy == 0.7
    saved = torch.load(tmp_path / WEIGHTS_FILE, weights_only=True)
    assert all(torch.equal(v, saved[k]) for k, v in best_weights.items())


def test_same_seed_same_model_and_global_settings_restored(tmp_path: Path, data) -> None:
    train_idx = data[2]
    threads = torch.get_num_threads()
    deterministic = torch.are_deterministic_algorithms_enabled()
    runs = []
    for name in ("a", "b"):
        train_model(
            "bilstm",
            out_dir=tmp_path / name,
            **_arguments(
                data,
                train_idx=train_idx[:96],
                epochs=1,
                batch_size=32,
                seed=5,
                hparams={"hidden": 16, "n_layers": 1},
            ),
        )
        runs.append(torch.load(tmp_path / name / WEIGHTS_FILE, weights_only=True))
    assert all(torch.equal(v, runs[1][k]) for k, v in runs[0].items())
    assert torch.get_num_threads() == threads
    assert torch.are_deterministic_algorithms_enabled() == deterministic


def test_memory_mapped_float16_windows(tmp_path: Path, data) -> None:
    windows, labels, _, _ = data
    mapped = np.lib.format.open_memmap(
        tmp_path / "windows.npy", mode="w+", dtype=np.float16, shape=windows.shape
    )
    mapped[:] = windows
    mapped.flush()
    readonly = np.load(tmp_path / "windows.npy", mmap_mode="r")
    result = train_model(
        "tcn",
        out_dir=tmp_path / "ckpt",
        **_arguments(data, windows=readonly, epochs=1, batch_size=64, hparams={"dim": 16}),
    )
    assert result.epochs_run == 1
    model, _ = load_checkpoint(tmp_path / "ckpt")
    assert evaluate(model, readonly, labels, CLASSES).n == len(labels)


def test_input_scale_is_the_median_window_peak(data) -> None:
    windows, _, train_idx, _ = data
    peaks = np.abs(windows[train_idx]).reshape(train_idx.size, -1).max(axis=1)
    assert fit_input_scale(windows, train_idx, seed=0) == pytest.approx(np.median(peaks))
    assert fit_input_scale(np.zeros((4, 2, 2, 2)), np.arange(4), seed=0) == 1.0


def test_bad_training_input_is_refused(tmp_path: Path, data) -> None:
    windows, labels, train_idx, _ = data

    def run(**changes):
        arguments = _arguments(data, out_dir=tmp_path, epochs=1, hparams={"dim": 16})
        return train_model("tcn", **(arguments | changes))

    with pytest.raises(ValueError, match="both train_idx and val_idx"):
        run(val_idx=np.arange(260, 300))
    with pytest.raises(ValueError, match="val_idx is empty"):
        run(val_idx=np.array([], dtype=int))
    with pytest.raises(ValueError, match=r"labels must lie in \[0, 2\)"):
        run(class_names=CLASSES[:2])
    with pytest.raises(ValueError, match="labels must be integers"):
        run(labels=labels.astype(float))
    with pytest.raises(ValueError, match="outside"):
        run(train_idx=np.array([0, 9999]))
    with pytest.raises(ValueError, match="lacks sample_rate_hz"):
        run(meta={"conditioning": {}})
    with pytest.raises(ValueError, match="lacks conditioning"):
        run(meta={"sample_rate_hz": 200.0})
    with pytest.raises(ValueError, match="data set meta says 10x10 frames, windows are 6x8"):
        run(meta=DATA_META | {"grid": {"rows": 10, "cols": 10}})
    with pytest.raises(ValueError, match="unknown hyperparameter"):
        run(hparams={"depth": 3})
    with pytest.raises(ValueError, match="batch_size: Input should be greater than 0"):
        run(batch_size=0)
    with pytest.raises(ValueError, match="label_smoothing"):
        run(label_smoothing=1.0)
    poisoned = windows.copy()
    poisoned[train_idx[5], 3, 2, 2] = np.nan
    with pytest.raises(ValueError, match=f"window {train_idx[5]} contains NaN"):
        run(windows=poisoned)


def test_checkpoint_meta_for_reads_top_level_grid_keys() -> None:
    meta = checkpoint_meta_for(
        "tcn",
        {},
        CLASSES,
        (WINDOW, ROWS, COLS),
        {
            "sample_rate_hz": 54,
            "conditioning": None,
            "rows": ROWS,
            "cols": COLS,
            "class_names": list(CLASSES),
            "groups": np.array(["p1", "p2"]),
        },
    )
    assert meta.sample_rate_hz == 54.0 and meta.conditioning == {}
    assert meta.row_pitch_mm is None
    assert meta.training_data["groups"] == ["p1", "p2"]
    with pytest.raises(ValueError, match="other class names"):
        checkpoint_meta_for(
            "tcn",
            {},
            CLASSES,
            (WINDOW, ROWS, COLS),
            {"sample_rate_hz": 54, "conditioning": {}, "class_names": ["x", "y", "z"]},
        )
    with pytest.raises(ValueError, match="says 30-frame windows"):
        checkpoint_meta_for(
            "tcn",
            {},
            CLASSES,
            (WINDOW, ROWS, COLS),
            {"sample_rate_hz": 54, "conditioning": {}, "window": 30},
        )


def test_evaluate_needs_matching_labels(data) -> None:
    windows, labels, _, _ = data
    model = build_model("tcn", ROWS, COLS, WINDOW, 3, dim=16)
    with pytest.raises(ValueError, match="360 windows but 10 labels"):
        evaluate(model, windows, labels[:10])
    metrics = evaluate(model, windows[:5], labels[:5])
    assert metrics.class_names == ("class_0", "class_1", "class_2")
    with pytest.raises(ValueError, match="model gives 3 classes, 2 names given"):
        evaluate(model, windows[:5], labels[:5], ["a", "b"])
