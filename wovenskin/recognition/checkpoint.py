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

This module imports torch only inside :func:`save_checkpoint` and :func:`load_checkpoint`,
so :func:`read_meta` and :class:`CheckpointMeta` serve torch-free inference.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field, fields, replace
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from torch import nn

META_FILE = "meta.json"
WEIGHTS_FILE = "model.pt"
ONNX_FILE = "model.onnx"
FORMAT_VERSION = 1
SAMPLE_RATE_REL_TOL = 1e-3
"""Sample rates within 0.1 % count as the same nominal rate."""


class CheckpointError(ValueError):
    """A checkpoint directory is missing, incomplete or corrupt."""


def _conditioning_dict(conditioning: Any) -> dict[str, Any]:
    """A conditioning config as a plain dict (accepts a mapping or an object with ``to_dict``)."""
    if conditioning is None:
        return {}
    if isinstance(conditioning, Mapping):
        return dict(conditioning)
    to_dict = getattr(conditioning, "to_dict", None)
    if callable(to_dict):
        return dict(to_dict())
    raise TypeError(f"conditioning must be a mapping or have to_dict(), got {type(conditioning)}")


def _same_value(a: Any, b: Any) -> bool:
    if isinstance(a, bool) or isinstance(b, bool):
        return isinstance(a, bool) and isinstance(b, bool) and a == b
    if isinstance(a, int | float) and isinstance(b, int | float):
        return math.isclose(float(a), float(b), rel_tol=1e-9, abs_tol=1e-12)
    if isinstance(a, list | tuple) and isinstance(b, list | tuple):
        return len(a) == len(b) and all(_same_value(x, y) for x, y in zip(a, b, strict=True))
    return a == b


def conditioning_differences(expected: Mapping[str, Any], given: Mapping[str, Any]) -> list[str]:
    """Human-readable ``key: expected X, got Y`` lines for every setting that differs."""
    missing = object()
    out = []
    for key in sorted(set(expected) | set(given)):
        a, b = expected.get(key, missing), given.get(key, missing)
        if a is missing or b is missing or not _same_value(a, b):
            shown_a = "unset" if a is missing else repr(a)
            shown_b = "unset" if b is missing else repr(b)
            out.append(f"{key}: model {shown_a}, input {shown_b}")
    return out


@dataclass(frozen=True)
class CheckpointMeta:
    """Everything a consumer must know to feed a checkpoint, and how it was made."""

    model_name: str
    hparams: dict[str, Any]
    class_names: tuple[str, ...]
    rows: int
    cols: int
    window: int
    sample_rate_hz: float
    conditioning: dict[str, Any]
    row_pitch_mm: float | None = None
    col_pitch_mm: float | None = None
    training_data: dict[str, Any] = field(default_factory=dict)
    metrics: dict[str, Any] = field(default_factory=dict)
    # execution settings measured to suit this model (e.g. {"min_probability": 0.9}); used
    # by the live pipeline unless the user gives their own
    arbiter: dict[str, Any] = field(default_factory=dict)
    torch_version: str = ""
    wovenskin_version: str = ""
    created: str = ""
    format_version: int = FORMAT_VERSION

    def __post_init__(self) -> None:
        object.__setattr__(self, "class_names", tuple(str(c) for c in self.class_names))
        if len(self.class_names) < 2:
            raise ValueError(f"a checkpoint needs at least 2 classes, got {len(self.class_names)}")
        if len(set(self.class_names)) != len(self.class_names):
            raise ValueError(f"duplicate class names in {list(self.class_names)}")
        if self.rows < 1 or self.cols < 1 or self.window < 1:
            raise ValueError(
                f"bad input shape: {self.rows}x{self.cols} grid, {self.window}-frame window"
            )
        if not (self.sample_rate_hz > 0 and math.isfinite(self.sample_rate_hz)):
            raise ValueError(f"sample rate must be positive, got {self.sample_rate_hz}")

    @property
    def n_classes(self) -> int:
        return len(self.class_names)

    @property
    def input_shape(self) -> tuple[int, int, int]:
        """``(window, rows, cols)`` of one input window."""
        return (self.window, self.rows, self.cols)

    def describe_input(self) -> str:
        """E.g. ``"30-frame windows of 10x10 frames at 200 Hz"``."""
        return (
            f"{self.window}-frame windows of {self.rows}x{self.cols} frames "
            f"at {self.sample_rate_hz:g} Hz"
        )

    def check_input(
        self,
        rows: int,
        cols: int,
        window: int,
        sample_rate_hz: float,
        conditioning: Mapping[str, Any] | Any,
    ) -> None:
        """Raise a one-line ``ValueError`` unless the input matches the training input."""
        if (rows, cols) != (self.rows, self.cols) or not math.isclose(
            sample_rate_hz, self.sample_rate_hz, rel_tol=SAMPLE_RATE_REL_TOL
        ):
            raise ValueError(
                f"model expects {self.rows}x{self.cols} frames at {self.sample_rate_hz:g} Hz, "
                f"got {rows}x{cols} at {sample_rate_hz:g} Hz"
            )
        if window != self.window:
            raise ValueError(f"model expects windows of {self.window} frames, got {window}")
        differences = conditioning_differences(self.conditioning, _conditioning_dict(conditioning))
        if differences:
            more = f" (+{len(differences) - 3} more)" if len(differences) > 3 else ""
            raise ValueError(
                "model was trained with other conditioning settings: "
                + "; ".join(differences[:3])
                + more
            )

    def with_updates(self, **changes: Any) -> CheckpointMeta:
        """A copy with some fields replaced."""
        return replace(self, **changes)

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["class_names"] = list(self.class_names)
        return d

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> CheckpointMeta:
        if not isinstance(d, Mapping):
            raise CheckpointError(f"checkpoint meta must be a JSON object, got {type(d).__name__}")
        version = d.get("format_version", FORMAT_VERSION)
        if version != FORMAT_VERSION:
            raise CheckpointError(f"unsupported checkpoint format version {version!r}")
        known = {f.name for f in fields(cls)}
        required = ("model_name", "hparams", "class_names", "rows", "cols", "window")
        missing = [k for k in (*required, "sample_rate_hz", "conditioning") if k not in d]
        if missing:
            raise CheckpointError(f"checkpoint meta lacks {', '.join(missing)}")
        try:
            values = {k: v for k, v in d.items() if k in known}
            for key in ("rows", "cols", "window"):
                values[key] = int(values[key])
            values["sample_rate_hz"] = float(values["sample_rate_hz"])
            for key in ("row_pitch_mm", "col_pitch_mm"):
                if values.get(key) is not None:
                    values[key] = float(values[key])
            for key in ("hparams", "conditioning", "training_data", "metrics", "arbiter"):
                if key in values and not isinstance(values[key], Mapping):
                    raise TypeError(f"{key} must be an object")
            return cls(**values)
        except (TypeError, ValueError) as exc:
            raise CheckpointError(f"bad checkpoint meta: {exc}") from None


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file and a rename (no torn files)."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def write_meta(directory: str | Path, meta: CheckpointMeta) -> Path:
    """Write ``meta.json`` into ``directory`` (created if needed); return its path."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    path = directory / META_FILE
    text = json.dumps(meta.to_dict(), indent=2, sort_keys=False, allow_nan=False) + "\n"
    atomic_write_bytes(path, text.encode("utf-8"))
    return path


def read_meta(directory: str | Path) -> CheckpointMeta:
    """Read ``meta.json`` of a checkpoint directory (no torch needed)."""
    directory = Path(directory)
    path = directory / META_FILE
    if not directory.is_dir():
        raise CheckpointError(f"no checkpoint directory at {directory}")
    if not path.is_file():
        raise CheckpointError(f"checkpoint {directory} has no {META_FILE}")
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise CheckpointError(f"cannot read {path}: {exc}") from None
    return CheckpointMeta.from_dict(data)


def _versions() -> tuple[str, str]:
    import torch

    import wovenskin

    return torch.__version__, getattr(wovenskin, "__version__", "")


def _check_model_matches(model: nn.Module, meta: CheckpointMeta) -> None:
    from wovenskin.recognition.models import MODEL_REGISTRY

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
    import io

    import torch

    _check_model_matches(model, meta)
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    torch_version, wovenskin_version = _versions()
    meta = meta.with_updates(
        torch_version=torch_version,
        wovenskin_version=wovenskin_version,
        created=datetime.now(UTC).isoformat(timespec="seconds"),
    )
    buffer = io.BytesIO()
    torch.save(model.state_dict(), buffer)
    atomic_write_bytes(directory / WEIGHTS_FILE, buffer.getvalue())
    if export_onnx:
        from wovenskin.recognition.onnx_runtime import export_onnx as export

        export(model, meta, directory / ONNX_FILE)
    else:
        (directory / ONNX_FILE).unlink(missing_ok=True)
    write_meta(directory, meta)
    return meta


def load_checkpoint(directory: str | Path) -> tuple[nn.Module, CheckpointMeta]:
    """Rebuild the torch model of a checkpoint directory, in eval mode, with its meta."""
    import torch

    from wovenskin.recognition.models import build_model

    meta = read_meta(directory)
    path = Path(directory) / WEIGHTS_FILE
    if not path.is_file():
        raise CheckpointError(f"checkpoint {directory} has no {WEIGHTS_FILE}")
    hparams = dict(meta.hparams)
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
        if "level_input" not in hparams:
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
