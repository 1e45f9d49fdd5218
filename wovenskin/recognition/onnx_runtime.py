"""ONNX export of trained models and torch-free inference with ONNX Runtime.

:func:`export_onnx` writes a model as an ONNX graph (opset 17, input ``windows`` of shape
``(batch, W, R, C)`` float32 with a dynamic batch axis, output ``logits`` ``(batch, K)``)
and checks that ONNX Runtime reproduces torch on random windows. It imports torch when
called; nothing else here needs it.

:class:`OnnxRecognizer` is what live inference uses: it loads ``model.onnx`` and
``meta.json`` of a checkpoint directory with onnxruntime only, validates every input
(shape, dtype, NaN/inf) with a one-line ``ValueError``, and returns class probabilities.
Importing this module does not import torch.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from wovenskin.io import atomic_write_bytes
from wovenskin.recognition.checkpoint_meta import (
    ONNX_FILE,
    CheckpointError,
    CheckpointMeta,
    read_meta,
)

if TYPE_CHECKING:
    from torch import nn

OPSET = 17
INPUT_NAME = "windows"
OUTPUT_NAME = "logits"
VERIFY_ATOL = 1e-4
"""Largest probability difference between torch and ONNX Runtime that export accepts."""
MAX_CHUNK = 1024
"""Windows per ONNX Runtime call inside :meth:`OnnxRecognizer.predict_proba` (bounds memory)."""
ONNX_THREADS = 1
"""ONNX Runtime threads of a recogniser unless asked otherwise (the commands' ``--threads``):
one, fastest for batch-1 live inference on a busy machine."""


def softmax(logits: np.ndarray) -> np.ndarray:
    """Row-wise softmax of ``(B, K)`` logits, computed stably in float64, returned float32."""
    z = np.asarray(logits, dtype=np.float64)
    z = z - z.max(axis=-1, keepdims=True)
    e = np.exp(z)
    return (e / e.sum(axis=-1, keepdims=True)).astype(np.float32)


def _session(model_bytes_or_path: bytes | str, threads: int) -> Any:
    import onnxruntime as ort

    options = ort.SessionOptions()
    options.intra_op_num_threads = threads
    options.inter_op_num_threads = 1
    options.execution_mode = ort.ExecutionMode.ORT_SEQUENTIAL
    options.graph_optimization_level = ort.GraphOptimizationLevel.ORT_ENABLE_ALL
    options.log_severity_level = 3  # errors only
    return ort.InferenceSession(
        model_bytes_or_path, sess_options=options, providers=["CPUExecutionProvider"]
    )


def export_onnx(
    model: nn.Module, meta: CheckpointMeta, path: str | Path, *, verify: bool = True
) -> Path:
    """Export ``model`` (built for ``meta``'s input) to ``path`` as ONNX; return the path.

    The legacy TorchScript exporter is used (``dynamo=False``): it needs no extra packages
    and handles every registry model. With ``verify`` the graph is run in ONNX Runtime on
    random windows of batch 1 and 3 and must match torch within :data:`VERIFY_ATOL` on
    probabilities, else ``RuntimeError``.
    """
    import io
    import warnings

    import torch

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    was_training = model.training
    model.eval()
    try:
        example = torch.zeros((1, *meta.input_shape), dtype=torch.float32)
        buffer = io.BytesIO()
        with warnings.catch_warnings():
            # The exporter warns about tracing internals of nn.LSTM / attention that do not
            # affect the graph (the batch axis is declared dynamic below).
            warnings.simplefilter("ignore")
            torch.onnx.export(
                model,
                (example,),
                buffer,
                dynamo=False,
                opset_version=OPSET,
                input_names=[INPUT_NAME],
                output_names=[OUTPUT_NAME],
                dynamic_axes={INPUT_NAME: {0: "batch"}, OUTPUT_NAME: {0: "batch"}},
                do_constant_folding=True,
            )
        graph = buffer.getvalue()
        if verify:
            _verify(model, graph, meta)
    finally:
        model.train(was_training)
    atomic_write_bytes(path, graph)
    return path


def _verify(model: nn.Module, graph: bytes, meta: CheckpointMeta) -> None:
    import torch

    session = _session(graph, threads=1)
    generator = torch.Generator().manual_seed(0)
    scale = float(getattr(model, "input_scale", torch.ones(())))
    for batch in (1, 3):
        windows = torch.randn((batch, *meta.input_shape), generator=generator) * scale
        with torch.inference_mode():
            expected = softmax(model(windows).numpy())
        got = softmax(session.run([OUTPUT_NAME], {INPUT_NAME: windows.numpy()})[0])
        error = float(np.max(np.abs(expected - got)))
        if not error <= VERIFY_ATOL:
            raise RuntimeError(
                f"ONNX export of {meta.model_name!r} differs from torch by {error:.2e} "
                f"(batch {batch}; tolerance {VERIFY_ATOL:g})"
            )


class OnnxRecognizer:
    """A checkpoint's ONNX graph in ONNX Runtime: windows in, class probabilities out."""

    def __init__(self, checkpoint_dir: str | Path, threads: int = ONNX_THREADS) -> None:
        if threads < 1:
            raise ValueError(f"threads must be at least 1, got {threads}")
        self.checkpoint_dir = Path(checkpoint_dir)
        self.meta: CheckpointMeta = read_meta(self.checkpoint_dir)
        graph_path = self.checkpoint_dir / ONNX_FILE
        if not graph_path.is_file():
            raise CheckpointError(f"checkpoint {self.checkpoint_dir} has no {ONNX_FILE}")
        try:
            self._session = _session(str(graph_path), threads)
        except Exception as exc:  # onnxruntime raises its own exception types
            first_line = str(exc).strip().splitlines()[0] if str(exc).strip() else repr(exc)
            raise CheckpointError(f"cannot load {graph_path}: {first_line}") from None
        inputs = self._session.get_inputs()
        outputs = self._session.get_outputs()
        if [i.name for i in inputs] != [INPUT_NAME] or OUTPUT_NAME not in [o.name for o in outputs]:
            raise CheckpointError(f"{graph_path} is not a wovenskin recogniser graph")
        declared = inputs[0].shape[1:]
        if list(declared) != list(self.meta.input_shape):
            raise CheckpointError(
                f"{graph_path} takes windows of shape {declared}, meta.json says "
                f"{list(self.meta.input_shape)}"
            )
        self.threads = threads

    @property
    def class_names(self) -> tuple[str, ...]:
        return self.meta.class_names

    @property
    def n_classes(self) -> int:
        return self.meta.n_classes

    def check_input(
        self,
        rows: int,
        cols: int,
        window: int,
        sample_rate_hz: float,
        conditioning: Any,
    ) -> None:
        """Refuse a stream that does not match the checkpoint (see ``CheckpointMeta``)."""
        self.meta.check_input(rows, cols, window, sample_rate_hz, conditioning)

    def _validated(self, windows: np.ndarray | Sequence[Any]) -> np.ndarray:
        array = np.asarray(windows)
        expected = self.meta.input_shape
        if array.ndim == 3:
            array = array[np.newaxis]
        if array.ndim != 4 or tuple(array.shape[1:]) != expected:
            raise ValueError(
                f"expected windows of shape (B, {expected[0]}, {expected[1]}, {expected[2]}) "
                f"or one ({expected[0]}, {expected[1]}, {expected[2]}) window, "
                f"got {np.shape(windows)}"
            )
        if array.dtype.kind not in "fiub":
            raise ValueError(f"windows must be numeric, got dtype {array.dtype}")
        array = np.ascontiguousarray(array, dtype=np.float32)
        finite = np.isfinite(array).all(axis=(1, 2, 3))
        if not finite.all():
            bad = np.flatnonzero(~finite)
            raise ValueError(
                f"windows contain NaN or inf values (window {bad[0]}"
                + (f" and {bad.size - 1} more" if bad.size > 1 else "")
                + ")"
            )
        return array

    def predict_logits(self, windows: np.ndarray) -> np.ndarray:
        """``(B, K)`` float32 logits for ``(B, W, R, C)`` windows (or one ``(W, R, C)`` window)."""
        array = self._validated(windows)
        if array.shape[0] == 0:
            return np.zeros((0, self.n_classes), dtype=np.float32)
        parts = [
            self._session.run([OUTPUT_NAME], {INPUT_NAME: array[i : i + MAX_CHUNK]})[0]
            for i in range(0, array.shape[0], MAX_CHUNK)
        ]
        return np.concatenate(parts, axis=0).astype(np.float32, copy=False)

    def predict_proba(self, windows: np.ndarray) -> np.ndarray:
        """``(B, K)`` float32 class probabilities, columns in :attr:`class_names` order."""
        return softmax(self.predict_logits(windows))

    def predict(self, windows: np.ndarray) -> np.ndarray:
        """``(B,)`` int64 index of the most probable class of every window."""
        return np.argmax(self.predict_logits(windows), axis=1).astype(np.int64)
