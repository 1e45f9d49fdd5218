"""``wovenskin bench model``: inference latency and throughput of the gesture classifiers.

For every registry model (transformer, BiLSTM, TCN) at its default hyperparameters, on a
10 x 10 skin with 30-frame windows and the 15 classes, and for the shipped default model
when the package holds one:

- per-window latency at batch 1 on ONE thread, median and p99, on ONNX Runtime (an
  :class:`~wovenskin.recognition.onnx_runtime.OnnxRecognizer` with one intra-op thread,
  timed through ``predict_proba`` as live inference calls it, input checks and softmax
  included) and on torch (``torch.set_num_threads(1)``, inference mode);
- batched throughput, windows per second at batch 256, on one thread and on all threads
  of this machine, for both runtimes;
- the ratio of the transformer's median ONNX Runtime latency to the BiLSTM's (the paper
  reports 15 ms against 12 ms on its hardware, a ratio of 1.25), and the same on torch.

Weights do not change the cost of a forward pass, so the registry models are freshly
initialised and exported to ONNX in a temporary directory; the shipped model runs its own
graph. Every callable is warmed up first, and batch-1 calls are timed in interleaved rounds
(each round times every model once) with the process pinned to one CPU, so a burst of
load from other processes hits all models alike instead of skewing one of them.
"""

from __future__ import annotations

import os
import platform
import tempfile
import time
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
import onnxruntime
import torch
from rich.table import Table

from wovenskin.gestures import CLASS_NAMES
from wovenskin.recognition.checkpoint_meta import (
    WEIGHTS_FILE,
    CheckpointMeta,
    read_meta,
    write_meta,
)
from wovenskin.recognition.onnx_runtime import OnnxRecognizer, export_onnx
from wovenskin.recognition.shipped import ModelNotFoundError, default_model_dir
from wovenskin.signal.config import ConditioningConfig
from wovenskin.training.checkpoint import load_checkpoint
from wovenskin.training.models import MODEL_REGISTRY, build_model, count_parameters, resolve_hparams
from wovenskin.training.timing import WARMUP_CALLS as WARMUP_CALLS  # re-exported
from wovenskin.training.timing import measure_latency, one_core

PAPER_MS = {"transformer": 15.0, "bilstm": 12.0}
"""The paper's per-window latencies (its hardware) for the transformer and the BiLSTM."""
BATCH = 256
THROUGHPUT_SECONDS = 1.0
INPUT_POOL = 32
"""Distinct random windows cycled through the timed calls."""
ROWS, COLS, WINDOW = 10, 10, 30
FRESH_SOURCE = "default hparams, fresh weights"


def measure_throughput(
    call: Callable[[np.ndarray], object],
    batch: np.ndarray,
    min_seconds: float = THROUGHPUT_SECONDS,
    min_calls: int = 3,
) -> float:
    """Windows per second of ``call(batch)``, after one warm-up call."""
    call(batch)
    calls, start = 0, time.perf_counter()
    while True:
        call(batch)
        calls += 1
        elapsed = time.perf_counter() - start
        if calls >= min_calls and elapsed >= min_seconds:
            return calls * len(batch) / elapsed


def available_threads() -> int:
    """CPUs this process may run on."""
    if hasattr(os, "sched_getaffinity"):
        return len(os.sched_getaffinity(0))
    return os.cpu_count() or 1


@dataclass
class ModelTiming:
    """Measured figures of one model (latencies in ms, throughput in windows/s)."""

    name: str
    model_name: str
    source: str  # "default hparams, fresh weights" or the shipped model's directory
    params: int
    onnx_median_ms: float
    onnx_p99_ms: float
    torch_median_ms: float
    torch_p99_ms: float
    onnx_batch_wps_1_thread: float
    onnx_batch_wps_all_threads: float
    torch_batch_wps_1_thread: float
    torch_batch_wps_all_threads: float


@dataclass
class ModelBenchResult:
    models: list[ModelTiming]
    ratio_transformer_bilstm: float
    ratio_transformer_bilstm_torch: float
    repeats: int
    batch_size: int
    threads_all: int
    input_shape: tuple[int, int, int]
    cpu: str
    onnxruntime_version: str
    torch_version: str
    date: str
    paper_ms: dict[str, float] = field(default_factory=lambda: dict(PAPER_MS))

    def timing(self, name: str) -> ModelTiming:
        for entry in self.models:
            if entry.name == name:
                return entry
        raise KeyError(name)

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["models"] = {
            m.name: {k: v for k, v in asdict(m).items() if k != "name"} for m in self.models
        }
        d["input_shape"] = list(self.input_shape)
        d["paper_ratio_transformer_bilstm"] = PAPER_MS["transformer"] / PAPER_MS["bilstm"]
        return d

    def table(self) -> Table:
        window, rows, cols = self.input_shape
        table = Table(
            title=(
                f"wovenskin bench model: {window}-frame windows of {rows}x{cols}, batch 1 on one "
                f"thread; batch {self.batch_size} on 1 and {self.threads_all} threads"
            )
        )
        table.add_column("model")
        table.add_column("params", justify="right")
        for runtime in ("ORT", "torch"):
            table.add_column(f"{runtime}\nmedian ms", justify="right")
            table.add_column(f"{runtime}\np99 ms", justify="right")
        for runtime in ("ORT", "torch"):
            table.add_column(f"{runtime} win/s\n1 thread", justify="right")
            table.add_column(f"{runtime} win/s\n{self.threads_all} threads", justify="right")
        for m in self.models:
            table.add_row(
                m.name,
                f"{m.params:,}",
                f"{m.onnx_median_ms:.3f}",
                f"{m.onnx_p99_ms:.3f}",
                f"{m.torch_median_ms:.3f}",
                f"{m.torch_p99_ms:.3f}",
                f"{m.onnx_batch_wps_1_thread:,.0f}",
                f"{m.onnx_batch_wps_all_threads:,.0f}",
                f"{m.torch_batch_wps_1_thread:,.0f}",
                f"{m.torch_batch_wps_all_threads:,.0f}",
            )
        transformer = self.timing("transformer").onnx_median_ms
        bilstm = self.timing("bilstm").onnx_median_ms
        paper = PAPER_MS["transformer"] / PAPER_MS["bilstm"]
        faster = "met" if transformer <= bilstm else "NOT met"
        sub_ms = "met" if transformer <= 1.0 else "NOT met"
        table.caption = (
            f"transformer / BiLSTM (ORT median, batch 1, one thread): "
            f"{self.ratio_transformer_bilstm:.2f} "
            f"(torch {self.ratio_transformer_bilstm_torch:.2f}; "
            f"paper {PAPER_MS['transformer']:g} ms / {PAPER_MS['bilstm']:g} ms = {paper:.2f}). "
            f"Targets: transformer <= BiLSTM {faster}; transformer <= 1 ms {sub_ms}. "
            f"{self.repeats} timed calls per model; {self.cpu}, onnxruntime "
            f"{self.onnxruntime_version}, torch {self.torch_version}, {self.date}"
        )
        return table


@dataclass
class _Candidate:
    name: str
    model_name: str
    source: str
    checkpoint_dir: Path
    torch_model: Any  # nn.Module in eval mode


def _fresh_candidates(directory: Path, names: list[str]) -> list[_Candidate]:
    """Registry models at default hparams, fresh weights, exported to ONNX in ``directory``."""

    candidates = []
    for name in names:
        torch.manual_seed(0)
        model = build_model(name, ROWS, COLS, WINDOW, len(CLASS_NAMES)).eval()
        meta = CheckpointMeta(
            model_name=name,
            hparams=resolve_hparams(name),
            class_names=tuple(CLASS_NAMES),
            rows=ROWS,
            cols=COLS,
            window=WINDOW,
            sample_rate_hz=200.0,
            conditioning=ConditioningConfig().to_dict(),
        )
        checkpoint = directory / name
        export_onnx(model, meta, checkpoint / "model.onnx")
        write_meta(checkpoint, meta)
        candidates.append(_Candidate(name, name, FRESH_SOURCE, checkpoint, model))
    return candidates


def _shipped_candidate() -> _Candidate | None:
    """The shipped default model, when the package holds one (its torch twin from its meta)."""

    try:
        directory = default_model_dir()
    except ModelNotFoundError:
        return None
    meta = read_meta(directory)
    if (directory / WEIGHTS_FILE).is_file():
        model, _ = load_checkpoint(directory)
    else:  # only the graph is shipped; weights do not change the forward pass's cost
        torch.manual_seed(0)
        model = build_model(
            meta.model_name, meta.rows, meta.cols, meta.window, meta.n_classes, **meta.hparams
        ).eval()
    return _Candidate("shipped", meta.model_name, str(directory), directory, model)


def run_model_benchmark(
    repeats: int = 500,
    batch_size: int = BATCH,
    include_shipped: bool = True,
    throughput_seconds: float = THROUGHPUT_SECONDS,
    progress: Callable[[str], None] | None = None,
) -> ModelBenchResult:
    """Time every registry model (and the shipped one) on ONNX Runtime and torch."""

    if batch_size < 1:
        raise ValueError(f"batch size must be at least 1, got {batch_size}")
    say = progress or (lambda _message: None)
    threads_all = available_threads()
    torch_threads = torch.get_num_threads()
    with tempfile.TemporaryDirectory(prefix="wovenskin-bench-model-") as tmp:
        say("exporting the models to ONNX")
        candidates = _fresh_candidates(Path(tmp), list(MODEL_REGISTRY))
        shipped = _shipped_candidate() if include_shipped else None
        if shipped is not None:
            candidates.append(shipped)
        single = {c.name: OnnxRecognizer(c.checkpoint_dir, threads=1) for c in candidates}
        rng = np.random.default_rng(0)
        pools: dict[tuple[int, int, int], np.ndarray] = {}
        for recognizer in single.values():
            shape = recognizer.meta.input_shape
            if shape not in pools:
                pools[shape] = (0.05 * rng.standard_normal((INPUT_POOL, 1, *shape))).astype(
                    np.float32
                )
        try:
            torch.set_num_threads(1)
            say(f"timing batch 1 on one thread ({repeats} rounds)")
            with one_core(), torch.inference_mode():
                onnx_times, torch_times = {}, {}
                for shape, pool in pools.items():
                    group = [c for c in candidates if single[c.name].meta.input_shape == shape]
                    calls: dict[str, Callable[[np.ndarray], object]] = {}
                    for c in group:
                        calls[f"onnx:{c.name}"] = single[c.name].predict_proba
                        calls[f"torch:{c.name}"] = _torch_call(c.torch_model)
                    times = measure_latency(calls, pool, repeats)
                    for c in group:
                        onnx_times[c.name] = times[f"onnx:{c.name}"]
                        torch_times[c.name] = times[f"torch:{c.name}"]
                say(f"timing batch {batch_size} on one thread")
                wps_1 = {
                    c.name: _throughputs(c, single[c.name], pools, batch_size, throughput_seconds)
                    for c in candidates
                }
            torch.set_num_threads(threads_all)
            say(f"timing batch {batch_size} on {threads_all} threads")
            with torch.inference_mode():
                wps_all = {
                    c.name: _throughputs(
                        c,
                        OnnxRecognizer(c.checkpoint_dir, threads=threads_all),
                        pools,
                        batch_size,
                        throughput_seconds,
                    )
                    for c in candidates
                }
        finally:
            torch.set_num_threads(torch_threads)

    def ms(seconds: np.ndarray, q: float) -> float:
        return float(np.percentile(seconds, q) * 1e3)

    timings = [
        ModelTiming(
            name=c.name,
            model_name=c.model_name,
            source=c.source,
            params=count_parameters(c.torch_model),
            onnx_median_ms=ms(onnx_times[c.name], 50),
            onnx_p99_ms=ms(onnx_times[c.name], 99),
            torch_median_ms=ms(torch_times[c.name], 50),
            torch_p99_ms=ms(torch_times[c.name], 99),
            onnx_batch_wps_1_thread=wps_1[c.name][0],
            onnx_batch_wps_all_threads=wps_all[c.name][0],
            torch_batch_wps_1_thread=wps_1[c.name][1],
            torch_batch_wps_all_threads=wps_all[c.name][1],
        )
        for c in candidates
    ]
    by_name = {t.name: t for t in timings}
    return ModelBenchResult(
        models=timings,
        ratio_transformer_bilstm=by_name["transformer"].onnx_median_ms
        / by_name["bilstm"].onnx_median_ms,
        ratio_transformer_bilstm_torch=by_name["transformer"].torch_median_ms
        / by_name["bilstm"].torch_median_ms,
        repeats=repeats,
        batch_size=batch_size,
        threads_all=threads_all,
        input_shape=(WINDOW, ROWS, COLS),
        cpu=platform.processor() or platform.machine(),
        onnxruntime_version=onnxruntime.__version__,
        torch_version=torch.__version__,
        date=datetime.now(UTC).date().isoformat(),
    )


def _torch_call(model: Any) -> Callable[[np.ndarray], object]:

    def call(windows: np.ndarray) -> object:
        return model(torch.from_numpy(windows))

    return call


def _throughputs(
    candidate: _Candidate,
    recognizer: Any,
    pools: Mapping[tuple[int, int, int], np.ndarray],
    batch_size: int,
    seconds: float,
) -> tuple[float, float]:
    """(ONNX Runtime, torch) windows per second at ``batch_size``."""
    pool = pools[recognizer.meta.input_shape][:, 0]
    batch = np.ascontiguousarray(np.resize(pool, (batch_size, *pool.shape[1:])))
    onnx_wps = measure_throughput(recognizer.predict_proba, batch, seconds)
    torch_wps = measure_throughput(_torch_call(candidate.torch_model), batch, seconds)
    return onnx_wps, torch_wps
