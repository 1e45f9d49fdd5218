"""Tests of the recognition commands: dataset, train, eval, compare and bench model."""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace

import pytest
from cli_helpers import invoke, one_line_error
from paths import is_png

from wovenskin.bench import model as bench_model
from wovenskin.recognition.checkpoint_meta import read_meta
from wovenskin.recording.formats import write_labelled_stream
from wovenskin.sim.stream import simulate_stream
from wovenskin.training import capture_eval, capture_lopo, capture_train, runs
from wovenskin.training.config import CAPTURE_DEFAULTS
from wovenskin.training.datasets import generate_sim_dataset, open_dataset

pytestmark = pytest.mark.slow  # trains models or builds data sets: `make test-fast` leaves it out

TINY_SET = ["--recordings", "3", "--windows", "40", "--invalid-windows", "10", "--seconds", "20"]
TINY_HPARAMS = {
    "transformer": {"n_layers": 1, "ff_dim": 32, "d_model": 16, "n_heads": 2, "stem_channels": 8},
    "bilstm": {"hidden": 16, "n_layers": 1},
    "tcn": {"dim": 16, "n_blocks": 2, "stem_channels": 8},
}
TINY_TRAIN = ["--epochs", "1", "--batch-size", "32", "--threads", "1"]


@pytest.fixture(scope="module")
def dataset_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("cli") / "ds"
    result = invoke("dataset", "--out", out, *TINY_SET, "--seed", "5", "--workers", "1")
    assert result.exit_code == 0, result.output
    return out, result


@pytest.fixture(scope="module")
def trained(dataset_run, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("cli-model") / "tcn"
    hparams = json.dumps(TINY_HPARAMS["tcn"])
    result = invoke(
        "train", "--data", dataset_run[0], "--out", out, "--model", "tcn", "--hparams", hparams,
        *TINY_TRAIN,
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    assert "best epoch 1 of 1 (completed)" in result.stdout
    assert "epoch   1/1" in result.stdout  # the per-epoch line
    return out


@pytest.fixture()
def fake_captures(monkeypatch):
    """The labelled-captures API (another module) replaced by recording fakes."""
    calls: dict[str, tuple] = {}

    def evaluate_captures(path, model_dir):
        calls["evaluate"] = (Path(path), Path(model_dir))
        return SimpleNamespace(
            to_dict=lambda: {"capture_accuracy": 0.9, "window_accuracy": 0.8, "n_captures": 10}
        )

    def train_on_captures(path, out_dir, config, **kwargs):
        calls["train"] = (Path(path), Path(out_dir), config, kwargs)
        validation = SimpleNamespace(accuracy=0.75, macro_f1=0.7)
        return SimpleNamespace(validation=validation, best_epoch=3, stop_reason="completed")

    def leave_one_participant_out(path, out_dir, config, **kwargs):
        calls["lopo"] = (Path(path), Path(out_dir), config, kwargs)
        return SimpleNamespace(to_dict=lambda: {"mean_capture_accuracy": 0.85, "folds": [1, 2]})

    monkeypatch.setattr(capture_eval, "evaluate_captures", evaluate_captures)
    monkeypatch.setattr(capture_train, "train_on_captures", train_on_captures)
    monkeypatch.setattr(capture_lopo, "leave_one_participant_out", leave_one_participant_out)
    return calls


# ------------------------------------------------------------------------------- dataset


def test_dataset_prints_a_summary(dataset_run):
    out, result = dataset_run
    assert "150 windows" in result.stdout and "3 people, 3 skins" in result.stdout
    assert "on disk" in result.stdout and "invalid" in result.stdout
    assert len(open_dataset(out)) == 150


def test_dataset_from_streams(tmp_path):
    files = []
    for seed in (1, 2):
        path = tmp_path / f"s{seed}.npz"
        write_labelled_stream(path, simulate_stream(15.0, seed))
        files.append(path)
    out = tmp_path / "ds"
    result = invoke(
        "dataset", "--out", out, "--streams", *files, "--windows", "20", "--invalid-windows", "5",
        "--workers", "1",
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    ds = open_dataset(out)
    assert len(ds) == 50 and ds.meta["kind"] == "streams"
    assert "2 recordings" in result.stdout
    again = invoke("dataset", "--out", out, "--streams", files[0], "--workers", "1")
    one_line_error(again, "already holds a data set; pass --overwrite to replace it")


# --------------------------------------------------------------------------------- train


def test_train_records_data_and_split_and_resumes(trained, dataset_run):
    training = read_meta(trained).training_data
    assert training["split"]["name"] == "grouped"
    assert training["dataset"]["path"] == str(dataset_run[0].resolve())
    hparams = json.dumps(TINY_HPARAMS["tcn"])
    again = invoke(
        "train", "--data", dataset_run[0], "--out", trained, "--model", "tcn", "--hparams",
        hparams, "--resume", *TINY_TRAIN,
    )  # fmt: skip
    assert again.exit_code == 0, again.output
    assert "best epoch 1 of 1" in again.stdout
    different = invoke(
        "train", "--data", dataset_run[0], "--out", trained, "--model", "tcn", "--hparams",
        hparams, "--resume", "--epochs", "1", "--batch-size", "16", "--threads", "1",
    )  # fmt: skip
    one_line_error(different, "cannot resume")


def test_train_without_data_builds_the_default_set(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)

    def tiny_generate(path, workers, progress):
        return generate_sim_dataset(path, 3, 40, 10, 20.0, seed=2, workers=1, progress=progress)

    monkeypatch.setattr(runs, "generate_sim_dataset", tiny_generate)
    hparams = json.dumps(TINY_HPARAMS["bilstm"])
    result = invoke("train", "--model", "bilstm", "--hparams", hparams, *TINY_TRAIN)
    assert result.exit_code == 0, result.output
    assert "building the default one" in result.stdout
    assert (tmp_path / "runs" / "datasets" / "sim-default" / "meta.json").is_file()
    assert (tmp_path / "runs" / "models" / "bilstm-grouped" / "model.onnx").is_file()


@pytest.mark.parametrize(
    "args, message",
    [
        (["--hparams", '{"n_layer": 1}'], "unknown hyperparameter(s) n_layer"),
        (["--hparams", "{nope"], "--hparams is not valid JSON"),
        (["--hparams", "[1]"], "--hparams must be a JSON object"),
        (["--model", "gru"], "unknown model 'gru'"),
        (["--split", "all"], "cannot train on split 'all'"),
        (["--captures", "x.npz"], "give --data or --captures, not both"),
        (["--epochs", "0"], "--epochs 0: Input should be greater than or equal to 1"),
    ],
)
def test_train_errors_are_one_line(dataset_run, tmp_path, args, message):
    result = invoke("train", "--data", dataset_run[0], "--out", tmp_path / "m", *TINY_TRAIN, *args)
    one_line_error(result, message)


def test_training_commands_need_torch(monkeypatch, tmp_path):
    real = importlib.util.find_spec
    monkeypatch.setattr(
        importlib.util, "find_spec", lambda name, *a: None if name == "torch" else real(name, *a)
    )
    one_line_error(invoke("train", "--data", tmp_path), "wovenskin train needs PyTorch")
    one_line_error(invoke("bench", "model"), "wovenskin bench model needs PyTorch")


def test_train_on_captures(fake_captures, tmp_path):
    result = invoke("train", "--captures", tmp_path / "h.npz", "--out", tmp_path / "m", "--seed", 4)
    assert result.exit_code == 0, result.output
    path, out, config, kwargs = fake_captures["train"]
    assert (path, out) == (tmp_path / "h.npz", tmp_path / "m")
    assert config == replace(CAPTURE_DEFAULTS, seed=4)  # the capture recipe, not the window one
    assert callable(kwargs["progress"])
    assert "validation window accuracy 75.00 %" in result.stdout


# ---------------------------------------------------------------------------------- eval


def test_eval_writes_the_report_beside_the_model(trained):
    result = invoke("eval", "--model", trained)
    assert result.exit_code == 0, result.output
    report = trained / "eval-grouped"
    assert is_png(report / "confusion.png")
    metrics = json.loads((report / "metrics.json").read_text())
    assert metrics["split"] == "grouped" and metrics["seen_in_training"] == 0
    assert json.loads((report / "confusion.json").read_text())["n"] == metrics["n_windows"]
    assert "macro-F1" in result.stdout and "most often" in result.stdout
    assert result.stderr == ""


def test_eval_json_is_one_object_on_stdout(trained, tmp_path):
    out = tmp_path / "report"
    result = invoke("eval", "--model", trained, "--split", "random", "--out", out, "--json")
    assert result.exit_code == 0, result.output
    document = json.loads(result.stdout)
    assert result.stdout.count("\n") == 1
    assert {"accuracy", "macro_f1", "metrics", "report_dir", "files"} <= set(document)
    assert document["split"] == "random" and document["seen_in_training"] > 0
    assert "not a held-out score" in result.stderr  # the warning goes to stderr
    assert all(Path(f).is_file() for f in document["files"])
    assert (out / "confusion.png").is_file()


NO_TORCH = """
import sys

class NoTorch:
    def find_spec(self, name, path=None, target=None):
        if name == "torch" or name.startswith("torch."):
            raise ModuleNotFoundError(f"No module named {name!r}")

sys.meta_path.insert(0, NoTorch())
from wovenskin.cli import app
app(sys.argv[1:])
"""


def test_eval_runs_without_torch(trained, tmp_path):
    script = tmp_path / "no_torch.py"
    script.write_text(NO_TORCH)
    command = [
        sys.executable,
        script,
        "eval",
        "--model",
        trained,
        "--out",
        tmp_path / "r",
        "--json",
    ]
    done = subprocess.run(command, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["model_name"] == "tcn"
    assert (tmp_path / "r" / "confusion.png").is_file()


@pytest.mark.parametrize(
    "args, message",
    [
        (["--model", "missing-dir"], "missing-dir: no such model directory"),
        (["--split", "sideways"], "unknown split 'sideways'"),
        (["--lopo"], "--lopo needs --captures FILE"),
        (["--data", "nowhere"], "nowhere: no such data set directory"),
    ],
)
def test_eval_errors_are_one_line(trained, args, message):
    if "--model" not in args:
        args = ["--model", str(trained), *args]
    one_line_error(invoke("eval", *args), message)


def test_eval_captures_json(fake_captures, trained, tmp_path):
    result = invoke("eval", "--captures", tmp_path / "h.npz", "--model", trained, "--json")
    assert result.exit_code == 0, result.output
    document = json.loads(result.stdout)
    assert result.stdout.count("\n") == 1
    assert document["capture_accuracy"] == 0.9 and document["window_accuracy"] == 0.8
    assert fake_captures["evaluate"] == (tmp_path / "h.npz", trained)
    table = invoke("eval", "--captures", tmp_path / "h.npz", "--model", trained)
    assert table.exit_code == 0 and "capture_accuracy" in table.stdout


def test_eval_leave_one_participant_out(fake_captures, trained, tmp_path):
    args = ["eval", "--captures", tmp_path / "h.npz", "--lopo", "--out", tmp_path / "lopo"]
    result = invoke(*args, "--arch", "bilstm", "--epochs", "2", "--json")
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout)["mean_capture_accuracy"] == 0.85
    path, out, config, kwargs = fake_captures["lopo"]
    assert out == tmp_path / "lopo" and config.model == "bilstm" and config.epochs == 2
    assert config.hparams is None and config.lr == CAPTURE_DEFAULTS.lr
    one_line_error(invoke(*args, "--model", trained), "name the architecture with --arch")


# ------------------------------------------------------------------------------- compare


def test_compare_json(dataset_run, tmp_path):
    out = tmp_path / "cmp"
    result = invoke(
        "compare", "--data", dataset_run[0], "--out", out, "--epochs", "1", "--batch-size", "32",
        "--threads", "1", "--latency-repeats", "5", "--hparams", json.dumps(TINY_HPARAMS),
        "--json",
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    document = json.loads(result.stdout)
    assert result.stdout.count("\n") == 1
    assert list(document["models"]) == ["transformer", "bilstm", "tcn"]
    for entry in document["models"].values():
        assert {"params", "latency_median_ms", "grouped"} <= set(entry)
        assert 0 <= entry["grouped"]["accuracy"] <= 1
    assert json.loads((out / "compare.json").read_text()) == document
    assert (out / "grouped" / "tcn" / "eval-grouped" / "confusion.png").is_file()
    bad = invoke("compare", "--data", dataset_run[0], "--hparams", '{"tcn": 3}')
    one_line_error(bad, "--hparams must map model names to JSON objects")


# ----------------------------------------------------------------------------- bench model


def _fake_benchmark(seen: dict):
    """A stand-in for the real benchmark (tested in test_bench_model) that records its call."""

    def run(repeats, batch_size, include_shipped, throughput_seconds, progress):
        seen.update(repeats=repeats, batch=batch_size, shipped=include_shipped,
                    seconds=throughput_seconds)  # fmt: skip
        progress("timing")
        timings = [
            bench_model.ModelTiming(name, name, "fresh", 1000, ms, 2 * ms, ms, 2 * ms, 1, 2, 3, 4)
            for name, ms in (("transformer", 0.6), ("bilstm", 0.8), ("tcn", 0.5))
        ]
        return bench_model.ModelBenchResult(
            timings, 0.75, 1.0, repeats, batch_size, 2, (30, 10, 10), "x86_64", "1", "2", "today"
        )

    return run


def test_bench_model_json_and_table(monkeypatch):
    seen: dict = {}
    monkeypatch.setattr(bench_model, "run_model_benchmark", _fake_benchmark(seen))
    args = ["bench", "model", "--repeats", "7", "--batch-size", "16", "--no-shipped"]
    result = invoke(*args, "--seconds", "0.5", "--json")
    assert result.exit_code == 0, result.output
    assert seen == {"repeats": 7, "batch": 16, "shipped": False, "seconds": 0.5}
    document = json.loads(result.stdout)
    assert result.stdout.count("\n") == 1
    assert document["ratio_transformer_bilstm"] == 0.75
    assert set(document["models"]) == {"transformer", "bilstm", "tcn"}
    table = invoke(*args)
    assert table.exit_code == 0 and "transformer / BiLSTM" in table.stdout
