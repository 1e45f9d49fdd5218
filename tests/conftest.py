"""Shared test settings: where the project's shared data lives, and Hypothesis' profile."""

import os
from pathlib import Path

from hypothesis import settings

# The checkout sits beside ``shared/`` (GESTURES.md, FORMATS.md, datasets); CI clones the
# same way.  WOVENSKIN_SHARED overrides it.
SHARED = Path(os.environ.get("WOVENSKIN_SHARED", Path(__file__).resolve().parents[2] / "shared"))

# Tests never depend on the timing of a noisy machine: Hypothesis' per-example deadline
# (200 ms by default) is such a dependency (a loaded CI host failed a property test on it).
settings.register_profile("wovenskin", deadline=None)
settings.load_profile("wovenskin")
