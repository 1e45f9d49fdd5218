"""Starting a model from another's weights when classes or the grid differ (``wovenskin adapt``).

:func:`transferred_model` builds the registry model for the new class list and grid and
fills it from a trained one:

- every parameter and buffer whose name and shape match is copied (the convolutions, the
  transformer or LSTM, the input scale);
- the classifier's output layer (the last ``nn.Linear`` whose outputs are the classes)
  keeps each known class's row, wherever that class now sits in the list; a new class
  (a user's own gesture) starts from the mean of the known gestures' rows, so at first
  it is scored like "some gesture" and training moves it from there;
- a grid-dependent layer that cannot be copied (the frame stem's projection of a 10 x 10
  frame is another size on an 8 x 8 skin) keeps its fresh initialisation and is reported.

The class order of a transferred model is the old one with new classes inserted before
``invalid``, which stays last.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import torch
from torch import nn

from wovenskin.errors import ConfigError
from wovenskin.gestures import INVALID
from wovenskin.training.models import WindowClassifier, build_model


@dataclass(frozen=True)
class Transfer:
    """What :func:`transferred_model` copied, extended and left fresh."""

    copied: tuple[str, ...]
    new_classes: tuple[str, ...]
    reinitialised: tuple[str, ...]

    def describe(self) -> str:
        parts = [f"{len(self.copied)} tensors copied"]
        if self.new_classes:
            parts.append(f"new classes: {', '.join(self.new_classes)}")
        if self.reinitialised:
            parts.append(f"learnt afresh for the new grid: {', '.join(self.reinitialised)}")
        return "; ".join(parts)


def merged_classes(old: Sequence[str], wanted: Sequence[str]) -> list[str]:
    """``old`` with the classes of ``wanted`` it lacks inserted before ``invalid`` (kept last)."""
    old = list(old)
    if INVALID not in old:
        raise ConfigError(f"the base model has no {INVALID!r} class")
    extra = [name for name in dict.fromkeys(wanted) if name not in old]
    body = [name for name in old if name != INVALID]
    return [*body, *extra, INVALID]


def _output_layer(model: nn.Module, n_classes: int) -> str:
    """Name of the last ``nn.Linear`` with ``n_classes`` outputs (the classifier's)."""
    names = [
        name
        for name, module in model.named_modules()
        if isinstance(module, nn.Linear) and module.out_features == n_classes
    ]
    if not names:
        raise ConfigError("cannot find the model's output layer to add classes to")
    return names[-1]


def transferred_model(
    base: WindowClassifier,
    base_classes: Sequence[str],
    model_name: str,
    hparams: dict,
    classes: Sequence[str],
    rows: int,
    cols: int,
    window: int,
) -> tuple[WindowClassifier, Transfer]:
    """A ``model_name`` model for ``classes`` on a ``rows`` x ``cols`` grid, started from
    ``base`` (trained for ``base_classes``); see the module doc."""
    if window != base.window:
        raise ConfigError(
            f"the base model reads {base.window}-frame windows; this run needs {window}"
        )
    missing = [name for name in base_classes if name not in classes]
    if missing:
        raise ConfigError(f"the new class list drops the base model's {', '.join(missing)}")
    model = build_model(model_name, rows, cols, window, len(classes), **hparams)
    old_head = _output_layer(base, len(base_classes))
    new_head = _output_layer(model, len(classes))
    theirs = base.state_dict()
    ours = model.state_dict()
    copied, fresh = [], []
    for key, value in ours.items():
        if key.startswith(new_head + "."):
            continue
        if key in theirs and theirs[key].shape == value.shape:
            ours[key] = theirs[key].clone()
            copied.append(key)
        elif not key.startswith("positions"):
            fresh.append(key.rsplit(".", 1)[0])
    index = {name: i for i, name in enumerate(base_classes)}
    gestures = [index[name] for name in base_classes if name != INVALID]
    for part in ("weight", "bias"):
        old = theirs[f"{old_head}.{part}"]
        rows_out = [
            old[index[name]] if name in index else old[gestures].mean(dim=0) for name in classes
        ]
        ours[f"{new_head}.{part}"] = torch.stack(rows_out).clone()
    copied.append(f"{new_head} (rows of known classes)")
    model.load_state_dict(ours)
    new = tuple(name for name in classes if name not in index)
    return model, Transfer(tuple(copied), new, tuple(dict.fromkeys(fresh)))
