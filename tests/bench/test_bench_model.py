"""Tests of wovenskin.bench.model: timing helpers and the model latency benchmark."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch
from rich.console import Console

from wovenskin.bench import model as bench_model
from wovenskin.bench.model import measure_throughput, run_model_benchmark
from wovenskin.gestures import CLASS_NAMES
from wovenskin.recognition import shipped
from wovenskin.recognition.checkpoint_meta import CheckpointMeta
from wovenskin.training.checkpoint import save_checkpoint
from wovenskin.training.models import build_model, count_parameters
from wovenskin.training.timing import measure_latency

pytestmark = pytest.mark.slow  # trains models or builds data sets: `make test-fast` leaves it out


def test_measure_latency_interleaves_and_warms_up():
    order: list[str] = []
    inputs = np.arange(4.0)[:, None]
    calls = {"a": lambda x: order.append("a"), "b": lambda x: order.append("b")}
    times = measure_latency(calls, inputs, repeats=5, warmup=3)
    assert set(times) == {"a", "b"} and all(t.shape == (5,) for t in times.values())
    assert all((t >= 0).all() for t in times.values())
    assert order[:6] == ["a"] * 3 + ["b"] * 3  # warm-up, one callable after the other
    assert order[6:] == ["a", "b"] * 5  # timed rounds: every callable once per round
    seen: list[float] = []
    measure_latency({"x": lambda x: seen.append(float(x[0]))}, inputs, repeats=6, warmup=0)
    assert seen == [0.0, 1.0, 2.0, 3.0, 0.0, 1.0]  # the input pool is cycled
    with pytest.raises(ValueError, match="repeats"):
        measure_latency(calls, inputs, repeats=0)


def test_measure_throughput_counts_windows():
    calls = []
    wps = measure_throughput(lambda batch: calls.append(len(batch)), np.zeros((8, 2)), 0.0, 3)
    assert wps > 0 and calls == [8] * 4  # one warm-up and the three timed calls


@pytest.fixture()
def shipped_model(tmp_path, monkeypatch):
    """A small transformer as the package's shipped model (ONNX graph only, no weights)."""
    hparams = {"n_layers": 1, "d_model": 32, "ff_dim": 64, "stem_channels": 8}
    model = build_model("transformer", 10, 10, 30, len(CLASS_NAMES), **hparams)
    meta = CheckpointMeta("transformer", hparams, CLASS_NAMES, 10, 10, 30, 200.0, {})
    save_checkpoint(tmp_path, model, meta)
    (tmp_path / "model.pt").unlink()
    monkeypatch.setattr(shipped, "DEFAULT_MODEL_DIR", tmp_path)
    return count_parameters(model)


def test_model_benchmark_figures(shipped_model):
    threads = torch.get_num_threads()
    result = run_model_benchmark(repeats=5, batch_size=4, throughput_seconds=0.0)
    assert torch.get_num_threads() == threads  # restored
    names = [m.name for m in result.models]
    assert names == ["transformer", "bilstm", "tcn", "shipped"]
    defaults = {
        name: count_parameters(build_model(name, 10, 10, 30, len(CLASS_NAMES)))
        for name in ("transformer", "bilstm", "tcn")
    }
    for timing in result.models:
        expected = shipped_model if timing.name == "shipped" else defaults[timing.name]
        assert timing.params == expected
        assert 0 < timing.onnx_median_ms <= timing.onnx_p99_ms
        assert 0 < timing.torch_median_ms <= timing.torch_p99_ms
        assert min(timing.onnx_batch_wps_1_thread, timing.torch_batch_wps_all_threads) > 0
    assert result.timing("shipped").source == str(shipped.DEFAULT_MODEL_DIR)
    t, b = result.timing("transformer"), result.timing("bilstm")
    assert result.ratio_transformer_bilstm == pytest.approx(t.onnx_median_ms / b.onnx_median_ms)
    assert result.ratio_transformer_bilstm_torch == pytest.approx(
        t.torch_median_ms / b.torch_median_ms
    )
    document = json.loads(json.dumps(result.to_dict()))
    assert set(document["models"]) == {"transformer", "bilstm", "tcn", "shipped"}
    assert document["ratio_transformer_bilstm"] == result.ratio_transformer_bilstm
    assert document["paper_ratio_transformer_bilstm"] == pytest.approx(1.25)
    console = Console(record=True, width=200)
    console.print(result.table())
    assert "transformer / BiLSTM" in console.export_text()


def test_model_benchmark_without_a_shipped_model(monkeypatch, tmp_path):
    monkeypatch.setattr(shipped, "DEFAULT_MODEL_DIR", tmp_path / "absent")
    with pytest.raises(ValueError, match="batch size"):
        run_model_benchmark(repeats=2, batch_size=0)
    assert bench_model._shipped_candidate() is None
