"""A tiny, untrained TCN checkpoint for tests that need a model the pipeline can run: the
shipped model's grid, window and classes, exported to ONNX like it, in a fraction of a
second; and the settings of a tiny simulated data set to train such models on."""

from __future__ import annotations

from pathlib import Path

import torch

from wovenskin.gestures import CLASS_NAMES
from wovenskin.recognition.checkpoint_meta import CheckpointMeta
from wovenskin.signal import ConditioningConfig
from wovenskin.training.checkpoint import save_checkpoint
from wovenskin.training.models import build_model

HPARAMS = {"dim": 16, "n_blocks": 2, "stem_channels": 8}
TINY_SIM_SET = dict(
    n_recordings=3,
    windows_per_recording=40,
    invalid_windows_per_recording=10,
    seconds_per_recording=20.0,
    workers=1,
)
"""``generate_sim_dataset`` settings (all but the seed) for a data set built in seconds."""


def save_tiny_model(
    directory: Path, seed: int = 1, *, decisive: bool = False, conditioning: dict | None = None
) -> Path:
    """Write a tiny TCN checkpoint into ``directory``. ``decisive``: its logits spread
    widely (the last layer times 30), so its classes change often and it fires; else its
    outputs are nearly uniform."""
    torch.manual_seed(seed)
    model = build_model("tcn", 10, 10, 30, len(CLASS_NAMES), **HPARAMS)
    if decisive:
        with torch.no_grad():
            last = [m for m in model.modules() if isinstance(m, torch.nn.Linear)][-1]
            last.weight.mul_(30.0)
            last.bias.mul_(30.0)
    meta = CheckpointMeta(
        model_name="tcn", hparams=dict(HPARAMS), class_names=CLASS_NAMES, rows=10, cols=10,
        window=30, sample_rate_hz=200.0,
        conditioning=ConditioningConfig().to_dict() if conditioning is None else conditioning,
    )  # fmt: skip
    save_checkpoint(directory, model, meta)
    return directory
