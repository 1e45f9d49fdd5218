"""Checkpoint metadata: the input contract of a model, read and written without torch.

Owns the file names of a checkpoint directory, :class:`CheckpointMeta` (``meta.json``),
:func:`read_meta`, :func:`write_meta` and
:class:`CheckpointError`.  :meth:`CheckpointMeta.check_input` is the guard every consumer
calls before feeding a model: it refuses frames from another grid, window length, sample
rate or conditioning with one :class:`ModelInputError` line (a ``ValueError``) naming what
differs, which the command line prints as it is.

Both :mod:`~wovenskin.recognition.onnx_runtime` (torch-free inference) and
:mod:`~wovenskin.training.checkpoint` (saving and loading torch models) build on this
module, which imports neither; :mod:`~wovenskin.training.checkpoint` re-exports every
name here.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field, fields, replace
from pathlib import Path
from typing import Any

from wovenskin.errors import DataError
from wovenskin.io import atomic_write_bytes, plain_dict
from wovenskin.signal.config import FLAG_ONLY_SETTINGS

META_FILE = "meta.json"
WEIGHTS_FILE = "model.pt"
ONNX_FILE = "model.onnx"
FORMAT_VERSION = 1
SAMPLE_RATE_REL_TOL = 1e-3
"""Sample rates within 0.1 % count as the same nominal rate."""


class CheckpointError(ValueError):
    """A checkpoint directory is missing, incomplete or corrupt."""


class ModelInputError(DataError):
    """Frames a model was not trained for: another grid, rate, window or conditioning."""


def _conditioning_dict(conditioning: Any) -> dict[str, Any]:
    """A conditioning config as a plain dict (accepts a mapping or an object with ``to_dict``)."""
    return {} if conditioning is None else plain_dict(conditioning, "conditioning")


def _same_value(a: Any, b: Any) -> bool:
    if isinstance(a, bool) or isinstance(b, bool):
        return isinstance(a, bool) and isinstance(b, bool) and a == b
    if isinstance(a, int | float) and isinstance(b, int | float):
        return math.isclose(float(a), float(b), rel_tol=1e-9, abs_tol=1e-12)
    if isinstance(a, list | tuple) and isinstance(b, list | tuple):
        return len(a) == len(b) and all(_same_value(x, y) for x, y in zip(a, b, strict=True))
    return a == b


def conditioning_differences(expected: Mapping[str, Any], given: Mapping[str, Any]) -> list[str]:
    """Human-readable ``key: expected X, got Y`` lines for every setting that differs
    (settings that never change the model's input, ``FLAG_ONLY_SETTINGS``, do not count)."""
    missing = object()
    out = []
    for key in sorted((set(expected) | set(given)) - FLAG_ONLY_SETTINGS):
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
    # the reader recommended for this model ({"kind": "touch", its settings and its own
    # "arbiter" settings}; empty: the paper's window-by-window reading)
    reader: dict[str, Any] = field(default_factory=dict)
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
        """Raise one :class:`ModelInputError` line unless the input matches the training input."""
        if (rows, cols) != (self.rows, self.cols) or not math.isclose(
            sample_rate_hz, self.sample_rate_hz, rel_tol=SAMPLE_RATE_REL_TOL
        ):
            raise ModelInputError(
                f"model expects {self.rows}x{self.cols} frames at {self.sample_rate_hz:g} Hz, "
                f"got {rows}x{cols} at {sample_rate_hz:g} Hz: use a model trained for this "
                "skin (docs/skins.md)"
            )
        if window != self.window:
            raise ModelInputError(f"model expects windows of {self.window} frames, got {window}")
        differences = conditioning_differences(self.conditioning, _conditioning_dict(conditioning))
        if differences:
            more = f" (+{len(differences) - 3} more)" if len(differences) > 3 else ""
            raise ModelInputError(
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
            for key in ("hparams", "conditioning", "training_data", "metrics", "arbiter", "reader"):
                if key in values and not isinstance(values[key], Mapping):
                    raise TypeError(f"{key} must be an object")
            return cls(**values)
        except (TypeError, ValueError) as exc:
            raise CheckpointError(f"bad checkpoint meta: {exc}") from None


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
