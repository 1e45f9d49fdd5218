"""Where the repository is, for tests that read its files (docs, examples, models), and
whether a written file is a PNG image."""

from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"  # the first eight bytes of every PNG file


def is_png(path: Path) -> bool:
    """Whether ``path`` starts with the PNG signature."""
    return Path(path).read_bytes()[:8] == PNG_SIGNATURE
