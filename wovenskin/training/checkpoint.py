"""Model checkpoints: a directory holding weights, the ONNX graph and the input contract.

A checkpoint directory holds

- ``meta.json``: :class:`CheckpointMeta` -- model name and hyperparameters, class names,
  grid (rows, cols, pitches when known), window length, sample rate, the conditioning
  settings the training data went through, a description of the training data, metrics,
  torch and wovenskin versions and the creation time;
- ``model.pt``: the PyTorch state dict (loaded with ``weights_only=True``);
- ``model.onnx``: the same network for ONNX Runtime (:mod:`~wovenskin.recognition.onnx_runtime`).

:meth:`CheckpointMeta.check_input` is the guard every consumer calls before feeding a
model: it refuses frames from another grid, window length, sample rate or conditioning
with a one-line ``ValueError`` naming what differs.

The metadata side (:class:`CheckpointMeta`, :func:`read_meta`, :func:`write_meta`, the
file names) lives in :mod:`~wovenskin.recognition.checkpoint_meta` and is re-exported
here, so :mod:`~wovenskin.recognition.onnx_runtime` needs only that lower module and the
imports run one way; torch-free code reads metadata from there.  This module needs torch.
"""

from __future__ import annotations

import io
from datetime import UTC, datetime
from pathlib import Path

import torch
from torch import nn

from wovenskin import __version__
from wovenskin.io import atomic_write_bytes
from wovenskin.recognition.checkpoint_meta import (
    ONNX_FILE,
    WEIGHTS_FILE,
    CheckpointError,
    CheckpointMeta,
    read_meta,
    write_meta,
)
from wovenskin.recognition.onnx_runtime import export_onnx as _export_onnx
from wovenskin.training.models import MODEL_REGISTRY, build_model, resolve_hparams


def _check_model_matches(model: nn.Module, meta: CheckpointMeta) -> None:
    expected_type = MODEL_REGISTRY.get(meta.model_name)
    if expected_type is None:
        raise ValueError(f"unknown model {meta.model_name!r}; known: {', '.join(MODEL_REGISTRY)}")
    if type(model) is not expected_type:
        raise ValueError(
            f"meta names model {meta.model_name!r} but the model is a {type(model).__name__}"
        )
    shape = (model.rows, model.cols, model.window, model.n_classes)
    if shape != (meta.rows, meta.cols, meta.window, meta.n_classes):
        raise ValueError(
            f"model is built for {shape[0]}x{shape[1]} frames, {shape[2]}-frame windows and "
            f"{shape[3]} classes; meta says {meta.rows}x{meta.cols}, {meta.window} and "
            f"{meta.n_classes}"
        )


def save_checkpoint(
    directory: str | Path, model: nn.Module, meta: CheckpointMeta, *, export_onnx: bool = True
) -> CheckpointMeta:
    """Save ``model`` and ``meta`` into ``directory``; return the meta as written.

    Versions and the creation time are filled in. With ``export_onnx`` the ONNX graph is
    exported (and verified against torch) too; without it any older ``model.onnx`` is
    removed, so the directory never pairs weights with a stale graph.
    """
    _check_model_matches(model, meta)
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    meta = meta.with_updates(
        torch_version=torch.__version__,
        wovenskin_version=__version__,
        created=datetime.now(UTC).isoformat(timespec="seconds"),
    )
    buffer = io.BytesIO()
    torch.save(model.state_dict(), buffer)
    atomic_write_bytes(directory / WEIGHTS_FILE, buffer.getvalue())
    if export_onnx:
        _export_onnx(model, meta, directory / ONNX_FILE)
    else:
        (directory / ONNX_FILE).unlink(missing_ok=True)
    write_meta(directory, meta)
    return meta


def load_checkpoint(directory: str | Path) -> tuple[nn.Module, CheckpointMeta]:
    """Rebuild the torch model of a checkpoint directory, in eval mode, with its meta."""
    meta = read_meta(directory)
    path = Path(directory) / WEIGHTS_FILE
    if not path.is_file():
        raise CheckpointError(f"checkpoint {directory} has no {WEIGHTS_FILE}")
    hparams = dict(meta.hparams)
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
        if "level_input" not in hparams and "level_input" in resolve_hparams(meta.model_name):
            # Checkpoints made before ``level_input`` existed always fed the level.
            lstm_in = state.get("lstm.weight_ih_l0")
            hparams["level_input"] = any(k.startswith("level.") for k in state) or (
                lstm_in is not None and lstm_in.shape[1] == meta.rows * meta.cols + 1
            )
        model = build_model(
            meta.model_name, meta.rows, meta.cols, meta.window, meta.n_classes, **hparams
        )
        model.load_state_dict(state)
    except Exception as exc:  # torch raises RuntimeError, pickle/zip errors, EOFError...
        first_line = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise CheckpointError(f"cannot load weights {path}: {first_line}") from None
    model.eval()
    return model, meta
