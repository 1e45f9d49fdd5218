"""Where the repository is, for tests that read its files (docs, examples, models)."""

from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
