"""How training windows are cut: :class:`WindowSettings`, the recipes and the window sources."""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from wovenskin.settings import from_dict

SOURCE_NAMES: tuple[str, ...] = (
    "gesture_plain",
    "gesture_overlay",
    "invalid_plain",
    "invalid_overlay",
    "idle",
    "partial_overlay",
    "partial_onset",
    "capture",
    "still",
)
"""How a window was made, indexed by :attr:`WindowBatch.sources` (see the module doc).

``capture`` marks a window cut from a labelled capture (:mod:`~.datasets.captures`); ``still`` a
window of fingers resting before or after a gesture's motion (the ``stream`` recipe,
:mod:`~.stream_windows`)."""

RECIPES = ("stream", "overlay")
"""Ways of drawing training windows (:attr:`WindowSettings.recipe`)."""

SOURCE_CODES: dict[str, int] = {name: code for code, name in enumerate(SOURCE_NAMES)}


@dataclass(frozen=True)
class WindowSettings:
    """How windows are cut and augmented (frames of the recording's rate; see module doc).

    ``recipe`` picks how windows are drawn: ``"stream"`` (default) cuts plain windows at
    every position of the stream and labels each by what it shows
    (:mod:`~.stream_windows`, using ``min_motion_frames`` and ``motion_lag_frames``);
    ``"overlay"`` is the paper's augmentation described in this module's doc.
    """

    recipe: str = "stream"
    window_frames: int = 30
    min_segment_frames: int = 10
    max_partial_frames: int = 8
    overlay_fraction: float = 0.5
    invalid_overlay_fraction: float = 0.5
    rest_context_frames: int = 20
    quiet_margin_frames: int = 30
    invalid_mix: tuple[float, float, float] = (0.4, 0.25, 0.35)  # events, idle, partial/still
    min_motion_frames: int = 6
    motion_lag_frames: int = 6

    def __post_init__(self) -> None:
        if self.recipe not in RECIPES:
            raise ValueError(f"recipe must be one of {', '.join(RECIPES)}, got {self.recipe!r}")
        for name, least in (("min_motion_frames", 1), ("motion_lag_frames", 0)):
            value = getattr(self, name)
            if not (isinstance(value, int | np.integer) and value >= least):
                raise ValueError(f"{name} must be an integer >= {least}, got {value!r}")
        for name in ("window_frames", "min_segment_frames", "max_partial_frames"):
            value = getattr(self, name)
            if not (isinstance(value, int | np.integer) and value >= 1):
                raise ValueError(f"{name} must be an integer >= 1, got {value!r}")
        for name in ("rest_context_frames", "quiet_margin_frames"):
            value = getattr(self, name)
            if not (isinstance(value, int | np.integer) and value >= 0):
                raise ValueError(f"{name} must be an integer >= 0, got {value!r}")
        if not self.max_partial_frames < self.min_segment_frames <= self.window_frames:
            raise ValueError(
                "need max_partial_frames < min_segment_frames <= window_frames, got "
                f"{self.max_partial_frames}, {self.min_segment_frames}, {self.window_frames}"
            )
        for name in ("overlay_fraction", "invalid_overlay_fraction"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and 0.0 <= value <= 1.0):
                raise ValueError(f"{name} must lie in [0, 1], got {value!r}")
        mix = tuple(float(v) for v in self.invalid_mix)
        if len(mix) != 3 or not all(np.isfinite(v) and v >= 0 for v in mix) or sum(mix) <= 0:
            raise ValueError(
                "invalid_mix must be 3 non-negative weights (events, idle, partial) with a "
                f"positive sum, got {self.invalid_mix!r}"
            )
        object.__setattr__(self, "invalid_mix", mix)

    def to_dict(self) -> dict:
        d = asdict(self)
        d["invalid_mix"] = list(self.invalid_mix)
        return d

    @classmethod
    def from_dict(cls, d: dict) -> WindowSettings:
        """Build from a dict; missing keys take defaults, unknown keys are an error.

        A non-empty dict without ``recipe`` describes a data set made before recipes
        existed, which all used the paper's ``overlay`` recipe.
        """
        values = dict(d)
        if values and "recipe" not in values:
            values["recipe"] = "overlay"
        return from_dict(cls, values, "window settings")
