"""Counts in words, for every message that prints one: ``1 participant``, ``2 participants``.

:func:`quantity` is the one place a count and its noun are agreed, so no message says
"1 participants"; :func:`duration` words a length of time as people say it;
:func:`train_extra_hint` says how to install the training extra on this install.
"""

from __future__ import annotations

from pathlib import Path


def quantity(n: int, noun: str, many: str | None = None) -> str:
    """``n`` and ``noun``, plural unless ``n`` is 1: ``quantity(2, "trial")`` is "2 trials".

    ``many`` is the plural where adding an s is wrong (``quantity(3, "person", "people")``)."""
    word = noun if n == 1 else (many if many is not None else noun + "s")
    return f"{n} {word}"


def duration(seconds: float) -> str:
    """A rough length of time: "40 s", "12 min", "3.4 h"."""
    seconds = max(0.0, float(seconds))
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 90 * 60:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"


def train_extra_hint() -> str:
    """How to install PyTorch for training here: from a clone (a ``pyproject.toml`` beside
    the package, as ``make`` sets it up) ``.venv/bin/pip install -e '.[train]'``, else the
    package's extra from the index."""
    root = Path(__file__).resolve().parent.parent
    if (root / "pyproject.toml").is_file():
        return f".venv/bin/pip install -e '.[train]' (in {root})"
    return "pip install 'wovenskin[train]'"
