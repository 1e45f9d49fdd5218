"""The settings of ``wovenskin adapt``, one dataclass with every default written once.

Torch-free, so the command line reads its defaults from here without loading PyTorch.
How each was measured is in ``docs/adapt.md`` and ``docs/benchmarks.md``.
"""

from __future__ import annotations

from dataclasses import dataclass

from wovenskin.errors import ConfigError


@dataclass(frozen=True)
class AdaptSettings:
    """How ``adapt`` splits, trains and chooses (defaults measured, docs/adapt.md)."""

    held_out_fraction: float = 0.25
    seed: int = 0
    epochs: int = 4
    lr: float = 3e-4
    """Peak learning rate when every class and layer is the base model's: low, so the
    person's few trials move the model without unlearning other people."""
    new_class_lr: float = 1e-3
    """Peak learning rate when a class is new (a gesture of the person's own) or a layer is
    learnt afresh (another grid): at 3e-4 a new class was never learnt in 4 epochs
    (docs/benchmarks.md, "bench adapt")."""
    batch_size: int = 64
    user_windows: int = 4000
    """Gesture windows cut from the person's trained trials (all streams together)."""
    user_invalid_windows: int = 1600
    rehearsal_recordings: int = 12
    """Simulated other people (each a new person and skin, 60 s) mixed into training."""
    rehearsal_windows: int = 300
    """Gesture windows per rehearsal recording (plus 40 % as many invalid ones)."""
    threads: int = 1
    force: bool = False
    """Install the adapted model even when it scores worse than the base."""

    def __post_init__(self) -> None:
        if not 0.0 < self.held_out_fraction < 1.0:
            raise ConfigError(
                f"the held-out share must lie in (0, 1), got {self.held_out_fraction}"
            )
        for name in ("epochs", "batch_size", "user_windows", "threads"):
            if getattr(self, name) < 1:
                raise ConfigError(f"{name} must be at least 1, got {getattr(self, name)}")
        if self.rehearsal_recordings < 0 or self.rehearsal_windows < 1:
            raise ConfigError("rehearsal needs recordings >= 0 and windows >= 1")
        if not (self.lr > 0 and self.new_class_lr > 0):
            raise ConfigError(
                f"learning rates must be positive, got {self.lr}, {self.new_class_lr}"
            )
