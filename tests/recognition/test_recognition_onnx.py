"""Tests of wovenskin.recognition.onnx_runtime: export, torch parity, torch-free inference."""

from __future__ import annotations

import subprocess
import sys
import textwrap
import zlib
from pathlib import Path

import numpy as np
import pytest
import torch
from paths import REPO

from wovenskin.recognition import onnx_runtime
from wovenskin.recognition.checkpoint_meta import ONNX_FILE, CheckpointError, CheckpointMeta
from wovenskin.recognition.onnx_runtime import OnnxRecognizer, export_onnx, softmax
from wovenskin.training.checkpoint import save_checkpoint
from wovenskin.training.models import MODEL_REGISTRY, build_model

pytestmark = pytest.mark.slow  # trains models or builds data sets: `make test-fast` leaves it out

REPO = REPO
ATOL = 1e-4


def make_checkpoint(
    directory: Path, name: str, rows: int = 10, cols: int = 10, window: int = 30, k: int = 15
) -> torch.nn.Module:
    """A checkpoint whose logits span several units, so probabilities are not uniform."""
    torch.manual_seed(zlib.crc32(f"{name}-{rows}x{cols}".encode()) % 1000)  # not hash(): salted
    model = build_model(name, rows, cols, window, k)
    model.set_input_scale(0.2)
    with torch.no_grad():  # scale the output layer so logits spread by about 4 units
        last = [m for m in model.modules() if isinstance(m, torch.nn.Linear)][-1]
        probe = model.eval()(0.2 * torch.randn(16, window, rows, cols))
        gain = 4.0 / float(probe.std())
        last.weight.mul_(gain)
        last.bias.mul_(gain)
    meta = CheckpointMeta(
        model_name=name,
        hparams={},
        class_names=tuple(f"class_{i}" for i in range(k)),
        rows=rows,
        cols=cols,
        window=window,
        sample_rate_hz=200.0,
        conditioning={"smoothing_s": 0.1},
    )
    save_checkpoint(directory, model, meta)
    return model.eval()


@pytest.mark.parametrize("name", tuple(MODEL_REGISTRY))
@pytest.mark.parametrize(("rows", "cols"), [(10, 10), (6, 8)])
def test_onnx_runtime_matches_torch(tmp_path: Path, name: str, rows: int, cols: int) -> None:
    model = make_checkpoint(tmp_path, name, rows, cols)
    recognizer = OnnxRecognizer(tmp_path)
    rng = np.random.default_rng(0)
    spread = []
    for batch in (1, 37):
        windows = rng.normal(0.0, 0.2, (batch, 30, rows, cols)).astype(np.float32)
        windows[:, 10:20] += rng.uniform(0, 1, (batch, 1, rows, cols)).astype(np.float32)
        with torch.inference_mode():
            logits = model(torch.from_numpy(windows)).numpy()
        probabilities = recognizer.predict_proba(windows)
        assert probabilities.shape == (batch, 15)
        assert probabilities.dtype == np.float32
        np.testing.assert_allclose(probabilities, softmax(logits), atol=ATOL, rtol=0)
        np.testing.assert_allclose(recognizer.predict_logits(windows), logits, atol=1e-3, rtol=1e-4)
        np.testing.assert_allclose(probabilities.sum(axis=1), 1.0, atol=1e-5)
        top2 = np.sort(logits, axis=1)[:, -2:]
        clear = top2[:, 1] - top2[:, 0] > 1e-3  # an exact tie may break either way
        assert np.array_equal(recognizer.predict(windows)[clear], logits.argmax(axis=1)[clear])
        spread.append(probabilities.max(axis=1))
    assert np.concatenate(spread).max() > 0.5  # not a trivially uniform comparison


def test_onnx_runtime_does_not_import_torch(tmp_path: Path) -> None:
    make_checkpoint(tmp_path, "transformer")
    script = textwrap.dedent(
        f"""
        import sys
        import numpy as np
        from wovenskin.recognition.onnx_runtime import OnnxRecognizer
        recognizer = OnnxRecognizer({str(tmp_path)!r})
        p = recognizer.predict_proba(np.zeros((2, 30, 10, 10), np.float32))
        assert p.shape == (2, 15), p.shape
        recognizer.check_input(10, 10, 30, 200.0, {{"smoothing_s": 0.1}})
        loaded = sorted(m for m in sys.modules if m == "torch" or m.startswith("torch."))
        print("TORCH_MODULES", loaded)
        """
    )
    result = subprocess.run(
        [sys.executable, "-c", script],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 0, result.stderr
    assert "TORCH_MODULES []" in result.stdout


def test_single_window_empty_batch_and_integer_input(tmp_path: Path) -> None:
    make_checkpoint(tmp_path, "tcn", 6, 8, 12, 4)
    recognizer = OnnxRecognizer(tmp_path)
    window = np.random.default_rng(1).normal(0, 0.1, (12, 6, 8))
    assert recognizer.predict_proba(window).shape == (1, 4)
    assert np.allclose(recognizer.predict_proba(window), recognizer.predict_proba(window[None]))
    assert recognizer.predict_proba(np.zeros((0, 12, 6, 8))).shape == (0, 4)
    assert recognizer.predict_proba(np.ones((2, 12, 6, 8), dtype=np.int16)).shape == (2, 4)
    assert recognizer.predict_proba(window.astype(np.float16)).shape == (1, 4)
    assert recognizer.class_names == ("class_0", "class_1", "class_2", "class_3")
    assert recognizer.n_classes == 4


def test_bad_input_gives_a_clear_error(tmp_path: Path) -> None:
    make_checkpoint(tmp_path, "bilstm", 6, 8, 12, 4)
    recognizer = OnnxRecognizer(tmp_path)
    with pytest.raises(
        ValueError, match=r"expected windows of shape \(B, 12, 6, 8\).*got \(2, 12, 10, 10\)"
    ):
        recognizer.predict_proba(np.zeros((2, 12, 10, 10)))
    with pytest.raises(ValueError, match="expected windows"):
        recognizer.predict_proba(np.zeros((6, 8)))
    windows = np.zeros((5, 12, 6, 8), np.float32)
    windows[3, 2, 1, 1] = np.nan
    windows[4, 0, 0, 0] = np.inf
    with pytest.raises(ValueError, match=r"NaN or inf values \(window 3 and 1 more\)"):
        recognizer.predict_proba(windows)
    with pytest.raises(ValueError, match="numeric"):
        recognizer.predict_proba(np.full((1, 12, 6, 8), "x"))
    with pytest.raises(ValueError, match="model expects 6x8 frames at 200 Hz, got 10x10 at 200 Hz"):
        recognizer.check_input(10, 10, 12, 200.0, {"smoothing_s": 0.1})


def test_large_batches_are_chunked(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    make_checkpoint(tmp_path, "tcn", 6, 8, 12, 4)
    recognizer = OnnxRecognizer(tmp_path)
    windows = np.random.default_rng(2).normal(0, 0.3, (23, 12, 6, 8)).astype(np.float32)
    whole = recognizer.predict_proba(windows)
    monkeypatch.setattr(onnx_runtime, "MAX_CHUNK", 5)
    np.testing.assert_allclose(recognizer.predict_proba(windows), whole, atol=1e-6)


def test_missing_or_corrupt_graph(tmp_path: Path) -> None:
    make_checkpoint(tmp_path, "tcn", 6, 8, 12, 4)
    graph = tmp_path / ONNX_FILE
    graph.write_bytes(b"not an onnx graph")
    with pytest.raises(CheckpointError, match="cannot load") as info:
        OnnxRecognizer(tmp_path)
    assert "\n" not in str(info.value)
    graph.unlink()
    with pytest.raises(CheckpointError, match="has no model.onnx"):
        OnnxRecognizer(tmp_path)
    with pytest.raises(CheckpointError, match="no checkpoint directory"):
        OnnxRecognizer(tmp_path / "absent")
    with pytest.raises(ValueError, match="threads"):
        OnnxRecognizer(tmp_path, threads=0)


def test_graph_and_meta_must_agree(tmp_path: Path) -> None:
    make_checkpoint(tmp_path / "a", "tcn", 6, 8, 12, 4)
    make_checkpoint(tmp_path / "b", "tcn", 6, 8, 16, 4)
    (tmp_path / "a" / ONNX_FILE).write_bytes((tmp_path / "b" / ONNX_FILE).read_bytes())
    with pytest.raises(CheckpointError, match="meta.json says"):
        OnnxRecognizer(tmp_path / "a")


def test_export_verification_catches_a_broken_graph(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    model = build_model("tcn", 6, 8, 12, 4)
    meta = CheckpointMeta("tcn", {}, ("a", "b", "c", "d"), 6, 8, 12, 200.0, {})
    real_softmax = onnx_runtime.softmax
    calls = iter(range(100))

    def skewed_softmax(logits: np.ndarray) -> np.ndarray:
        p = real_softmax(logits)
        return p if next(calls) % 2 == 0 else np.roll(p, 1, axis=1)  # ORT side differs

    monkeypatch.setattr(onnx_runtime, "softmax", skewed_softmax)
    with pytest.raises(RuntimeError, match="differs from torch"):
        export_onnx(model, meta, tmp_path / "m.onnx")
    assert not (tmp_path / "m.onnx").exists()


def test_export_keeps_the_training_mode(tmp_path: Path) -> None:
    model = build_model("transformer", 6, 8, 12, 4).train()
    meta = CheckpointMeta("transformer", {}, ("a", "b", "c", "d"), 6, 8, 12, 200.0, {})
    export_onnx(model, meta, tmp_path / "m.onnx")
    assert model.training
    assert (tmp_path / "m.onnx").stat().st_size > 10_000


def test_softmax_is_stable() -> None:
    p = softmax(np.array([[1000.0, 0.0, -1000.0], [0.0, 0.0, 0.0]]))
    np.testing.assert_allclose(p[0], [1.0, 0.0, 0.0])
    np.testing.assert_allclose(p[1], [1 / 3] * 3, rtol=1e-6)
