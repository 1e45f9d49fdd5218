"""The trained default model shipped inside the package, and how to find it.

The checkpoint directory ``wovenskin/models/default/`` holds ``meta.json`` and
``model.onnx`` (all that inference needs, with ONNX Runtime) and ``MODEL_CARD.md`` (its
data, the command that reproduces it, and its measured figures).
The default is the stream-recipe transformer, shipped with its torch weights
(``model.pt``, to fine-tune), ``history.json`` and ``learning_curve.png``.
``wovenskin/models/overlay/`` keeps the previous default (the paper's overlay recipe) for
comparison.
"""

from __future__ import annotations

from pathlib import Path

DEFAULT_MODEL_DIR = Path(__file__).resolve().parent.parent / "models" / "default"


class ModelNotFoundError(FileNotFoundError):
    """No usable checkpoint at the given (or the default) location."""


def default_model_dir() -> Path:
    """The shipped default checkpoint directory; a one-line error if it is missing."""
    if not (DEFAULT_MODEL_DIR / "model.onnx").is_file():
        raise ModelNotFoundError(
            f"the shipped default model is missing ({DEFAULT_MODEL_DIR}); "
            "reinstall wovenskin or pass --model DIR"
        )
    return DEFAULT_MODEL_DIR


def resolve_model_dir(path: str | Path | None) -> Path:
    """``path`` (a checkpoint directory) when given, else the shipped default model."""
    if path is None:
        return default_model_dir()
    directory = Path(path)
    if not directory.is_dir():
        raise ModelNotFoundError(f"{directory}: no such model directory")
    if not (directory / "model.onnx").is_file():
        raise ModelNotFoundError(f"{directory}: no model.onnx (train or export the model first)")
    return directory
