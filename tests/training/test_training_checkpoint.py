"""Tests of wovenskin.training.checkpoint: save/load round trip, meta, input contract."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import torch

import wovenskin
from wovenskin.gestures import CLASS_NAMES
from wovenskin.recognition.checkpoint_meta import (
    META_FILE,
    ONNX_FILE,
    WEIGHTS_FILE,
    CheckpointError,
    CheckpointMeta,
    conditioning_differences,
    read_meta,
)
from wovenskin.signal.config import ConditioningConfig
from wovenskin.training.checkpoint import load_checkpoint, save_checkpoint
from wovenskin.training.models import build_model, resolve_hparams


def make_meta(**changes) -> CheckpointMeta:
    values = dict(
        model_name="tcn",
        hparams=resolve_hparams("tcn", {"dim": 32}),
        class_names=CLASS_NAMES,
        rows=10,
        cols=10,
        window=30,
        sample_rate_hz=200.0,
        conditioning=ConditioningConfig().to_dict(),
        row_pitch_mm=14.0,
        col_pitch_mm=10.0,
        training_data={"source": "simulated", "n_windows": 1000},
        metrics={"val_accuracy": 0.99},
    )
    values.update(changes)
    return CheckpointMeta(**values)


def make_model(meta: CheckpointMeta) -> torch.nn.Module:
    torch.manual_seed(0)
    model = build_model(
        meta.model_name, meta.rows, meta.cols, meta.window, meta.n_classes, **meta.hparams
    )
    model.set_input_scale(0.3)
    return model


def test_save_and_load_round_trip(tmp_path: Path) -> None:
    meta = make_meta()
    model = make_model(meta)
    written = save_checkpoint(tmp_path / "ckpt", model, meta)
    directory = tmp_path / "ckpt"
    assert {p.name for p in directory.iterdir()} == {META_FILE, WEIGHTS_FILE, ONNX_FILE}

    loaded, loaded_meta = load_checkpoint(directory)
    assert not loaded.training
    assert loaded_meta == written
    assert loaded_meta.torch_version == torch.__version__
    assert loaded_meta.wovenskin_version == wovenskin.__version__
    assert loaded_meta.created.endswith("+00:00")
    assert loaded_meta.class_names == CLASS_NAMES
    assert loaded_meta.metrics == {"val_accuracy": 0.99}
    assert float(loaded.input_scale) == pytest.approx(0.3)
    x = torch.randn(3, 30, 10, 10)
    model.eval()
    with torch.inference_mode():
        assert torch.equal(model(x), loaded(x))


def test_meta_json_is_plain_and_complete(tmp_path: Path) -> None:
    save_checkpoint(tmp_path, make_model(make_meta()), make_meta())
    data = json.loads((tmp_path / META_FILE).read_text())
    for key in (
        "model_name",
        "hparams",
        "class_names",
        "rows",
        "cols",
        "row_pitch_mm",
        "col_pitch_mm",
        "window",
        "sample_rate_hz",
        "conditioning",
        "training_data",
        "metrics",
        "torch_version",
        "wovenskin_version",
        "created",
        "format_version",
    ):
        assert key in data, key
    assert data["class_names"] == list(CLASS_NAMES)
    assert data["hparams"]["dim"] == 32
    assert data["conditioning"]["smoothing_s"] == ConditioningConfig().smoothing_s


def test_meta_dict_round_trip() -> None:
    meta = make_meta()
    assert CheckpointMeta.from_dict(json.loads(json.dumps(meta.to_dict()))) == meta


def test_check_input_accepts_the_training_input() -> None:
    meta = make_meta()
    meta.check_input(10, 10, 30, 200.0, ConditioningConfig())
    meta.check_input(10, 10, 30, 200.0 * (1 + 1e-5), ConditioningConfig().to_dict())


def test_check_input_refuses_another_grid_in_one_line() -> None:
    with pytest.raises(ValueError) as info:
        make_meta().check_input(6, 8, 30, 200.0, ConditioningConfig())
    assert str(info.value) == (
        "model expects 10x10 frames at 200 Hz, got 6x8 at 200 Hz: use a model trained for "
        "this skin (docs/skins.md)"
    )


def test_check_input_refuses_another_rate_window_or_conditioning() -> None:
    meta = make_meta()
    with pytest.raises(
        ValueError, match=r"^model expects 10x10 frames at 200 Hz, got 10x10 at 54 Hz: use a "
    ):
        meta.check_input(10, 10, 30, 54.0, ConditioningConfig())
    with pytest.raises(ValueError, match="^model expects windows of 30 frames, got 20$"):
        meta.check_input(10, 10, 20, 200.0, ConditioningConfig())
    other = ConditioningConfig(smoothing_s=0.05)
    with pytest.raises(ValueError, match="smoothing_s: model 0.1, input 0.05") as info:
        meta.check_input(10, 10, 30, 200.0, other)
    assert "\n" not in str(info.value)


def test_conditioning_differences_lists_changed_missing_and_extra_keys() -> None:
    lines = conditioning_differences({"a": 1.0, "b": True, "c": [1, 2]}, {"a": 1, "b": 1, "d": 2})
    assert lines == [
        "b: model True, input 1",
        "c: model [1, 2], input unset",
        "d: model unset, input 2",
    ]
    assert conditioning_differences({"x": 0.1 + 0.2}, {"x": 0.3}) == []


def test_meta_validation() -> None:
    with pytest.raises(ValueError, match="at least 2 classes"):
        make_meta(class_names=("only",))
    with pytest.raises(ValueError, match="duplicate"):
        make_meta(class_names=("a", "a"))
    with pytest.raises(ValueError, match="sample rate"):
        make_meta(sample_rate_hz=0.0)
    with pytest.raises(ValueError, match="bad input shape"):
        make_meta(window=0)


def test_save_refuses_a_model_that_does_not_match_its_meta(tmp_path: Path) -> None:
    meta = make_meta()
    model = make_model(meta)
    with pytest.raises(ValueError, match="meta says 6x8"):
        save_checkpoint(tmp_path, model, make_meta(rows=6, cols=8))
    with pytest.raises(ValueError, match="meta names model 'bilstm' but the model is a"):
        save_checkpoint(tmp_path, model, make_meta(model_name="bilstm"))
    with pytest.raises(ValueError, match="meta says 10x10, 30 and 3"):
        save_checkpoint(tmp_path, model, make_meta(class_names=("a", "b", "c")))
    assert not any(tmp_path.iterdir())


def test_save_without_onnx_removes_a_stale_graph(tmp_path: Path) -> None:
    meta = make_meta()
    save_checkpoint(tmp_path, make_model(meta), meta)
    assert (tmp_path / ONNX_FILE).is_file()
    save_checkpoint(tmp_path, make_model(meta), meta, export_onnx=False)
    assert not (tmp_path / ONNX_FILE).exists()
    assert not [p for p in tmp_path.iterdir() if p.name.endswith(".tmp")]


def test_read_meta_errors_are_one_line(tmp_path: Path) -> None:
    with pytest.raises(CheckpointError, match="no checkpoint directory"):
        read_meta(tmp_path / "absent")
    with pytest.raises(CheckpointError, match="has no meta.json"):
        read_meta(tmp_path)
    path = tmp_path / META_FILE
    path.write_text("{not json")
    with pytest.raises(CheckpointError, match="cannot read"):
        read_meta(tmp_path)
    path.write_text("[1, 2]")
    with pytest.raises(CheckpointError, match="must be a JSON object"):
        read_meta(tmp_path)
    data = make_meta().to_dict()
    del data["conditioning"]
    path.write_text(json.dumps(data))
    with pytest.raises(CheckpointError, match="lacks conditioning"):
        read_meta(tmp_path)
    data = make_meta().to_dict() | {"format_version": 99}
    path.write_text(json.dumps(data))
    with pytest.raises(CheckpointError, match="format version 99"):
        read_meta(tmp_path)
    data = make_meta().to_dict() | {"rows": "ten"}
    path.write_text(json.dumps(data))
    with pytest.raises(CheckpointError, match="bad checkpoint meta"):
        read_meta(tmp_path)
    data = make_meta().to_dict() | {"hparams": [1]}
    path.write_text(json.dumps(data))
    with pytest.raises(CheckpointError, match="hparams must be an object"):
        read_meta(tmp_path)


def test_load_checkpoint_errors(tmp_path: Path) -> None:
    meta = make_meta()
    save_checkpoint(tmp_path, make_model(meta), meta, export_onnx=False)
    (tmp_path / WEIGHTS_FILE).write_bytes(b"garbage")
    with pytest.raises(CheckpointError, match="cannot load weights") as info:
        load_checkpoint(tmp_path)
    assert "\n" not in str(info.value)
    (tmp_path / WEIGHTS_FILE).unlink()
    with pytest.raises(CheckpointError, match="has no model.pt"):
        load_checkpoint(tmp_path)
    # weights of another architecture
    other = make_meta(hparams=resolve_hparams("tcn", {"dim": 16}))
    save_checkpoint(tmp_path / "other", make_model(other), other, export_onnx=False)
    (tmp_path / WEIGHTS_FILE).write_bytes((tmp_path / "other" / WEIGHTS_FILE).read_bytes())
    with pytest.raises(CheckpointError, match="cannot load weights"):
        load_checkpoint(tmp_path)
