"""Shared test settings: where the project's shared data lives."""

import os
from pathlib import Path

# The checkout sits beside ``shared/`` (GESTURES.md, FORMATS.md, datasets); CI clones the
# same way.  WOVENSKIN_SHARED overrides it.
SHARED = Path(os.environ.get("WOVENSKIN_SHARED", Path(__file__).resolve().parents[2] / "shared"))
