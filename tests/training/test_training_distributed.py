"""Tests of training on the hardware at hand: devices, mixed precision and torch.distributed.

The rank sharding and the device choices are unit tests; the end-to-end test launches
``wovenskin train`` under torchrun as two gloo processes on the CPU and checks they reach
the single process's validation accuracy within a point, with one checkpoint written by
rank 0 and progress printed once.
"""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from hypothesis import given
from hypothesis import strategies as st
from typer.testing import CliRunner

from wovenskin.cli import app
from wovenskin.errors import ConfigError
from wovenskin.recognition.checkpoint_meta import ONNX_FILE, read_meta
from wovenskin.training import distributed
from wovenskin.training.compare import train_on_dataset
from wovenskin.training.config import TrainConfig
from wovenskin.training.datasets import open_dataset
from wovenskin.training.datasets.store import FORMAT, FORMAT_VERSION
from wovenskin.training.datasets.writer import (
    DatasetWriter,
    RecordingCollector,
    RecordingWindows,
)
from wovenskin.training.device import Precision, amp_dtype, cpu_copy, resolve_device
from wovenskin.training.distributed import Ranks
from wovenskin.training.models import build_model

CLASSES = ("slide_right", "slide_down", "press")
ROWS, COLS, WINDOW = 6, 8, 16
NO_CUDA = not torch.cuda.is_available()


# ------------------------------------------------------------------------ rank sharding


@given(n=st.integers(0, 300), world=st.integers(1, 5), seed=st.integers(0, 2**16))
def test_shards_are_disjoint_cover_the_epoch_and_have_equal_batch_counts(n, world, seed):
    order = np.random.default_rng(seed).permutation(n) + 1000
    batch_size = 4 * world
    shares = [distributed.shard(order, Ranks(r, world)) for r in range(world)]
    union = np.concatenate(shares)
    assert union.size == np.unique(union).size  # disjoint
    assert set(union) <= set(order) and order.size - union.size == n % world  # covering
    assert len({s.size for s in shares}) == 1
    per_rank = distributed.rank_batch_size(batch_size, Ranks(0, world))
    counts = {len(range(0, s.size, per_rank)) for s in shares}
    assert counts == {distributed.steps_per_epoch(n, batch_size, Ranks(0, world))}


def test_one_process_keeps_the_whole_order_and_batch():
    order = np.arange(10)[::-1]
    assert np.array_equal(distributed.shard(order, distributed.SINGLE), order)
    assert distributed.rank_batch_size(64, distributed.SINGLE) == 64
    assert distributed.steps_per_epoch(130, 64, distributed.SINGLE) == 3


def test_rank_batches_are_the_strided_shares_of_the_global_batches():
    order = np.arange(40)
    world, batch_size = 2, 8
    global_batches = [order[i : i + batch_size] for i in range(0, order.size, batch_size)]
    for rank in range(world):
        share = distributed.shard(order, Ranks(rank, world))
        per_rank = distributed.rank_batch_size(batch_size, Ranks(rank, world))
        mine = [share[i : i + per_rank] for i in range(0, share.size, per_rank)]
        assert [list(b) for b in mine] == [list(g[rank::world]) for g in global_batches]


def test_a_batch_size_the_ranks_do_not_divide_is_one_line():
    with pytest.raises(ConfigError, match="multiple of 3") as error:
        distributed.rank_batch_size(64, Ranks(0, 3))
    assert "\n" not in str(error.value)


def test_ranks_are_read_from_torchruns_variables():
    assert distributed.env_ranks({}) is None
    env = {"RANK": "1", "WORLD_SIZE": "2", "LOCAL_RANK": "1"}
    assert distributed.env_ranks(env) == Ranks(1, 2, 1)
    alone = {"RANK": "0", "WORLD_SIZE": "1", "LOCAL_RANK": "0"}
    assert distributed.launched(env) and not distributed.launched(alone)
    for bad, message in (
        ({"RANK": "0"}, "WORLD_SIZE, LOCAL_RANK not set"),
        ({**env, "RANK": "x"}, "not whole numbers"),
        ({**env, "RANK": "2"}, "not a rank of the world"),
    ):
        with pytest.raises(ConfigError, match=message):
            distributed.env_ranks(bad)


def test_without_torchrun_the_session_is_one_process(monkeypatch):
    for key in distributed.ENV_KEYS:
        monkeypatch.delenv(key, raising=False)
    with distributed.session("cpu") as ranks:
        assert ranks == distributed.SINGLE and ranks.is_main and not ranks.active
        assert not torch.distributed.is_initialized()
        assert distributed.main_value(ranks, 7) == 7
        assert distributed.all_sum([1.5, 2], ranks) == [1.5, 2]


# ------------------------------------------------------------------ device and precision


def test_the_cpu_trains_in_float32_and_mixed_precision_needs_cuda():
    cpu = torch.device("cpu")
    assert resolve_device("cpu") == cpu
    assert amp_dtype("auto", cpu) is None and amp_dtype("off", cpu) is None
    precision = Precision.of(cpu, "auto")
    assert precision.name == "off" and precision.scaler is None
    with pytest.raises(ConfigError, match="--amp bf16 needs a CUDA device"):
        amp_dtype("bf16", cpu)
    with pytest.raises(ConfigError, match="device"):
        TrainConfig.from_dict({"device": "gpu"})
    with pytest.raises(ConfigError, match="amp"):
        TrainConfig.from_dict({"amp": "fp8"})
    net = build_model("tcn", ROWS, COLS, WINDOW, len(CLASSES), dim=16)
    assert cpu_copy(net) is net  # CPU weights are saved as they are


@pytest.mark.skipif(not NO_CUDA, reason="this machine has CUDA")
def test_auto_is_the_cpu_and_cuda_without_a_gpu_is_one_line(tmp_path):
    assert resolve_device("auto") == torch.device("cpu")
    with pytest.raises(ConfigError, match="no CUDA GPU") as error:
        resolve_device("cuda")
    assert "\n" not in str(error.value)
    result = CliRunner().invoke(
        app, ["train", "--data", str(tmp_path / "none"), "--device", "cuda", "--out", str(tmp_path)]
    )
    assert result.exit_code == 2
    assert "no CUDA GPU" in result.output and "Traceback" not in result.output


@pytest.mark.skipif(NO_CUDA, reason="needs a CUDA GPU")
def test_mixed_precision_step_on_cuda():
    device = resolve_device("cuda")
    precision = Precision.of(device, "fp16")
    assert precision.scaler is not None and precision.name == "fp16"
    net = build_model("tcn", ROWS, COLS, WINDOW, len(CLASSES), dim=16).to(device)
    optimizer = torch.optim.AdamW(net.parameters(), lr=1e-3)
    x = torch.rand(8, WINDOW, ROWS, COLS, device=device)
    with precision.autocast():
        loss = torch.nn.functional.cross_entropy(
            net(x), torch.zeros(8, dtype=torch.long, device=device)
        )
    precision.step(loss, optimizer, net.parameters())
    assert cpu_copy(net) is not net and next(cpu_copy(net).parameters()).device.type == "cpu"


# --------------------------------------------------------- two gloo processes against one


def moving_blobs(n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Windows of a blob that slides right, slides down or presses in place."""
    rng = np.random.default_rng(seed)
    labels = rng.integers(0, len(CLASSES), n)
    t = np.linspace(0.0, 1.0, WINDOW)[None, :]
    r0, c0 = rng.uniform(1.5, ROWS - 2.5, (n, 1)), rng.uniform(1.5, COLS - 2.5, (n, 1))
    travel, amplitude = rng.uniform(2.0, 3.5, (n, 1)), rng.uniform(0.05, 0.3, (n, 1))
    right, down, press = (labels == k for k in range(3))
    row = r0 + down[:, None] * travel * (t - 0.5)
    col = c0 + right[:, None] * travel * (t - 0.5)
    strength = amplitude * np.where(press[:, None], 0.2 + 0.8 * t, 1.0)
    rr = np.arange(ROWS)[None, None, :, None]
    cc = np.arange(COLS)[None, None, None, :]
    distance2 = (rr - row[:, :, None, None]) ** 2 + (cc - col[:, :, None, None]) ** 2
    windows = strength[:, :, None, None] * np.exp(-distance2 / 1.3)
    windows += rng.normal(0.0, 0.003, windows.shape)
    return windows.astype(np.float32), labels.astype(np.int16)


def write_blob_dataset(path: Path, recordings: int = 6, per_recording: int = 80) -> Path:
    """A window data set on disk (the format ``wovenskin dataset`` writes) of moving blobs."""
    writer = DatasetWriter(path, recordings * per_recording, "float32")
    collector = RecordingCollector(writer, recordings, per_recording)
    for i in range(recordings):
        windows, labels = moving_blobs(per_recording, seed=i)
        sources = np.zeros(per_recording, np.int8)
        collector.put(i, RecordingWindows(windows, labels, sources, f"r{i}", f"p{i}", f"s{i}", {}))
    meta = {
        "format": FORMAT, "format_version": FORMAT_VERSION, "class_names": list(CLASSES),
        "rows": ROWS, "cols": COLS, "window_frames": WINDOW, "sample_rate_hz": 200.0,
        "conditioning": {"smoothing_s": 0.1}, "source": "moving blobs",
    }  # fmt: skip
    collector.finish(meta, overwrite=False)
    return path


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


TRAIN_ARGS = {"model": "tcn", "hparams": {"dim": 16}, "epochs": 2, "batch_size": 32}


@pytest.mark.slow
def test_two_gloo_processes_reach_the_single_process_accuracy(tmp_path: Path) -> None:
    data = write_blob_dataset(tmp_path / "blobs")
    config = TrainConfig(**TRAIN_ARGS, device="cpu")
    single = train_on_dataset(open_dataset(data), tmp_path / "one", "random", config)

    out = tmp_path / "two"
    command = [
        sys.executable, "-m", "torch.distributed.run", "--nnodes", "1", "--nproc-per-node", "2",
        "--master-addr", "127.0.0.1", "--master-port", str(free_port()),
        "-m", "wovenskin.cli", "train", "--data", str(data), "--out", str(out),
        "--split", "random", "--model", "tcn", "--hparams", json.dumps(TRAIN_ARGS["hparams"]),
        "--epochs", "2", "--batch-size", "32", "--device", "cpu",
    ]  # fmt: skip
    env = {**os.environ, "OMP_NUM_THREADS": "1", "COLUMNS": "200"}
    done = subprocess.run(command, capture_output=True, text=True, env=env, timeout=240)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-4000:]

    assert done.stdout.count("training tcn on") == 1  # progress and results: rank 0 only
    assert "2 processes" in done.stdout and "validation accuracy" in done.stdout
    meta = read_meta(out)
    two = meta.metrics["val_accuracy"]
    assert abs(two - single.validation.accuracy) <= 0.01, (two, single.validation.accuracy)
    assert two >= 0.9  # both learnt the task, not both failed it
    hardware = meta.training_data["training"]["hardware"]
    assert hardware == {"device": "cpu", "amp": "off", "processes": 2}
    assert (out / ONNX_FILE).is_file() and (out / "history.json").is_file()
    history = json.loads((out / "history.json").read_text())
    assert len(history["epochs"]) == 2
